"""The sparse path of the reduced normal equations (above :data:`core.adjust.normal.SPARSE_UNKNOWNS`
unknowns): factorisation, the step-size bound and the cofactors where they are reported.

Products (RPC images, scenes, strips) couple only through the points they share, so the reduced
normal matrix N (u x u) of a region is sparse: a product's block and those of its neighbours. It is
factorised by SuperLU (scipy.sparse.linalg.splu) with a fill-reducing minimum-degree order on
N + N' (MMD_AT_PLUS_A), symmetric mode and diagonal pivots (N is symmetric positive definite after
the Jacobi scaling of :class:`core.adjust.solver.ScaledSystem`, so no pivoting is needed).

Cofactors Q = N^-1 are computed only on the block pattern of N (selected entries: each product's
own block and its blocks with the products it shares points with, :func:`block_pattern`) by the
Takahashi recurrences on the sparse factors (:func:`selected_inverse`): the redundancy numbers, the
ground points' cofactors and the parameters' sigmas need no other entry. The full inverse is never
formed.
"""
from __future__ import annotations

import numpy as np
from scipy import linalg, sparse
from scipy.sparse import linalg as splinalg


class NotPositiveDefinite(ValueError):
    """The sparse factorisation met a zero or non-finite pivot."""


def factorise(N: sparse.spmatrix) -> splinalg.SuperLU:
    """SuperLU factors of the symmetric positive definite N (u, u) with a fill-reducing order
    (see the module docstring). Raises NotPositiveDefinite on a singular matrix."""
    try:
        lu = splinalg.splu(sparse.csc_matrix(N), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                           options={"SymmetricMode": True})
    except RuntimeError as err:  # "Factor is exactly singular"
        raise NotPositiveDefinite(str(err)) from None
    pivots = lu.U.diagonal()
    if not np.all(np.isfinite(pivots)) or np.any(pivots <= 0):
        raise NotPositiveDefinite("the normal matrix is not positive definite")
    return lu


def inverse_diagonal_bound(N: sparse.spmatrix, layouts: list[np.ndarray]) -> np.ndarray:
    """(u,) lower bounds of the diagonal of N^-1: for any set B of unknowns, (N^-1)_BB >= (N_BB)^-1
    (the inverse of a principal block is the inverse's block less a positive semidefinite Schur
    term), taken over each column group's unknowns ``layouts``; 1 / N_ii for unknowns in none.
    The groups of one size are gathered and inverted at once."""
    out = 1.0 / N.diagonal()
    csr = sparse.csr_matrix(N)
    sizes = np.array([cols.size for cols in layouts])
    for q in np.unique(sizes[sizes > 0]):
        cols = np.stack([c for c in layouts if c.size == q])                       # (m, q)
        rows, columns = np.broadcast_arrays(cols[:, :, None], cols[:, None, :])
        blocks = np.asarray(csr[rows.ravel(), columns.ravel()]).reshape(-1, q, q)
        out[cols] = np.diagonal(np.linalg.inv(blocks), axis1=1, axis2=2)
    return out


def block_pattern(N: sparse.spmatrix, layouts: list[np.ndarray]) -> sparse.csc_matrix:
    """(u, u) the pattern of the blocks the statistics read: every column group's (``layouts``)
    own block, whole, and its whole blocks with each group N couples it to (an entry of N that is
    exactly zero, such as between an RPC correction's column and row terms, may have a nonzero
    cofactor). Unknowns in no group are a group each."""
    n = N.shape[0]
    group = np.full(n, -1, dtype=np.int64)
    for g, cols in enumerate(layouts):
        group[cols] = g
    alone = np.nonzero(group < 0)[0]
    group[alone] = len(layouts) + np.arange(alone.size)
    coo = sparse.coo_matrix(N)
    n_groups = len(layouts) + alone.size
    coupled = sparse.coo_matrix((np.ones(coo.nnz + n_groups), (np.r_[group[coo.row], np.arange(n_groups)],
                                                               np.r_[group[coo.col], np.arange(n_groups)])),
                                shape=(n_groups, n_groups)).tocsr()
    member = sparse.csr_matrix((np.ones(n), (group, np.arange(n))), shape=(n_groups, n))  # group x unknown
    pattern = (member.T @ coupled @ member).tocsc()
    pattern.data[:] = 1.0
    return pattern


def on_pattern(N: sparse.spmatrix, pattern: sparse.spmatrix) -> sparse.csc_matrix:
    """N with an entry stored at every position of ``pattern`` (zeros included), so that its factor's
    structure holds the pattern (:func:`selected_inverse` reads the inverse there)."""
    coo = sparse.coo_matrix(pattern)
    values = np.asarray(sparse.csr_matrix(N)[coo.row, coo.col]).ravel()
    return sparse.csc_matrix((values, (coo.row, coo.col)), shape=N.shape)


