"""Parameter sets the observations cannot separate: found from the normal matrix, named, and one of
each fixed (or the run stopped, as the settings say).

The seeds' CBERS-02B experiments (Zhang et al. 2015, Table II) show that all ten interior
parameters together cannot be determined; such sets are detected here before solving.

Moves of a whole block that only the priors hold (tie points without control: a common shift, a
height tilt an RPC image's drift follows, ...) are no defect here, the priors determine them; they
are named with their size after the solution by :mod:`core.adjust.datumdirections`.
"""
from __future__ import annotations

import logging

import numpy as np

from ..errors import InputError
from .normal import System
from .problem import Problem

log = logging.getLogger(__name__)

PIVOT_SHARE = 0.1  # a pivot row adds a null direction when the pivots' smallest singular value stays above this share
SINGULAR = 1e-11           # trajectory: smallest / largest eigenvalue of the correlation-scaled matrix


# Interior: share of a combination's information left with the trajectory free. Measured on
# CBERS-02B: non-determinable sets keep <= 1.3e-5 (the middle chip's stagger barely separates
# yaw from a common chip rotation), the weakest determinable term (focal length) >= 1.6e-3.
INTERIOR_SINGULAR = 1e-4
# Parameters that carry the datum: the trajectory corrections and the RPC images' corrections (a
# block's common move is theirs; with weak priors they keep little information of their own once
# the others are free, which is no defect), tested as a whole, never the one fixed.
DATUM_BLOCKS = ("position", "attitude", "rpc_correction")


def non_determinable(N: np.ndarray, names: list[str], trajectory: np.ndarray,
                     prefer: np.ndarray | None = None) -> list[list[str]]:
    """Sets of parameters the observations cannot separate, each listed with the most
    involved first. Several null directions are recombined (:func:`separated`) around pivots
    taken from ``prefer`` (n,) bool first (the parameters one would fix: a reference chip's).

    Trajectory: (near-)null directions of the correlation-scaled normal matrix (ratio below
    SINGULAR). Interior (the rest): directions that keep less than INTERIOR_SINGULAR of their
    information once the trajectory is free (the Schur complement of the trajectory block,
    scaled by the interior diagonal), named with the trajectory parameters that absorb them.
    """
    _check_finite(N, names)
    d = np.sqrt(np.maximum(np.diag(N), 0.0))
    dead = np.nonzero(d <= 0)[0]
    if dead.size:
        return [[names[i]] for i in dead]
    C = N / d[:, None] / d[None, :]  # one side at a time: |N_ij| <= d_i d_j, nothing overflows on the way
    t = np.nonzero(trajectory)[0]
    try:
        if t.size == 0:  # an RPC scene's correction: no trajectory to absorb anything
            vals, vecs = np.linalg.eigh(C)
            null = separated(vecs[:, vals < SINGULAR * vals[-1]], prefer)
            return [_members(v, np.arange(len(names)), names) for v in null.T]
        vals, vecs = np.linalg.eigh(C[np.ix_(t, t)])
        sets = [_members(v, t, names)
                for v in separated(vecs[:, vals < SINGULAR * vals[-1]], None if prefer is None else prefer[t]).T]
        if sets or trajectory.all():
            return sets
        i = np.nonzero(~trajectory)[0]
        absorb = np.linalg.solve(C[np.ix_(t, t)], C[np.ix_(t, i)])
        vals, vecs = np.linalg.eigh(C[np.ix_(i, i)] - C[np.ix_(i, t)] @ absorb)
    except np.linalg.LinAlgError as exc:  # finite but numerically singular beyond what eigh resolves
        raise InputError(f"the normal equations of {_listed(names)} cannot be analysed ({exc}): these parameters "
                         "are not determined by the observations; give onboard GPS/attitude sigmas "
                         "(POSITION_SIGMA, ATTITUDE_SIGMA), more or better spread GCPs, or fewer unknowns",
                         parameter="") from None
    for v in separated(vecs[:, vals < INTERIOR_SINGULAR], None if prefer is None else prefer[i]).T:
        inner = _members(v, i, names)
        outer = _members(-absorb @ v, t, names)[:2]
        sets.append(inner + outer)
    return sets


def separated(null: np.ndarray, prefer: np.ndarray | None = None) -> np.ndarray:
    """The null directions ``null`` (n, k) recombined so that each moves one pivot parameter the
    others leave still: a space of several directions has no basis of its own, and the one eigh
    returns is decided by rounding (which chip terms joined the attitude pitch bias in a CBERS-02B
    block changed from run to run). Pivots: the parameters of ``prefer`` (n,) bool first, then the
    most involved, each taken when it adds a direction the pivots before it do not span."""
    k = null.shape[1]
    if k < 2:
        return null
    norms = np.linalg.norm(null, axis=1)
    order = np.lexsort((-norms, np.zeros(norms.size, bool) if prefer is None else ~np.asarray(prefer, bool)))
    pivots: list[int] = []
    for row in order:
        if np.linalg.svd(null[pivots + [row]], compute_uv=False)[-1] > PIVOT_SHARE * norms.max():
            pivots.append(int(row))
            if len(pivots) == k:
                break
    return null @ np.linalg.inv(null[pivots]) if len(pivots) == k else null


