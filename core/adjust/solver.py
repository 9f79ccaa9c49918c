"""Gauss-Newton iterations with a trust-region (Levenberg-Marquardt) damping to convergence, on the
reduced normal equations of a :class:`core.adjust.problem.Problem` (ground points eliminated).

The normal equations are solved scaled to a unit diagonal (Jacobi scaling: N_s = D^-1 N D^-1,
D = sqrt(diag N)), which makes the damping independent of the parameters' units and keeps the
Cholesky factorisation accurate when they span many orders of magnitude (metres of position,
radians of attitude, 1/m^4 of a radial term). A damped step solves (N_s + lambda I) z = -D^-1 b,
dx = D^-1 z; the ground unknowns are damped alike (lambda diag(N_gg) on each point's block before it
is eliminated, :func:`core.adjust.normal.assemble`). The damping follows the gain ratio rho =
(actual decrease of the weighted squared residuals) / (decrease the linearisation predicts for the
parameter and ground steps, :meth:`core.adjust.problem.Problem.model_cost`) as in Nielsen (1999): a
step that lowers the residuals is taken and lambda shrinks by max(1/3, 1 - (2 rho - 1)^3); a
refused step multiplies it by nu, nu doubling with every refusal in a row. Undamped Gauss-Newton is
tried first and returned to once lambda falls below LAMBDA_MIN: damping slows the weakly determined
directions (position against attitude, scaled eigenvalues ~1e-8) to linear convergence.

Reference: Nielsen, H. B. (1999): Damping parameter in Marquardt's method. Report IMM-REP-1999-05,
Technical University of Denmark.
"""
from __future__ import annotations

import logging

import numpy as np
from scipy import linalg, sparse

from ..errors import Cancelled, ConvergenceError, NoDescentError
from .normal import Linearization, System, back_substitute
from .problem import Problem
from .sparsenormal import NotPositiveDefinite, factorise, inverse_diagonal_bound

log = logging.getLogger(__name__)

STEP_TOLERANCE = 1e-3     # px: a step changing no image residual more than this is converged


SIGMA_TOLERANCE = 1e-3    # a step below this share of every parameter's a-priori sigma is converged


# A step the linearised model says lowers the weighted squared residuals by less than this is converged:
# it moves the solution by under 0.15 of its posterior standard deviation (d' N d / 2 = the decrease),
# nothing the statistics could tell. Gauss-Newton creeps along a flat direction held only by a weak
# prior (two RPC images tied at 0.05 px, held by a 100 px prior: 0.005 per iteration, 7 % shorter steps
# each time, 30 iterations without converging).
DECREASE_TOLERANCE = 1e-2


# A refused step that promised more than this share of the cost: stuck, not converged (ZY-3 with a
# runaway term promised 99 %). Less is rounding or a kink of the cost (a line point changing segment,
# 0.2 % on 3 roads of one direction): the sigma0 it could change by is under 0.5 %.
PROMISE_SHARE = 1e-2


# Damping (on the unit diagonal of the scaled normal matrix) after the first refusal: Nielsen's tau.
# From 1e-6 a strongly curved block (3 roads of one direction, no GCPs, CBERS-02B) took ~10 refusals
# per iteration to reach a useful damping and did not converge in 30 iterations; from 1e-3, 15.
LAMBDA_START = 1e-3
LAMBDA_MIN = 1e-9         # below this the damping is dropped (Gauss-Newton)
LAMBDA_MAX = 1e10         # beyond this no step lowers the residuals: the solution is stuck


