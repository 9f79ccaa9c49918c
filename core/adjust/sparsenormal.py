"""The sparse path of the reduced normal equations (above :data:`core.adjust.normal.SPARSE_UNKNOWNS`
unknowns): factorisation, the step-size bound and the cofactors where they are reported.

Products (RPC images, scenes, strips) couple only through the points they share, so the reduced
normal matrix N (u x u) of a region is sparse: a product's block and those of its neighbours. It is
factorised by SuperLU (scipy.sparse.linalg.splu) with a fill-reducing minimum-degree order on
N + N' (MMD_AT_PLUS_A), symmetric mode and diagonal pivots (N is symmetric positive definite after
the Jacobi scaling of :class:`core.adjust.solver.ScaledSystem`, so no pivoting is needed).

Cofactors Q = N^-1 are computed only on the block pattern of N (selected entries: each product's
own block and its blocks with the products it shares points with, :func:`block_pattern`), by
solves with the unit columns of a batch of unknowns, keeping the rows on that pattern: the
redundancy numbers, the ground points' cofactors and the parameters' sigmas need no other entry.
The full inverse is never formed.
"""
from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.sparse import linalg as splinalg

SOLVE_COLUMNS = 256  # unit columns solved at once for the selected cofactors (u x 256 numbers)


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
    term), taken over each column group's unknowns ``layouts``; 1 / N_ii for unknowns in none."""
    out = 1.0 / N.diagonal()
    csr = sparse.csr_matrix(N)
    for cols in layouts:
        if cols.size:
            block = csr[cols][:, cols].toarray()
            out[cols] = np.diag(np.linalg.inv(block))
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


def selected_cofactors(lu: splinalg.SuperLU, pattern: sparse.spmatrix) -> sparse.csc_matrix:
    """Q = N^-1 on the nonzero pattern of ``pattern`` (u, u) (:func:`block_pattern`), N factorised as ``lu``:
    solves with SOLVE_COLUMNS unit columns at a time, of which only the pattern's rows are kept."""
    pat = sparse.csc_matrix(pattern)
    pat.sort_indices()
    n = pat.shape[0]
    data = np.empty(pat.indices.size)
    for start in range(0, n, SOLVE_COLUMNS):
        stop = min(n, start + SOLVE_COLUMNS)
        rhs = np.zeros((n, stop - start))
        rhs[np.arange(start, stop), np.arange(stop - start)] = 1.0
        x = lu.solve(rhs)
        a, b = pat.indptr[start], pat.indptr[stop]
        column = np.repeat(np.arange(stop - start), np.diff(pat.indptr[start:stop + 1]))
        data[a:b] = x[pat.indices[a:b], column]
    Q = sparse.csc_matrix((data, pat.indices.copy(), pat.indptr.copy()), shape=pat.shape)
    return (0.5 * (Q + Q.T)).tocsc()  # the two triangles agree to rounding
