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
scenes, tie points) are eliminated with one dense product per two groups of observations that
share columns (:class:`PointBlocks`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.sparse import csgraph

RIDGE = 1e-9  # share of a point's normal-matrix trace added to its diagonal (see assemble)
# Above this many unknowns the reduced normal matrix is held sparse (scipy.sparse CSR): products
# couple only through shared points, and a dense matrix costs n^2 memory and an n^3 factorisation.
# Below it the dense matrix is faster (see docs/development.md, "The solver", for the figures).
SPARSE_UNKNOWNS = 1500


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
    N: np.ndarray | sparse.csr_matrix
    b: np.ndarray
    K: np.ndarray
    bg: np.ndarray
    cost: float
    prior: GroundPrior | None = None
    layouts: list[np.ndarray] | None = None

    @property
    def is_sparse(self) -> bool:
        """Whether N is held sparse (above SPARSE_UNKNOWNS unknowns); then ``layouts`` holds the
        unknowns of each column group (:func:`column_groups`: one product, or a strip under one
        trajectory), whose diagonal blocks of N are full."""
        return sparse.issparse(self.N)

    def add_blocks(self, blocks: list[tuple[np.ndarray, np.ndarray]]) -> None:
        """Add symmetric blocks (cols (q,), block (q, q)) to N (pseudo-observations)."""
        acc = _Accumulator(self.N.shape[0], self.is_sparse, None if self.is_sparse else self.N)
        for cols, block in blocks:
            acc.add(cols, cols, block)
        if self.is_sparse:
            self.N = (self.N + acc.matrix()).tocsr()


class _Accumulator:
    """Sums of blocks at (rows, cols) of an n x n matrix: added into a dense array in place, or
    kept as coordinate lists and summed into a CSR matrix at the end (memory of the blocks only)."""

    def __init__(self, n: int, sparse_form: bool, dense: np.ndarray | None = None):
        self.n, self.sparse_form = n, sparse_form
        self.dense = None if sparse_form else (np.zeros((n, n)) if dense is None else dense)
        self.rows, self.cols, self.values = [], [], []

    def add(self, rows: np.ndarray, cols: np.ndarray, block: np.ndarray) -> None:
        if not self.sparse_form:
            self.dense[np.ix_(rows, cols)] += block
            return
        self.rows.append(np.repeat(rows, cols.size))
        self.cols.append(np.tile(cols, rows.size))
        self.values.append(block.ravel())

    def matrix(self) -> np.ndarray | sparse.csr_matrix:
        if not self.sparse_form:
            return self.dense
        if not self.values:
            return sparse.csr_matrix((self.n, self.n))
        return sparse.coo_matrix((np.concatenate(self.values), (np.concatenate(self.rows), np.concatenate(self.cols))),
                                 shape=(self.n, self.n)).tocsr()


def groups(columns: np.ndarray) -> list[slice]:
    """Runs of consecutive observations with identical column rows (observations are kept
    sorted so that those sharing columns are adjacent)."""
    if columns.shape[0] == 0:
        return []
    bounds = np.r_[0, np.nonzero(np.diff(run_ids(columns)))[0] + 1, columns.shape[0]]
    return [slice(int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:])]


def assemble(lin: Linearization, prior: GroundPrior | None, n_unknowns: int, obs_groups: list[slice],
             ground_damping: float = 0.0) -> System:
    """Reduced normal equations of the image observations (ground eliminated). ground_damping:
    Levenberg-Marquardt damping of the ground unknowns, lambda diag(N_gg) added to each point's
    block before it is eliminated (the parameters' own damping is the solver's)."""
    sparse_form = n_unknowns > SPARSE_UNKNOWNS
    acc = _Accumulator(n_unknowns, sparse_form)
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
        acc.add(c, c, a.T @ a)
    N = acc.matrix()
    if multi.any():
        N = _subtract_shared_points(N, b, lin, multi, K, bg, n_unknowns)
    return System(N, b, K, bg, cost, prior, column_groups(lin.columns)[1] if sparse_form else None)


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