def solve(problem: Problem, progress, is_cancelled, label: str = "",
          start: tuple[Linearization, System] | None = None) -> dict:
    """Gauss-Newton iterations to convergence, damped (Levenberg-Marquardt, the damping set by the
    gain ratio) only after a step that fails, from the linearisation and normal equations ``start`` of
    the problem's current state (None: made here). Returns the iteration log, the last normal
    equations and linearisation."""
    lam, nu = 0.0, 2.0
    history = []
    lin, system = start or problem.system()
    cost = best = system.cost
    idle = 0
    for it in range(problem.settings.max_iterations):
        if is_cancelled():
            raise Cancelled("adjustment cancelled by the user")
        promised, rejected = None, False
        while True:
            # The ground unknowns are damped with the parameters: a damped parameter step with the
            # ground's full Newton step (nonlinear where line points change segment, or a tie
            # point's rays are nearly parallel) could refuse every step for good.
            damped = system if lam == 0.0 else problem.system((lin, system.prior), ground_damping=lam)[1]
            try:
                scaled = ScaledSystem(damped)
                dx, z, factor = scaled.step(lam)
            except (linalg.LinAlgError, NotPositiveDefinite):
                lam, nu = raised(lam, nu)
                if lam > LAMBDA_MAX:
                    raise NoDescentError(_not_converged(history, "the normal matrix is not positive definite"))
                continue
            predicted = cost - problem.model_cost(lin, system.prior, dx, back_substitute(lin, damped, dx))
            if promised is None:  # the linearised model's decrease of the cost for this iteration's first step
                promised = predicted
            change = _image_change(lin, dx)
            # At the optimum already (rounding decides the cost, not the step), or the step is a
            # negligible share of every parameter's standard deviation (weakly determined
            # directions, where the cost is flat, would otherwise be crept along for ever).
            relative = scaled.relative(z, factor, lam)
            negligible = change < STEP_TOLERANCE or relative < SIGMA_TOLERANCE
            if (negligible or predicted < DECREASE_TOLERANCE) and not rejected:
                return {"iterations": history, "system": system, "linearization": lin}
            # A damped step is tried however small: along a curved valley of nearly null directions
            # (position against roll under heavy image weights) the Gauss-Newton step overshoots by
            # a second-order 0.01 px that outweighs what it gains, while a tenth of it still descends.
            saved = problem.state()
            problem.step(lin, damped, dx)
            new_cost = problem.cost()
            if new_cost <= cost * (1 + 1e-9):
                break
            problem.restore(saved)
            rejected = True
            if negligible:
                # Damped down to nothing after the steps the linearised model promised much from
                # were all refused: stuck, not at the optimum (a nearly singular normal matrix).
                if promised > PROMISE_SHARE * cost:
                    raise NoDescentError(_not_converged(
                        history, f"no step reduces the residuals (the linearised model promised {promised:.4g} "
                                 f"of {cost:.4g}; the normal matrix is nearly singular)"))
                return {"iterations": history, "system": system, "linearization": lin}
            lam, nu = raised(lam, nu)
            if lam > LAMBDA_MAX:
                raise NoDescentError(_not_converged(history, "no step reduces the residuals"))
        rho = (cost - new_cost) / predicted if predicted > 0 else 1.0
        history.append({"iteration": it + 1, "cost": new_cost, "max_image_change_px": change, "damping": lam,
                        "gain_ratio": float(rho)})
        log.info("%siteration %d: weighted squared residuals %.6g, largest image change %.2e px, damping %.2g, "
                 "gain ratio %.3f", label, it + 1, new_cost, change, lam, rho)
        progress(min(0.9, 0.1 + 0.08 * (it + 1)), f"{label}iteration {it + 1}: cost {new_cost:.6g}")
        # Line points that change segment at each relinearisation can make the steps cycle between
        # two costs, each a decrease from its own linearisation: two iterations in a row that do
        # not lower the lowest cost reached have converged in cost too.
        idle = idle + 1 if best - new_cost <= 1e-8 * best else 0
        stalled = cost - new_cost <= 1e-8 * cost or idle >= 2
        best, cost = min(best, new_cost), new_cost
        lam *= max(1.0 / 3.0, 1.0 - (2.0 * min(rho, 1.0) - 1.0) ** 3)
        lam, nu = (0.0 if lam < LAMBDA_MIN else lam), 2.0
        # A step that no longer lowers the cost (Gauss-Newton, which neglects the curvature of
        # large residuals such as gross errors, may cycle there) has converged in cost.
        if (change < 10 * STEP_TOLERANCE and lam == 0.0) or stalled:
            # Gauss-Newton converges quadratically here: the next step would change nothing
            # measurable. The statistics take the last linearisation with the final residuals.
            lin.r = problem.residuals()
            system.cost = new_cost
            return {"iterations": history, "system": system, "linearization": lin}
        lin, system = problem.system()
        # the cost as linearised: a line point may change segment with the new linearisation
        cost = system.cost
    n = problem.settings.max_iterations
    raise ConvergenceError(_not_converged(history, f"still changing after {n} iteration{'s' * (n != 1)}"))


def raised(lam: float, nu: float) -> tuple[float, float]:
    """The damping and its factor after a refused step (Nielsen 1999): lam times nu, nu doubled;
    LAMBDA_START when there was none. Raising a small damping from where it is, not from
    LAMBDA_START, keeps a long curved valley from costing ten iterations per refusal."""
    return (nu * lam if lam > 0.0 else LAMBDA_START), 2.0 * nu


class ScaledSystem:
    """The normal equations N dx = -b scaled to a unit diagonal (see the module docstring); a
    sparse N (:attr:`core.adjust.normal.System.is_sparse`) stays sparse and is factorised by
    :func:`core.adjust.sparsenormal.factorise`."""

    def __init__(self, system: System):
        d = np.sqrt(system.N.diagonal().copy())
        d[~(d > 0)] = 1.0
        self.d, self.system = d, system
        if system.is_sparse:
            scale = sparse.diags(1.0 / d)
            self.N = (scale @ system.N @ scale).tocsc()
        else:
            self.N = system.N / np.outer(d, d)
        self.b = system.b / d

    def step(self, lam: float) -> tuple[np.ndarray, np.ndarray, object]:
        """(dx, z = D dx, the factor of N_s + lam I: Cholesky, or SuperLU when sparse) of the step
        damped by lam."""
        if self.system.is_sparse:
            factor = factorise(self.N + lam * sparse.identity(self.b.size, format="csc"))
            z = -factor.solve(self.b)
        else:
            factor = linalg.cho_factor(self.N + lam * np.eye(self.b.size), check_finite=False)
            z = -linalg.cho_solve(factor, self.b, check_finite=False)
        if not np.all(np.isfinite(z)):
            raise linalg.LinAlgError("the damped normal matrix is singular")
        return z / self.d, z, factor

    def relative(self, z: np.ndarray, factor, lam: float) -> float:
        """The largest share of a scaled step z of its parameter's standard deviation,
        |z_i| / sqrt((N_s + lam I)^-1_ii). Dense: exact, from the full inverse. Sparse: an upper
        bound from lower bounds of the inverse's diagonal (each column group's own block
        inverted, :func:`core.adjust.sparsenormal.inverse_diagonal_bound`), so that a step is
        called negligible only when the exact test would call it so too; a weakly determined
        direction the bound misses still ends the iterations by DECREASE_TOLERANCE."""
        if not self.system.is_sparse:
            return float(np.max(np.abs(z) / np.sqrt(np.diag(
                linalg.cho_solve(factor, np.eye(z.size), check_finite=False))), initial=0.0))
        damped = self.N + lam * sparse.identity(self.b.size, format="csc")
        return float(np.max(np.abs(z) / np.sqrt(inverse_diagonal_bound(damped, self.system.layouts or [])),
                            initial=0.0))


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
