"""Automatic removal of interior parameters the control at hand cannot support.

After a solution with free or weighted interior parameters (camera terms, chip terms,
installation angles), the weakest ones are fixed at 0 a few at a time and the block is
re-solved, until every kept parameter passes three tests (their figures go in the report):

- significance: |value| >= T_CRITICAL * sigma (sigma a posteriori, 95 % two-sided);
- correlation: |r| <= MAX_CORRELATION with every other unknown (trajectory included), unless
  the parameter is clearly determined all the same (t >= T_CORRELATED): above it the two
  trade against each other and a weakly determined split is decided by noise;
- information: at least MIN_INFORMATION of the parameter's information from the
  observations is left once the trajectory and the interior parameters kept before it are
  free: below it they would absorb it. The interior parameters are taken strongest first (a
  pivoted Cholesky decomposition of the observations' information, trajectory eliminated),
  so of two or more that the control cannot separate (the focal length and b3 of a line
  array, a camera's principal point and installation roll) one is kept and the others are
  removed; testing each against all the others free would fail every member and remove the
  whole group, and with it an error the group models (the across-track scale). Installation
  angles against a shared attitude correction keep only ~0.1 % by construction (the attitude
  bias takes the rest; the cameras' time separation decides) and are still well determined
  (Zhang et al. 2024), so the threshold is that of non-determinability. A round that finds
  non-determinable parameters removes only those (they are removable together) and tests the
  others again once they are gone.

The tests remove free parameters only. A weighted parameter (a prior sigma, e.g. INTERIOR=default)
that fails them stays, held by its prior, and is named with its reasons: fixing it at 0 would
assert a sigma of 0, a stronger and usually wrong claim than the prior given, and the prior
already keeps a term the control cannot see from running away. Measured on simulated TH-1 blocks
with 9 GCPs and 25 tie points (tests/bench/bench_seed001_th1.py), removing the weighted terms
that failed left the 3D check RMSE at 3.8-5.8 m plan where keeping them gave 3.6-3.9 m (floor:
the true interior given, 3.3-3.5 m), worse in 13 of 16 heights.

Then a guard: the conventional adjustment (no interior parameters) of the same
observations is solved too, and self-calibration is kept only when it lowers the weighted
squared residuals significantly, by the F-test of nested models (Koch 1999; the test of
additional parameters in Förstner 1979 / Grün 1978): F = ((C0 - C1) / q) / (C1 / dof1) against
F(q, dof1) at GUARD_ALPHA, C0 and C1 the costs of the two solutions with the same weights (the
conventional run's variance components and robust weights), q the kept parameters' effective
number (a free one counts 1, a weighted one its share of information from the observations,
1 - sigma_posterior^2 / sigma_prior^2: a term its prior alone holds adds no freedom), dof1 the
conventional redundancy minus q. Parameters that only fit noise, or that the control cannot
separate from the trajectory, do not pass it, and the run falls back to the conventional
solution and says so. The test needs no check points and no extra solutions beyond one
(a leave-one-out cross-validation of the control points would need one per GCP and leaves
too few points for 4-GCP blocks).
"""
from __future__ import annotations

import copy
import logging
import math
from typing import Callable

import numpy as np
from scipy import stats

from .solver import solve

log = logging.getLogger(__name__)

T_CRITICAL = 1.96        # |value| / sigma below this: not significant (alpha 0.05, two-sided)
MAX_CORRELATION = 0.98   # |r| with another unknown above this: the control cannot split them ...
T_CORRELATED = 5.0       # ... unless the parameter stands out this clearly from its sigma
MIN_INFORMATION = 1e-4   # share of its observation information left with the others free
GUARD_ALPHA = 0.05       # significance of the F-test against the conventional adjustment


def interior_free(problem) -> np.ndarray:
    """Indices (into params.params) of the free or weighted interior parameters."""
    return np.array([i for i in problem.params.free if problem.params.params[i].block
                     in ("installation", "chip", "camera")], dtype=np.int64)


def _tests(problem, est) -> list[dict]:
    """Each free interior parameter's value, sigma, t, largest correlation (with whom) and
    information share, and the tests it fails (list of reasons)."""
    params, st = problem.params, est.st
    system = est.result["system"]
    free = params.free
    column = {int(i): k for k, i in enumerate(free)}
    d = np.sqrt(np.diag(st.Q))
    corr = st.Q / np.outer(d, d)
    interior = interior_free(problem)
    shares = information_shares(system.N, np.array([column[int(i)] for i in interior], dtype=np.int64),
                                np.array([_prior(params.params[i]) for i in interior]))
    out = []
    for i, info in zip(interior, shares):
        p, k = params.params[i], column[int(i)]
        sigma = float(st.sigma0 * d[k])
        t = abs(p.value) / sigma if sigma > 0 else math.inf
        r = np.abs(corr[k]).copy()
        r[k] = 0.0
        j = int(np.argmax(r))
        fails = []
        if info < MIN_INFORMATION:
            fails.append(f"non-determinable with this control: keeps {100 * max(info, 0.0):.2g} % of its "
                         "information once the trajectory and the stronger interior parameters are free")
        if r[j] > MAX_CORRELATION and t < T_CORRELATED:
            fails.append(f"correlated with {params.params[free[j]].name} at r = {corr[k, j]:+.4f}")
        if t < T_CRITICAL:
            fails.append(f"not significant: value {p.value:.4g} {p.unit}, sigma {sigma:.3g}, t = {t:.2f} "
                         f"< {T_CRITICAL}")
        out.append({"name": p.name, "index": int(i), "value": p.value, "sigma": sigma, "unit": p.unit, "t": t,
                    "correlation": float(corr[k, j]), "correlated_with": params.params[free[j]].name,
                    "information": info, "fails": fails, "weighted": p.mode == "weighted",
                    "effective": _effective_share(p, float(d[k] ** 2))})
    return out