def column_groups(columns: np.ndarray) -> tuple[np.ndarray, list[np.ndarray], np.ndarray]:
    """Observations whose columns (n, q) overlap, directly or through others, form one group:
    a scene of a block (its trajectory and interior), or a whole strip under one piecewise
    trajectory, whose observations touch a different window of knots each. Returns the group of
    each observation (n,), each group's layout (the sorted union of its columns), and each
    observation's slots in its group's layout (n, q) (-1 where its column is -1)."""
    run = run_ids(columns)
    first = np.nonzero(np.r_[True, run[1:] != run[:-1]])[0] if run.size else np.zeros(0, dtype=np.int64)
    run_cols = columns[first]                                                     # (R, q)
    n_runs, n_cols = run_cols.shape[0], int(columns.max(initial=-1)) + 1
    r, k = np.nonzero(run_cols >= 0)
    graph = sparse.coo_matrix((np.ones(r.size), (r, n_runs + run_cols[r, k])), shape=(n_runs + n_cols,) * 2)
    _, component = csgraph.connected_components(graph, directed=False)
    _, run_group = np.unique(component[:n_runs], return_inverse=True)
    layouts, slots = [], np.full(run_cols.shape, -1, dtype=np.int64)
    for g in range(int(run_group.max(initial=-1)) + 1):
        mine = run_group == g
        cols = run_cols[mine]
        layout = np.unique(cols[cols >= 0])
        slots[mine] = np.where(cols >= 0, np.searchsorted(layout, cols), -1)
        layouts.append(layout)
    return run_group[run], layouts, slots[run]


@dataclass
class GroupBlocks:
    """The points' couplings within one column group (:func:`column_groups`): point (k,) the
    points seen in the group (ascending), B (k, 3, q) the sum of J_g' P J_p over each point's
    observations in the group, in the group's layout ``columns`` (q,) of unknown indices; obs
    (o,) the observations summed, pair (o,) the row of B each went to, slots (o, q_obs) where
    each observation's own columns lie in the layout (-1: unused)."""
    point: np.ndarray
    B: np.ndarray
    columns: np.ndarray
    obs: np.ndarray
    pair: np.ndarray
    slots: np.ndarray


@dataclass
class PointBlocks:
    """The coupling of ground unknowns with the parameters, M_p = sum of J_g' P J_p over a
    point's observations (3 x n_unknowns), kept compact: one block per (point, column group),
    B (3, q) in that group's columns (:class:`GroupBlocks`), so that M_p' X M_p sums over the
    points seen in two groups (a, b) as B_a' X_ab B_b, one dense product per two groups.
    crosses: per two groups (a, b) (a = b included), the rows (i of group a, j of group b)
    that belong to the same points."""
    groups: list[GroupBlocks]
    crosses: list[tuple[int, int, np.ndarray, np.ndarray]]


def point_blocks(lin: Linearization, mask: np.ndarray) -> PointBlocks:
    """The :class:`PointBlocks` of the observations ``mask`` (n,) (all with a ground unknown)."""
    group, layouts, slots = column_groups(lin.columns)
    obs = np.nonzero(mask)[0]
    obs = obs[np.lexsort((lin.point[obs], group[obs]))]
    pj = lin.p[obs][:, :, None] * lin.jg[obs]                                     # P J_g (o,2,3)
    block = np.matmul(pj.transpose(0, 2, 1), lin.values[obs])                    # J_g' P J_p (o,3,q_obs)
    bounds = np.searchsorted(group[obs], np.arange(len(layouts) + 1))
    out = []
    for g, layout in enumerate(layouts):
        a, b = bounds[g], bounds[g + 1]
        if a == b or layout.size == 0:
            continue
        mine, where = obs[a:b], slots[obs[a:b]]
        pts = lin.point[mine]
        new = np.r_[True, pts[1:] != pts[:-1]]
        pair = np.cumsum(new) - 1
        # each observation's (3, q_obs) added into its point's row at its slots: one bincount
        flat = (pair[:, None, None] * 3 + np.arange(3)[None, :, None]) * layout.size + where[:, None, :]
        used = np.broadcast_to(where[:, None, :] >= 0, flat.shape)
        B = np.bincount(flat[used], weights=block[a:b][used], minlength=(pair[-1] + 1) * 3 * layout.size)
        out.append(GroupBlocks(pts[new], B.reshape(-1, 3, layout.size), layout, mine, pair, where))
    return PointBlocks(out, _crosses(out))


