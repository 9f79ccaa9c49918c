"""Gauss-Newton iterations with Levenberg-Marquardt damping to convergence, on the reduced normal
equations of a :class:`core.adjust.problem.Problem` (ground points eliminated)."""
from __future__ import annotations

import logging

import numpy as np
from scipy import linalg

from ..errors import Cancelled, ConvergenceError, NoDescentError
from .normal import Linearization
from .problem import Problem

log = logging.getLogger(__name__)

STEP_TOLERANCE = 1e-3     # px: a step changing no image residual more than this is converged


SIGMA_TOLERANCE = 1e-3    # a step below this share of every parameter's a-priori sigma is converged


PROMISE_SHARE = 1e-3      # a refused step that promised more than this share of the cost: not converged


def solve(problem: Problem, progress, is_cancelled, label: str = "") -> dict:
    """Gauss-Newton iterations to convergence, damped (Levenberg-Marquardt) only after a step
    that fails: damping slows the weakly determined directions (position against attitude,
    eigenvalue ratios ~1e-8) to linear convergence. Returns the iteration log."""
    lam = 0.0
    history = []
    lin, system = problem.system()
    cost = system.cost
    for it in range(problem.settings.max_iterations):
        if is_cancelled():
            raise Cancelled("adjustment cancelled by the user")
        D = np.diag(system.N).copy()
        D[D <= 0] = 1.0
        promised, rejected = None, False
        while True:
            try:
                factor = linalg.cho_factor(system.N + lam * np.diag(D), check_finite=False)
                dx = -linalg.cho_solve(factor, system.b, check_finite=False)
            except linalg.LinAlgError:
                lam = max(10.0 * lam, 1e-9)
                if lam > 1e12:
                    raise NoDescentError(_not_converged(history, "the normal matrix is not positive definite"))
                continue
            if promised is None:  # the linearised model's decrease of the cost for this iteration's first step
                promised = -float(system.b @ dx)
            change = _image_change(lin, dx)
            # At the optimum already (rounding decides the cost, not the step), or the step is a
            # negligible share of every parameter's standard deviation (weakly determined
            # directions, where the cost is flat, would otherwise be crept along for ever).
            relative = np.max(np.abs(dx) / np.sqrt(np.diag(
                linalg.cho_solve(factor, np.eye(dx.size), check_finite=False))), initial=0.0)
            if change < STEP_TOLERANCE or relative < SIGMA_TOLERANCE:
                # Damped down to nothing after the steps the linearised model promised much from
                # were all refused: stuck, not at the optimum (a nearly singular normal matrix).
                if rejected and promised > PROMISE_SHARE * cost:
                    raise NoDescentError(_not_converged(
                        history, f"no step reduces the residuals (the linearised model promised {promised:.4g} "
                                 f"of {cost:.4g}; the normal matrix is nearly singular)"))
                return {"iterations": history, "system": system, "linearization": lin}
            saved = problem.state()
            problem.step(lin, system, dx)
            new_cost = problem.cost()
            if new_cost <= cost * (1 + 1e-9):
                break
            problem.restore(saved)
            rejected = True
            lam = max(10.0 * lam, 1e-9)
            if lam > 1e12:
                raise NoDescentError(_not_converged(history, "no step reduces the residuals"))
        history.append({"iteration": it + 1, "cost": new_cost, "max_image_change_px": change, "damping": lam})
        log.info("%siteration %d: weighted squared residuals %.6g, largest image change %.2e px", label, it + 1,
                 new_cost, change)
        progress(min(0.9, 0.1 + 0.08 * (it + 1)), f"{label}iteration {it + 1}: cost {new_cost:.6g}")
        stalled = cost - new_cost <= 1e-8 * cost
        cost = new_cost
        lam = lam / 10.0 if lam > 1e-9 else 0.0
        # A step that no longer lowers the cost (Gauss-Newton, which neglects the curvature of
        # large residuals such as gross errors, may cycle there) has converged in cost.
        if (change < 10 * STEP_TOLERANCE and lam == 0.0) or stalled:
            # Gauss-Newton converges quadratically here: the next step would change nothing
            # measurable. The statistics take the last linearisation with the final residuals.
            lin.r = problem.residuals()
            system.cost = new_cost
            return {"iterations": history, "system": system, "linearization": lin}
        lin, system = problem.system()
    n = problem.settings.max_iterations
    raise ConvergenceError(_not_converged(history, f"still changing after {n} iteration{'s' * (n != 1)}"))


def _image_change(lin: Linearization, dx: np.ndarray) -> float:
    """Largest change (px) a parameter step makes to an image residual, to first order."""
    step = np.einsum("nkq,nq->nk", lin.values, np.where(lin.columns >= 0, dx[np.maximum(lin.columns, 0)], 0.0))
    return float(np.max(np.abs(step), initial=0.0))


def _not_converged(history: list[dict], why: str) -> str:
    tried = "; ".join(f"#{h['iteration']}: {h['cost']:.4g} (step {h['max_image_change_px']:.3g} px)"
                      for h in history[-5:]) or "no iteration completed"
    return (f"the adjustment did not converge: {why}. Weighted squared residuals per iteration: {tried}. "
            "Try fewer free interior parameters, a simpler trajectory model, onboard sigmas, or check the GCPs "
            "for gross errors.")