def _effective_share(p, q_kk: float) -> float:
    """How much of one parameter a solution spends on it: 1 when free; when weighted, the
    share of its posterior information that comes from the observations, 1 - Q_kk / sigma^2
    (Q_kk its cofactor, SI units squared; sigma its prior), 0 for a term its prior alone holds."""
    if p.mode != "weighted":
        return 1.0
    return float(min(max(1.0 - q_kk / p.sigma ** 2, 0.0), 1.0))


def _prior(p) -> float:
    """The information (1 / sigma^2, SI) of a parameter's own pseudo-observation (0 when free)."""
    return 1.0 / p.sigma ** 2 if p.mode == "weighted" else 0.0


def information_shares(N: np.ndarray, interior: np.ndarray, prior: np.ndarray) -> np.ndarray:
    """Per interior unknown, the share (k,) of its information from the observations that is
    left once the other unknowns (trajectory) and the interior unknowns stronger than it are
    free: a pivoted Cholesky decomposition of the Schur complement of the other unknowns,
    scaled by its diagonal, taking the largest remaining share first.

    N: (n, n) normal matrix of the free unknowns (with the priors); interior: (k,) its columns
    of the interior unknowns; prior: (k,) their priors' information, taken out (the share is of
    the observations' information). Shares after the first below MIN_INFORMATION are those left
    given every stronger unknown (all of them non-determinable)."""
    n = N.shape[0]
    other = np.setdiff1d(np.arange(n), interior)
    data = N.copy()
    data[interior, interior] -= prior
    own = np.diag(data)[interior]
    S = data[np.ix_(interior, interior)]
    if other.size:
        coupling = data[np.ix_(other, interior)]
        S = S - coupling.T @ np.linalg.solve(data[np.ix_(other, other)], coupling)
    scale = np.sqrt(np.where(own > 0, own, np.inf))
    S = S / np.outer(scale, scale)
    shares = np.zeros(interior.size)
    todo = np.ones(interior.size, bool)
    while todo.any():
        left = np.where(todo, np.diag(S), -np.inf)
        j = int(np.argmax(left))
        shares[j], todo[j] = max(left[j], 0.0), False
        if left[j] < MIN_INFORMATION:
            shares[todo] = np.maximum(np.diag(S)[todo], 0.0)
            break
        S = S - np.outer(S[:, j], S[j, :]) / S[j, j]
    return shares