def _check_finite(N: np.ndarray, names: list[str]) -> None:
    """InputError naming the parameters whose normal equations are not finite numbers: a weight that
    overflowed (a sigma far too small or too large) leaves nothing to analyse."""
    bad = ~np.isfinite(N).all(axis=1)
    if bad.any():
        raise InputError(f"the normal equations of {_listed([n for n, b in zip(names, bad) if b])} are not finite "
                         "numbers: a weight overflowed; check the sigmas that weigh them (image and ground sigmas of "
                         "the points, POSITION_SIGMA, ATTITUDE_SIGMA, INTERIOR priors) for values far too small or "
                         "too large", parameter="")


def _listed(names: list[str], shown: int = 8) -> str:
    more = f" and {len(names) - shown} more" if len(names) > shown else ""
    return ", ".join(names[:shown]) + more


def _members(v: np.ndarray, index: np.ndarray, names: list[str]) -> list[str]:
    big = np.nonzero(np.abs(v) > 0.25 * np.abs(v).max())[0]
    return [names[index[j]] for j in big[np.argsort(-np.abs(v[big]))]]


def _reference_chip(problem: Problem, index: int) -> bool:
    """Whether parameter ``index`` is a term of its camera's reference (middle) chip."""
    p = problem.params.params[index]
    return p.block == "chip" and p.chip == len(problem.scene.cameras[p.camera].chips) // 2


def _choose_to_fix(problem: Problem, members: list[str]) -> str | None:
    """The parameter to fix in a non-determinable set: an interior one, preferably of the
    reference (middle) chip, else the one taking the largest part."""
    params = problem.params
    interior = [n for n in members if params.params[params.index[n]].block not in DATUM_BLOCKS]
    for n in interior:
        if _reference_chip(problem, params.index[n]):
            return n
    return interior[0] if interior else None


def _sets(system: System, names: list[str], trajectory: np.ndarray, prefer: np.ndarray) -> list[list[str]]:
    """:func:`non_determinable` of the whole normal matrix; of a sparse one (a region's,
    :attr:`System.is_sparse`) of each column group's own block (a product, or a strip under one
    trajectory): its parameters against each other with the other products held. A move of the
    whole block that only the priors hold is no defect here (see the module docstring) and is not
    looked for; :mod:`core.adjust.datumdirections` names it after the solution."""
    if not system.is_sparse:
        return non_determinable(system.N, names, trajectory, prefer)
    csr = system.N.tocsr()
    sets = []
    for cols in system.layouts or []:
        sets += non_determinable(csr[cols][:, cols].toarray(), [names[i] for i in cols], trajectory[cols], prefer[cols])
    return sets


def check_determinability(problem: Problem, system: System) -> list[dict]:
    """Find non-determinable parameter sets; fix one interior parameter of each (or stop with
    their names). Returns what was found and done, for the report."""
    found = []
    for _ in range(len(problem.params.params)):
        free = problem.params.free
        names = [problem.params.params[i].name for i in free]
        # A weighted interior parameter is determined by its prior (to at most its sigma) whatever
        # the observations say: like the trajectory it may absorb the others, it is not tested.
        # Its prior is a small share of the information the image observations give it, so the
        # share test would call it non-determinable and fix it at 0, discarding the prior.
        trajectory = np.array([problem.params.params[i].block in DATUM_BLOCKS
                               or problem.params.params[i].mode == "weighted" for i in free])
        sets = _sets(system, names, trajectory, np.array([_reference_chip(problem, i) for i in free]))
        if not sets:
            return found
        # Null directions of one eigenvalue (~rounding) come in any order: take the set whose
        # parameter to fix comes first among the parameters, so the order does not hang on rounding.
        index = problem.params.index
        members = min(sets, key=lambda m: index.get(_choose_to_fix(problem, m), len(index)))
        chosen = _choose_to_fix(problem, members) if problem.settings.on_singular == "fix" else None
        if chosen is None:
            blocks = {problem.params.params[problem.params.index[n]].block for n in members}
            hint = ("" if problem.settings.on_singular == "stop" and blocks - set(DATUM_BLOCKS) else
                    "; give onboard GPS/attitude sigmas, more or better spread GCPs, or a simpler trajectory model"
                    + (" (RPC images: RPC_SIGMA, the vendor's stated accuracy, or a simpler RPC_CORRECTION)"
                       if "rpc_correction" in blocks else ""))
            raise InputError(f"these parameters cannot be determined together from the observations: "
                             f"{', '.join(members)}{hint}")
        found.append({"parameters": members, "fixed": chosen})
        log.warning("not determinable together: %s; fixed %s", ", ".join(members), chosen)
        problem.fix([chosen])
        _, system = problem.system()
    return found

