"""Solve, estimate the variance components and down-weight gross errors, alternately, until
neither the flags nor the component factors change (see :mod:`core.adjust.robust`)."""
from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from .normal import Linearization, System
from .problem import Problem
from .robust import (COMPONENT_TOLERANCE, REFLAGGED, components, critical, flag_lines, inliers, joint_groups,
                     rescale, robust_scale, robust_weights, truncation)
from .solver import solve
from .statistics import Statistics, component_coupling, normalised, statistics

log = logging.getLogger(__name__)

@dataclass
class Estimate:
    """The last solution and its statistics, the robust passes' log, whether the loop stopped
    at its pass limit, the variance components (group -> (sum of p v^2 with the stated sigmas,
    redundancy, count)) over the inliers (n,) of the last pass, the truncation factor, and the
    sets of groups whose factors could not be told apart (each estimated as one,
    :func:`core.adjust.robust.joint_groups`); held (n,) bool: the observations held flagged after
    being flagged REFLAGGED times (:mod:`core.adjust.robust`, Convergence)."""
    result: dict
    st: Statistics
    passes: list
    at_limit: bool
    components: dict
    inlier: np.ndarray
    kappa: float
    joint: list = field(default_factory=list)
    held: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))


def estimate(problem: Problem, progress, is_cancelled,
             start: tuple[Linearization, System] | None = None) -> Estimate:
    """Solve, estimate the variance components and down-weight gross errors, alternately,
    until neither the flags nor the component factors change (see :mod:`core.adjust.robust`).
    ``start``: the problem's linearisation and normal equations at its current state, where the first
    solution starts (None: made there)."""
    s = problem.settings
    crit = critical(s.alpha)
    robust = s.robust != "none"
    kappa = truncation(crit) if robust else 1.0
    iterate = robust or s.variance_components
    passes = []
    joint: list[tuple[str, ...]] = []
    entered = np.zeros(len(problem.obs), int)  # how often each observation has been flagged anew
    held = np.zeros(len(problem.obs), bool)
    for k in range(s.max_robust_iterations if iterate else 1):
        label = f"robust pass {k + 1}: " if robust else f"variance component pass {k + 1}: " if iterate else ""
        result = solve(problem, progress, is_cancelled, label, start if k == 0 else None)
        st = statistics(problem, result["linearization"], result["system"])
        # Before any component is estimated the scale is robust: sigma0 of a first pass is
        # inflated by the gross errors themselves and would hide most of them.
        unscaled = np.ones(len(problem.obs))
        scale = robust_scale(problem, st) if robust and (k == 0 or not s.variance_components) else unscaled
        inlier = inliers(st, scale, crit) if robust else np.ones(len(problem.obs), bool)
        comps = components(problem, st, inlier)
        component_change = 0.0
        if s.variance_components:
            labels, H = component_coupling(problem, result["linearization"], result["system"], st.redundancy, inlier)
            joint = joint_groups(comps, labels, H, joint)
            component_change = rescale(problem, comps, kappa, joint, (labels, H))
            st.w, scale = normalised(problem, st.v, st.redundancy), unscaled
        before = problem.factor[:, 0] < 1.0
        lines_before = problem.line_flagged.copy()
        change = robust_weights(problem, st, scale, held) if robust else 0.0
        if robust:
            change = max(change, flag_lines(problem, st, scale, crit))
        after = problem.factor[:, 0] < 1.0
        entered += after & ~before
        held |= after & (entered >= REFLAGGED)
        passes.append({"pass": k + 1, "sigma0": st.sigma0, "down_weighted": int(after.sum()),
                       "held_flagged": int(held.sum()), "largest_change": change, "component_change": component_change,
                       "joint_groups": [list(j) for j in joint]})
        log.info("%ssigma0 %.3f, %d observations down-weighted, variance components changed by %.1f %%", label,
                 st.sigma0, int(after.sum()), 100 * component_change)
        # Done when no observation changes side (the weights of the down-weighted ones then only
        # follow their already large residuals and no longer move the solution), or when the
        # last re-weighting no longer moved the solution measurably (with tens of thousands of
        # observations some always sit at the critical value and change side back and forth),
        # no control line changes side, and no variance component changes by more than its tolerance.
        settled = (change < 1e-3 or (k > 0 and (np.array_equal(before, after) or not result["iterations"]))) and \
            np.array_equal(lines_before, problem.line_flagged)
        if not iterate or (settled and component_change < COMPONENT_TOLERANCE):
            return Estimate(result, st, passes, False, comps, inlier, kappa, joint, held)
    return Estimate(result, st, passes, True, comps, inlier, kappa, joint, held)