def _batch(failing: list[dict]) -> list[dict]:
    """The failing parameters to remove in one round (weakest first): every non-determinable
    one when there are any (:func:`information_shares` keeps the determinable rest), else up
    to a third of them, never both of a correlated pair (removing one may leave the other
    clearly determined: k1 and k2 of a short array; it is tested again next round)."""
    undetermined = [x for x in failing if x["information"] < MIN_INFORMATION]
    if undetermined:
        return undetermined
    batch, partners = [], set()
    for x in failing[:max(1, len(failing) // 3)]:
        if x["name"] in partners:
            continue
        batch.append(x)
        if abs(x["correlation"]) > MAX_CORRELATION:
            partners.add(x["correlated_with"])
    return batch


def _same_weight_cost(problem, like) -> float:
    """The least weighted squared residuals of ``problem``'s model with the weights of ``like``
    (same observations in the same order): its variance components and robust weights. The
    self-calibrated solution minimises its own weights' cost; under the conventional run's
    weights it is not the minimum (by far when the two runs' variance components or flags
    differ, e.g. many tie points), so it is re-solved from there (Gauss-Newton, weights held)."""
    same = copy.deepcopy(problem)
    same.set_weights_of(like)
    solve(same, lambda *a: None, lambda: False, "guard: ")
    return same.cost()


def select_interior(problem, est, estimate: Callable) -> tuple[object, object, dict]:
    """Remove failing interior parameters and guard against the conventional adjustment.

    problem, est: the solved problem (:class:`core.adjust.problem.Problem`) and its estimate
    (:class:`core.adjust.estimation.Estimate`);
    estimate(problem) re-solves. Returns the problem and estimate to report (the conventional
    ones when self-calibration is not significantly better) and the report section."""
    conventional = copy.deepcopy(problem)
    removed, rounds = [], 0
    while True:
        tests = _tests(problem, est)
        failing = sorted((x for x in tests if x["fails"] and not x["weighted"]),
                         key=lambda x: (len(x["fails"]) < 2, x["t"]))
        if not failing:
            break
        batch = _batch(failing)
        for x in batch:
            log.info("interior parameter %s removed: %s", x["name"], "; ".join(x["fails"]))
            removed.append({k: v for k, v in x.items() if k != "index"} | {"round": rounds + 1})
        problem.fix_at_zero([x["index"] for x in batch])
        rounds += 1
        if interior_free(problem).size == 0:
            tests = []
            break
        est = estimate(problem)
    kept = [_kept_entry(x) for x in tests]
    for x in kept:
        if x.get("held_by_prior"):
            log.info("interior parameter %s kept, held by its prior: %s", x["name"], x["held_by_prior"])
    report = _report(rounds, removed, kept)
    est0 = estimate(_without_interior(conventional))
    guard = _guard(problem, est, conventional, est0, len(kept), sum(x["effective"] for x in kept))
    report["guard"] = guard
    if guard["self_calibration_kept"]:
        log.info("self-calibration kept: %d interior parameters (%s); F = %.3g > %.3g", len(kept),
                 ", ".join(x["name"] for x in kept), guard["F"], guard["F_critical"])
        report["outcome"] = "self-calibration"
        return problem, est, report
    log.warning("self-calibration fell back to the conventional adjustment (no interior parameters): %s",
                guard["reason"])
    report["outcome"] = "conventional"
    return conventional, est0, report


def _kept_entry(test: dict) -> dict:
    """A kept parameter's report entry; a weighted one that failed a test says why its prior holds it."""
    entry = {k: v for k, v in test.items() if k not in ("index", "fails")}
    if test["fails"]:
        entry["held_by_prior"] = "; ".join(test["fails"])
    return entry


def _report(rounds: int, removed: list, kept: list) -> dict:
    return {"method": "significant", "t_critical": T_CRITICAL, "max_correlation": MAX_CORRELATION,
            "min_information": MIN_INFORMATION, "rounds": rounds, "removed": removed, "kept": kept}


def _without_interior(problem):
    """``problem`` (changed in place) with every interior parameter fixed at 0 and the
    weights as stated: the conventional adjustment of the same observations."""
    problem.fix_at_zero(interior_free(problem))
    problem.reset_weights()
    return problem


def conventional_instead(problem, estimate: Callable, why: str) -> tuple[object, object, dict]:
    """The conventional adjustment in place of a self-calibrating one that cannot be solved
    (``why``): its problem, estimate and the selection's report section saying so."""
    n = int(interior_free(problem).size)
    conventional = _without_interior(copy.deepcopy(problem))
    est0 = estimate(conventional)
    log.warning("self-calibration fell back to the conventional adjustment (no interior parameters): %s", why)
    guard = {"kept_parameters": n, "effective_parameters": None, "cost_conventional": conventional.cost(),
             "cost_self_calibrated": None, "dof": None, "alpha": GUARD_ALPHA, "F": None, "F_critical": None,
             "self_calibration_kept": False, "reason": why}
    return conventional, est0, _report(0, [], []) | {"guard": guard, "outcome": "conventional"}


def _guard(problem, est, conventional, est0, kept: int, q: float) -> dict:
    """The F-test of the kept interior parameters (``kept`` of them, ``q`` effective, see the
    module's docstring) against the conventional solution."""
    c0 = conventional.cost()
    c1 = _same_weight_cost(problem, conventional)
    dof1 = est0.st.dof - q
    out = {"kept_parameters": kept, "effective_parameters": q, "cost_conventional": c0,
           "cost_self_calibrated": c1, "dof": [q, dof1], "alpha": GUARD_ALPHA, "F": None, "F_critical": None}
    if kept == 0:
        return out | {"self_calibration_kept": False, "reason": "no interior parameter passed its tests"}
    if q <= 0:
        return out | {"self_calibration_kept": False,
                      "reason": f"the observations add nothing to the {kept} kept interior parameters' priors"}
    if dof1 <= 0:
        return out | {"self_calibration_kept": False,
                      "reason": f"no redundancy left for {q:.3g} effective interior parameters "
                                f"({est0.st.dof:.0f} before them)"}
    f = ((c0 - c1) / q) / (c1 / dof1)
    crit = float(stats.f.ppf(1.0 - GUARD_ALPHA, q, dof1))
    out |= {"F": float(f), "F_critical": crit}
    if f > crit:
        return out | {"self_calibration_kept": True, "reason": ""}
    return out | {"self_calibration_kept": False,
                  "reason": f"the {kept} kept interior parameters ({q:.3g} effective) do not lower the weighted "
                            f"squared residuals "
                            f"significantly (F = {f:.3g} <= {crit:.3g} at alpha {GUARD_ALPHA}: "
                            f"{c1:.4g} against {c0:.4g} without them)"}