def selected_inverse(lu: splinalg.SuperLU, pattern: sparse.spmatrix) -> sparse.csc_matrix:
    """Q = N^-1 on the pattern of ``pattern`` (:func:`block_pattern`), from the factors ``lu`` of N
    (:func:`factorise` of :func:`on_pattern`): the Takahashi recurrences (Takahashi, Fagan and Chen
    1973; Erisman and Tinney 1975) on N's LDL' factorisation, supernode by supernode, which give the
    inverse on the factor's structure (a superset of N's) without forming any other entry.

    SuperLU in symmetric mode without pivoting factorises P N P' = L U with U = D L' (L unit lower).
    For a supernode J of consecutive columns sharing the rows R below them:
    Z_RJ = -Z_RR L_RJ L_JJ^-1 and Z_JJ = (L_JJ^-T D_J^-1 - Z_JR L_RJ) L_JJ^-1, Z = (P N P')^-1,
    from the last supernode to the first."""
    if not np.array_equal(lu.perm_r, lu.perm_c):
        raise NotPositiveDefinite("the factorisation pivoted: the normal matrix is not positive definite")
    L = sparse.csc_matrix(lu.L)
    L.sort_indices()
    keys, Z = _takahashi(L.indptr, L.indices, L.data, lu.U.diagonal())
    n = L.shape[0]
    position = lu.perm_c                                                         # row of N -> row of L
    pat = sparse.coo_matrix(pattern)
    i, j = position[pat.row], position[pat.col]
    key = np.minimum(i, j) * n + np.maximum(i, j)
    at = np.minimum(np.searchsorted(keys, key), keys.size - 1)
    if not np.array_equal(keys[at], key):
        raise ValueError("the pattern is not within the factor's structure (factorise on_pattern(N, pattern))")
    return sparse.csc_matrix((Z[at], (pat.row, pat.col)), shape=pat.shape)


def _supernodes(Lp: np.ndarray, Li: np.ndarray) -> np.ndarray:
    """Bounds (k + 1,) of the runs of consecutive columns of L (CSC, rows sorted) whose rows below
    the diagonal are the next column's rows: column j's are j + 1 and those of column j + 1."""
    n = Lp.size - 1
    same = [j + 1 for j in range(n - 1) if Lp[j + 1] - Lp[j] - 1 == Lp[j + 2] - Lp[j + 1]
            and np.array_equal(Li[Lp[j] + 1:Lp[j + 1]], Li[Lp[j + 1]:Lp[j + 2]])]
    return np.setdiff1d(np.arange(n + 1), same)


def _takahashi(Lp: np.ndarray, Li: np.ndarray, Lx: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(keys, Z): the inverse of L D L' at each entry of L (CSC; key column * n + row, ascending)."""
    n = Lp.size - 1
    keys = np.repeat(np.arange(n, dtype=np.int64), np.diff(Lp)) * n + Li
    Z = np.zeros(Li.size)
    bounds = _supernodes(Lp, Li)
    for j0, j1 in zip(bounds[-2::-1], bounds[:0:-1]):
        w = j1 - j0
        R = Li[Lp[j1 - 1] + 1:Lp[j1]]                                           # rows below the supernode
        LJJ, LRJ = np.zeros((w, w)), np.zeros((R.size, w))
        for k, j in enumerate(range(j0, j1)):                                   # column j: rows j..j1-1, then R
            column = Lx[Lp[j]:Lp[j + 1]]
            LJJ[k:, k], LRJ[:, k] = column[:w - k], column[w - k:]
        ZRJ = np.zeros((0, w))
        if R.size:
            lower = np.minimum.outer(R, R) * n + np.maximum.outer(R, R)
            ZRR = Z[np.searchsorted(keys, lower)]
            ZRJ = -_right_inverse(LJJ, ZRR @ LRJ)
        ZJJ = _right_inverse(LJJ, _right_inverse(LJJ, np.diag(1.0 / d[j0:j1])).T - ZRJ.T @ LRJ)
        ZJJ = 0.5 * (ZJJ + ZJJ.T)
        for k, j in enumerate(range(j0, j1)):
            Z[Lp[j]:Lp[j] + w - k], Z[Lp[j] + w - k:Lp[j + 1]] = ZJJ[k:, k], ZRJ[:, k]
    return keys, Z


def _right_inverse(LJJ: np.ndarray, X: np.ndarray) -> np.ndarray:
    """X L_JJ^-1 (L_JJ unit lower triangular)."""
    return linalg.solve_triangular(LJJ, X.T, trans="T", lower=True, unit_diagonal=True).T
