"""Near-singular trajectory directions held by a minimal prior.

Without onboard sigmas (POSITION_SIGMA / ATTITUDE_SIGMA empty: no pseudo-observations of that
block) the control alone must separate the platform's position from its attitude. A shift across
track and a roll move the image almost alike (only relief and the Earth's curvature tell them
apart), so with control points on gentle terrain their corrections come out correlated 0.999 or
more, and the solution wanders along that direction: CBERS-02B HRC, 55 GCPs, no onboard sigmas,
position order 1, attitude order 2: corrections of 3 km and 4.5 mrad where the truth is 0. The
image fit hardly notices (it is the direction it cannot see), but the model, and every product of
it, rests on values the data do not support.

When a pair of trajectory parameters of such a block is correlated MAX_CORRELATION or more, the
combinations of that block's corrections that the observations (and the other priors) determine
worse than MINIMAL_POSITION_SIGMA (m) / MINIMAL_ATTITUDE_SIGMA (rad) are held by a pseudo-
observation of 0 with that sigma: in units of those sigmas, the eigenvectors u of the block's
covariance with an eigenvalue above 1 get the row u' x = 0 of weight 1. Only these directions
are held: what the control determines better than the prior is left as the control says. The
prior's sigmas are far above any onboard GNSS or star tracker (tens of metres, tens of arcseconds)
and its rows have almost no redundancy (the prior decides the held directions): like the
constraints of a minimal datum they do not count among the equations (degrees of freedom), and no
variance component is estimated for them. The report says what was held (``trajectory_prior``); onboard
sigmas, even wide ones, replace it.
"""
from __future__ import annotations

import logging

import numpy as np
from scipy import linalg

from ..rotations import ARCSEC
from .normal import System
from .problem import HELD_GROUP, Problem, Pseudo

log = logging.getLogger(__name__)

MAX_CORRELATION = 0.999
MINIMAL_POSITION_SIGMA = 1000.0            # m
MINIMAL_ATTITUDE_SIGMA = 1000.0 * ARCSEC   # rad


def hold_weak_trajectory(problem: Problem, system: System) -> dict | None:
    """Hold the near-singular directions of the trajectory blocks without pseudo-observations
    (see the module docstring) in ``problem`` (its :attr:`held` rows), from the normal equations
    ``system`` of its free parameters. Returns the report entry (None when nothing is held)."""
    params = problem.params
    if getattr(params, "position_basis", None) is None:  # an RPC scene's correction: no trajectory
        return None
    s = problem.settings
    minimal = {"position": MINIMAL_POSITION_SIGMA, "attitude": MINIMAL_ATTITUDE_SIGMA}
    open_blocks = [b for b, sigma in (("position", s.position_sigma), ("attitude", s.attitude_sigma)) if sigma is None]
    if not open_blocks:
        return None
    if system.is_sparse:
        log.warning("the trajectory's position/attitude split without onboard sigmas is not tested on a block of %d "
                    "unknowns (it needs the full covariance, %d^2 numbers): give POSITION_SIGMA and ATTITUDE_SIGMA "
                    "(the onboard GNSS and attitude accuracy)", system.N.shape[0], system.N.shape[0])
        return None
    free = params.free
    block = np.array([params.params[i].block for i in free])
    trajectory = np.isin(block, ("position", "attitude"))
    unheld = np.isin(block, open_blocks)
    # the covariance (up to sigma0^2) from the normal matrix scaled to a unit diagonal (see core.adjust.solver)
    scale = np.sqrt(np.abs(np.diag(system.N)))
    scale[~(scale > 0)] = 1.0
    try:
        Q = linalg.cho_solve(linalg.cho_factor(system.N / np.outer(scale, scale), check_finite=False),
                             np.eye(free.size), check_finite=False) / np.outer(scale, scale)
    except linalg.LinAlgError:
        return None  # left to the solver, which says so
    d = np.sqrt(np.abs(np.diag(Q)))
    corr = Q / np.outer(d, d)
    pair = np.abs(np.where(np.outer(trajectory, unheld) | np.outer(unheld, trajectory), corr, 0.0))
    np.fill_diagonal(pair, 0.0)
    a, b = np.unravel_index(np.argmax(pair), pair.shape)
    if pair[a, b] < MAX_CORRELATION:
        return None
    k = np.nonzero(unheld)[0]
    sigma = np.array([minimal[block[j]] for j in k])
    vals, vecs = np.linalg.eigh(Q[np.ix_(k, k)] / np.outer(sigma, sigma))
    weak = vals > 1.0
    names = [params.params[i].name for i in free]
    if not weak.any():
        log.info("%s and %s are correlated %.4f, but determined within %g m / %g arcsec: nothing held",
                 names[a], names[b], corr[a, b], MINIMAL_POSITION_SIGMA, MINIMAL_ATTITUDE_SIGMA / ARCSEC)
        return None
    entry = {"correlation": {"a": names[a], "b": names[b], "r": float(corr[a, b])}, "blocks": open_blocks,
             "position_sigma_m": MINIMAL_POSITION_SIGMA, "attitude_sigma_arcsec": MINIMAL_ATTITUDE_SIGMA / ARCSEC,
             "directions": int(weak.sum()),
             # how far the observations alone leave each held combination open, in prior sigmas
             "open_sigmas": [float(np.sqrt(v)) for v in np.sort(vals[weak])[::-1][:5]]}
    problem.held = [Pseudo(HELD_GROUP, free[k], (vecs[:, weak] / sigma[:, None]).T, 1.0)]
    log.warning("without onboard %s sigmas the control does not separate the trajectory's position from its "
                "attitude (%s and %s correlated %.4f): %d combination(s) of the corrections, determined only to "
                "%s times %g m / %g arcsec, are held by a minimal prior of that size; give POSITION_SIGMA and "
                "ATTITUDE_SIGMA (the onboard GNSS and attitude accuracy) to replace it", " and ".join(open_blocks),
                names[a], names[b], corr[a, b], int(weak.sum()), f"{entry['open_sigmas'][0]:.3g}",
                MINIMAL_POSITION_SIGMA, MINIMAL_ATTITUDE_SIGMA / ARCSEC)
    return entry