def _crosses(groups: list[GroupBlocks]) -> list[tuple[int, int, np.ndarray, np.ndarray]]:
    """(a, b, i, j) for every two groups a, b that share points: rows i of group a and j of
    group b of the same points, i ascending. Found from the points' own entries (every two rows
    of one point, k^2 for a point in k groups, sorted by their two groups), so that the cost is
    that of the points, not of the groups squared times the points."""
    if not groups:
        return []
    group = np.concatenate([np.full(g.point.size, k, dtype=np.int64) for k, g in enumerate(groups)])
    row = np.concatenate([np.arange(g.point.size, dtype=np.int64) for g in groups])
    point = np.concatenate([g.point for g in groups])
    order = np.lexsort((group, point))
    group, row, point = group[order], row[order], point[order]
    starts = np.r_[0, np.nonzero(np.diff(point))[0] + 1]
    size = np.diff(np.r_[starts, point.size])                                     # groups of each point
    per_entry = np.repeat(size, size)                                            # partners of each entry
    first = np.repeat(np.arange(point.size), per_entry)
    offset = np.arange(first.size) - np.repeat(np.cumsum(per_entry) - per_entry, per_entry)
    second = np.repeat(np.repeat(starts, size), per_entry) + offset
    key = group[first] * len(groups) + group[second]
    by_key = np.argsort(key, kind="stable")                                      # stable: points stay ascending
    key, first, second = key[by_key], first[by_key], second[by_key]
    bounds = np.r_[0, np.nonzero(np.diff(key))[0] + 1, key.size]
    return [(int(key[s] // len(groups)), int(key[s] % len(groups)), row[first[s:e]], row[second[s:e]])
            for s, e in zip(bounds[:-1], bounds[1:])]


def _subtract_shared_points(N, b, lin, multi, K, bg, n_unknowns):
    """Schur complement of points observed several times: N -= sum of M_p' K_p M_p,
    b -= sum of M_p' K_p b_g (b in place), with M_p their couplings (:func:`point_blocks`); one
    dense product per two column groups that share points. Returns N (dense: changed in place)."""
    pb = point_blocks(lin, multi)
    KB = [K[g.point] @ g.B for g in pb.groups]                                   # (k,3,q) per group
    acc = _Accumulator(n_unknowns, sparse.issparse(N))
    for a, c, i, j in pb.crosses:
        ga, gc = pb.groups[a], pb.groups[c]
        acc.add(ga.columns, gc.columns, ga.B[i].reshape(-1, ga.columns.size).T @
                KB[c][j].reshape(-1, gc.columns.size))                           # sum of B_a' K B_c
    S = acc.matrix()
    if sparse.issparse(N):
        N = (N - 0.5 * (S + S.T)).tocsr()
    else:
        N -= 0.5 * (S + S.T)
    for g in pb.groups:
        kbg = np.einsum("kij,kj->ki", K[g.point], bg[g.point])                  # K_p b_g per point
        b[g.columns] -= np.einsum("kaq,ka->q", g.B, kbg)
    return N


def back_substitute(lin: Linearization, system: System, dx: np.ndarray) -> np.ndarray:
    """Ground corrections (m,3): dg = -K (b_g + N_gp dx)."""
    if system.K.shape[0] == 0:
        return np.zeros((0, 3))
    step = np.einsum("nkq,nq->nk", lin.values, np.where(lin.columns >= 0, dx[np.maximum(lin.columns, 0)], 0.0))
    sel = lin.point >= 0
    rhs = system.bg + sum_by_point(lin.point[sel], np.einsum("nki,nk->ni", lin.jg[sel], (lin.p * step)[sel]),
                                   system.K.shape[0])
    return -np.einsum("mij,mj->mi", system.K, rhs)
