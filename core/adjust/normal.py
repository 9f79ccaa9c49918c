"""Normal equations of the image observations with the ground points eliminated.

Each control point has one image observation per camera that sees it and, when its ground
coordinates are weighted, three unknowns with a pseudo-observation (east, north, up sigmas).
Writing J_p (2 x q) for the observation's derivatives by the q parameters it touches, J_g
(2 x 3) by its ground point, P its weight and P_G the point's ground weight (ECEF), the
point's unknowns are eliminated by the Schur complement (seed 003 eq. 21-23). For a point seen
once this folds into the observation itself:

    K = (J_g' P J_g + P_G)^-1,   P~ = P - P J_g K J_g' P,   r~ = r - J_g K b_g,
    N += J_p' P~ J_p,            b += J_p' P r~,             b_g = J_g' P r + P_G e

(e = current ground minus measured ground). Tie points have no prior (P_G = 0): their
rays alone fix them, two or more per point. Observations touching the same parameter
columns (same camera, chip and trajectory knots) are stacked and multiplied with BLAS, so
assembly costs one dense product per group. Points seen in several cameras (three-line
scenes, tie points) are eliminated with one dense product per two runs of observations that
share columns (:class:`PointBlocks`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

RIDGE = 1e-9  # share of a point's normal-matrix trace added to its diagonal (see assemble)


@dataclass
class Linearization:
    """Per-observation linearised system: residuals r (n,2) px, weights p (n,2) (1/px^2),
    columns (n,q) unknown indices (-1 unused), values (n,2,q), ground Jacobian jg (n,2,3),
    point (n,) index into the ground unknowns (-1: ground fixed)."""
    r: np.ndarray
    p: np.ndarray
    columns: np.ndarray
    values: np.ndarray
    jg: np.ndarray
    point: np.ndarray


@dataclass
class GroundPrior:
    """Weighted ground points: weight (m,3,3) ECEF (1/m^2), misfit e (m,3) = current -
    measured (m)."""
    weight: np.ndarray
    misfit: np.ndarray


@dataclass
class System:
    """Reduced normal equations N dx = -b of the n_unknowns parameters, with what is needed
    to back-substitute the ground points (K (m,3,3), b_g (m,3)), the weighted squared residuals
    (cost) and the ground prior they were made with."""
    N: np.ndarray
    b: np.ndarray
    K: np.ndarray
    bg: np.ndarray
    cost: float
    prior: GroundPrior | None = None


def groups(columns: np.ndarray) -> list[slice]:
    """Runs of consecutive observations with identical column rows (observations are kept
    sorted so that those sharing columns are adjacent)."""
    if columns.shape[0] == 0:
        return []
    change = np.nonzero(np.any(columns[1:] != columns[:-1], axis=1))[0] + 1
    bounds = np.r_[0, change, columns.shape[0]]
    return [slice(int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:])]


def assemble(lin: Linearization, prior: GroundPrior | None, n_unknowns: int, obs_groups: list[slice],
             ground_damping: float = 0.0) -> System:
    """Reduced normal equations of the image observations (ground eliminated). ground_damping:
    Levenberg-Marquardt damping of the ground unknowns, lambda diag(N_gg) added to each point's
    block before it is eliminated (the parameters' own damping is the solver's)."""
    N = np.zeros((n_unknowns, n_unknowns))
    b = np.zeros(n_unknowns)
    n_points = 0 if prior is None else prior.weight.shape[0]
    K = np.zeros((n_points, 3, 3))
    bg = np.zeros((n_points, 3))
    cost = float(np.sum(lin.p * lin.r * lin.r))
    P = np.zeros((lin.r.shape[0], 2, 2))
    P[:, 0, 0], P[:, 1, 1] = lin.p[:, 0], lin.p[:, 1]
    p_tilde, r_tilde = P, lin.r
    if n_points:
        cost += float(np.einsum("mi,mij,mj->", prior.misfit, prior.weight, prior.misfit))
        seen = lin.point >= 0
        counts = np.bincount(lin.point[seen], minlength=n_points)
        jtp = lin.jg.transpose(0, 2, 1) * lin.p[:, None, :]                # J_g' P (n,3,2)
        ngg = prior.weight + sum_by_point(lin.point[seen], (jtp @ lin.jg)[seen], n_points)
        if ground_damping:
            ngg = ngg + ground_damping * ngg * np.eye(3)
        bg = np.einsum("mij,mj->mi", prior.weight, prior.misfit) + \
            sum_by_point(lin.point[seen], np.einsum("nil,nl->ni", jtp, lin.r)[seen], n_points)
        # A ridge far below any ray's weight: a tie point (no prior) whose rays are all but one
        # down-weighted to zero keeps a finite K (it stays put along its last ray); one with
        # no weight left at all keeps K = 0 (it stays put).
        trace = np.trace(ngg, axis1=1, axis2=2)
        dead = trace <= 0
        K = inverse3(ngg + np.where(dead, 1.0, RIDGE * trace)[:, None, None] * np.eye(3))
        K[dead] = 0.0
        single = (lin.point >= 0) & (counts[np.maximum(lin.point, 0)] == 1)
        if single.any():
            k = K[lin.point[single]]
            pj = np.swapaxes(jtp[single], 1, 2)                            # P J_g (s,2,3)
            p_tilde = P.copy()
            p_tilde[single] = P[single] - pj @ k @ jtp[single]
            r_tilde = lin.r.copy()
            r_tilde[single] = lin.r[single] - np.einsum("nij,njk,nk->ni", lin.jg[single], k, bg[lin.point[single]])
        multi = (lin.point >= 0) & ~single
    else:
        multi = np.zeros(lin.r.shape[0], bool)
    # b = sum J_p' P r~ ; N = sum J_p' P~ J_p (per group of identical columns)
    pr = np.einsum("nij,nj->ni", P, r_tilde)
    contrib = np.einsum("nkq,nk->nq", lin.values, pr)
    ok = lin.columns >= 0
    b += np.bincount(lin.columns[ok], weights=contrib[ok], minlength=n_unknowns)
    chol = _chol2(np.where(multi[:, None, None], P, p_tilde))
    # L' J_p for every observation (L L' = P~), so that N = sum of (L' J_p)' (L' J_p)
    scaled = chol[:, 0, :, None] * lin.values[:, :1, :] + chol[:, 1, :, None] * lin.values[:, 1:, :]
    for idx in obs_groups:
        cols = lin.columns[idx.start]
        keep = cols >= 0
        if not keep.any():
            continue
        block = scaled[idx]
        a = (block if keep.all() else block[:, :, keep]).reshape(-1, int(keep.sum()))
        c = cols[keep]
        N[np.ix_(c, c)] += a.T @ a
    if multi.any():
        _subtract_shared_points(N, b, lin, multi, K, bg, n_unknowns)
    return System(N, b, K, bg, cost, prior)


def inverse3(a: np.ndarray) -> np.ndarray:
    """Inverses of symmetric 3x3 matrices (m,3,3) by their adjugates (np.linalg.inv is ~10x
    slower on millions of small matrices)."""
    a00, a01, a02, a11, a12, a22 = a[:, 0, 0], a[:, 0, 1], a[:, 0, 2], a[:, 1, 1], a[:, 1, 2], a[:, 2, 2]
    c00 = a11 * a22 - a12 * a12
    c01 = a02 * a12 - a01 * a22
    c02 = a01 * a12 - a02 * a11
    c11 = a00 * a22 - a02 * a02
    c12 = a01 * a02 - a00 * a12
    c22 = a00 * a11 - a01 * a01
    det = a00 * c00 + a01 * c01 + a02 * c02
    out = np.stack([c00, c01, c02, c01, c11, c12, c02, c12, c22], axis=1).reshape(-1, 3, 3)
    return out / det[:, None, None]


def sum_by_point(point: np.ndarray, values: np.ndarray, n_points: int) -> np.ndarray:
    """Sums of per-observation arrays values (n, ...) over the observations of each point."""
    if point.size == n_points:
        out = np.zeros((n_points,) + values.shape[1:])
        out[point] = values
        if np.array_equal(np.sort(point), np.arange(n_points)):
            return out  # one observation per point: nothing to sum
    flat = values.reshape(values.shape[0], -1)
    out = np.stack([np.bincount(point, weights=flat[:, k], minlength=n_points) for k in range(flat.shape[1])], 1)
    return out.reshape((n_points,) + values.shape[1:])


def _chol2(p: np.ndarray) -> np.ndarray:
    """Lower Cholesky factors L (n,2,2) of symmetric positive (semi)definite 2x2 matrices
    (L L' = p); semidefinite ones (a fully absorbed observation) get zeros where needed."""
    a, b, c = p[:, 0, 0], p[:, 0, 1], p[:, 1, 1]
    l11 = np.sqrt(np.maximum(a, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        l21 = np.where(l11 > 0, b / l11, 0.0)
    l22 = np.sqrt(np.maximum(c - l21 * l21, 0.0))
    out = np.zeros_like(p)
    out[:, 0, 0], out[:, 1, 0], out[:, 1, 1] = l11, l21, l22
    return out


def run_ids(columns: np.ndarray) -> np.ndarray:
    """(n,) the index of each observation's run of identical column rows (:func:`groups`)."""
    if columns.shape[0] == 0:
        return np.zeros(0, dtype=np.int64)
    return np.concatenate([[0], np.cumsum(np.any(columns[1:] != columns[:-1], axis=1))])


@dataclass
class PointBlocks:
    """The coupling of ground unknowns with the parameters, M_p = sum of J_g' P J_p over a
    point's observations (3 x n_unknowns), kept compact: a point's observations in one run of
    identical columns (one camera or scene) touch the same q columns, so M_p is the sum of one
    block per (point, run) pair, B_i (3, q) in that run's columns, scattered.

    point (k,) and columns (k, q) (unknown indices, -1 unused: B is zero there) of the k pairs,
    grouped by point; obs (o,) the observations summed and pair (o,) the pair of each; crosses:
    per two runs (a, b), the pairs (i, j) of the points seen in both (i in a, j in b; a = b
    included), so that M_p' X M_p sums over them as B_i' X B_j, one dense product per two runs."""
    point: np.ndarray
    columns: np.ndarray
    B: np.ndarray
    obs: np.ndarray
    pair: np.ndarray
    crosses: list[tuple[np.ndarray, np.ndarray]]


def point_blocks(lin: Linearization, mask: np.ndarray) -> PointBlocks:
    """The :class:`PointBlocks` of the observations ``mask`` (n,) (all with a ground unknown)."""
    obs = np.nonzero(mask)[0]
    run = run_ids(lin.columns)[obs]
    order = np.lexsort((run, lin.point[obs]))
    obs, run = obs[order], run[order]
    pts = lin.point[obs]
    new = np.r_[True, (pts[1:] != pts[:-1]) | (run[1:] != run[:-1])]
    starts = np.nonzero(new)[0]
    pj = lin.p[obs][:, :, None] * lin.jg[obs]                                     # P J_g (o,2,3)
    block = np.matmul(pj.transpose(0, 2, 1), lin.values[obs])                    # J_g' P J_p (o,3,q)
    columns = lin.columns[obs[starts]]
    B = np.where(columns[:, None, :] >= 0, _segment_sums(block, starts), 0.0)
    point, pair_run = pts[starts], run[starts]
    return PointBlocks(point, columns, B, obs, np.cumsum(new) - 1, _crosses(point, pair_run))


def _segment_sums(values: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """Sums of values (o, ...) over the segments starting at ``starts`` (k,) (ascending, the
    first 0), in order: a loop over the segments' lengths (a point's observations in one run: a
    few cameras), which is 3x faster than np.add.reduceat over the first axis of 3D arrays."""
    length = np.diff(np.r_[starts, values.shape[0]])
    out = values[starts].copy()
    for m in range(1, int(length.max(initial=1))):
        longer = length > m
        out[longer] += values[starts[longer] + m]
    return out


def _crosses(point: np.ndarray, run: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Every two pairs (i, j) of one point (``point`` (k,) grouped), grouped by their runs."""
    if point.size == 0:
        return []
    first = np.nonzero(np.r_[True, point[1:] != point[:-1]])[0]
    count = np.diff(np.r_[first, point.size])
    i_all, j_all = [], []
    for k in np.unique(count):
        idx = first[count == k][:, None] + np.arange(k)                           # (points, k)
        i_all.append(np.repeat(idx, k, axis=1).ravel())
        j_all.append(np.tile(idx, (1, k)).ravel())
    i, j = np.concatenate(i_all), np.concatenate(j_all)
    key = run[i] * (int(run.max()) + 1) + run[j]
    order = np.argsort(key, kind="stable")
    i, j, key = i[order], j[order], key[order]
    bounds = np.r_[np.nonzero(np.r_[True, key[1:] != key[:-1]])[0], key.size]
    return [(i[a:b], j[a:b]) for a, b in zip(bounds[:-1], bounds[1:])]


def _subtract_shared_points(N, b, lin, multi, K, bg, n_unknowns) -> None:
    """Schur complement of points observed several times: N -= sum of M_p' K_p M_p,
    b -= sum of M_p' K_p b_g, with M_p their couplings (:func:`point_blocks`); one dense
    product per two runs of observations."""
    pb = point_blocks(lin, multi)
    KB = K[pb.point] @ pb.B                                                       # (k,3,q)
    S = np.zeros((n_unknowns, n_unknowns))
    for i, j in pb.crosses:
        ci, cj = pb.columns[i[0]], pb.columns[j[0]]
        ki, kj = ci >= 0, cj >= 0
        product = pb.B[i].reshape(-1, ci.size).T @ KB[j].reshape(-1, cj.size)       # sum of B_i' K B_j (q,q)
        S[np.ix_(ci[ki], cj[kj])] += product[np.ix_(ki, kj)]
    N -= 0.5 * (S + S.T)
    kbg = np.einsum("kij,kj->ki", K[pb.point], bg[pb.point])                      # K_p b_g per pair
    contrib = np.einsum("kaq,ka->kq", pb.B, kbg)
    ok = pb.columns >= 0
    b -= np.bincount(pb.columns[ok], weights=contrib[ok], minlength=n_unknowns)


def back_substitute(lin: Linearization, system: System, dx: np.ndarray) -> np.ndarray:
    """Ground corrections (m,3): dg = -K (b_g + N_gp dx)."""
    if system.K.shape[0] == 0:
        return np.zeros((0, 3))
    step = np.einsum("nkq,nq->nk", lin.values, np.where(lin.columns >= 0, dx[np.maximum(lin.columns, 0)], 0.0))
    sel = lin.point >= 0
    rhs = system.bg + sum_by_point(lin.point[sel], np.einsum("nki,nk->ni", lin.jg[sel], (lin.p * step)[sel]),
                                   system.K.shape[0])
    return -np.einsum("mij,mj->mi", system.K, rhs)
