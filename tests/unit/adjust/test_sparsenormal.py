"""The sparse path of the reduced normal equations (issue 31): on a block where both paths run, the
sparse one gives the dense one's normal matrix, step and cofactor blocks; above SPARSE_UNKNOWNS the
sparse one is chosen; a real block (tests/support/mixed_block.py) adjusts to the same solution and
sigmas on both paths. The synthetic block: 12 products of 6 parameters on a 4 x 3 grid, tie points seen by
a product and a neighbour, some by three products, 0.3 px image sigma, a 10 px prior per parameter."""
from dataclasses import replace

import numpy as np
import pytest
from scipy import sparse

from pushbroom_adjust.core.adjust import AdjustmentSettings, normal
from pushbroom_adjust.core.adjust.block import adjust_block
from pushbroom_adjust.core.adjust.normal import GroundPrior, Linearization, assemble, groups
from pushbroom_adjust.core.adjust.solver import ScaledSystem
from pushbroom_adjust.core.adjust.sparsenormal import NotPositiveDefinite, factorise, inverse_diagonal_bound
from pushbroom_adjust.core.adjust.statistics import cofactor_block, cofactors
from tests.support.mixed_block import MixedBlock

PRODUCTS, TERMS, SIDE = 12, 6, 4
SETTINGS = AdjustmentSettings(position_order=1, attitude_order=1, position_sigma=10.0, attitude_sigma=2e-4)


def region(seed: int = 5) -> tuple[Linearization, GroundPrior, int]:
    rng = np.random.default_rng(seed)
    first = np.repeat(np.arange(PRODUCTS), 40)
    right = np.where(first % SIDE < SIDE - 1, first + 1, first - 1)
    below = np.where(first + SIDE < PRODUCTS, first + SIDE, first - SIDE)
    second = np.where(rng.random(first.size) < 0.5, right, below)
    third = np.where(rng.random(first.size) < 0.2, (first + SIDE + 1) % PRODUCTS, -1)  # some points in three
    n_points = first.size
    point = np.r_[np.arange(n_points), np.arange(n_points), np.nonzero(third >= 0)[0]]
    product = np.r_[first, second, third[third >= 0]]
    order = np.lexsort((point, product))
    point, product = point[order], product[order]
    n = point.size
    columns = product[:, None] * TERMS + np.arange(TERMS)[None, :]
    lin = Linearization(rng.normal(scale=0.3, size=(n, 2)), np.full((n, 2), 1 / 0.09), columns,
                        rng.normal(size=(n, 2, TERMS)), rng.normal(size=(n, 2, 3)), point)
    return lin, GroundPrior(np.zeros((n_points, 3, 3)), np.zeros((n_points, 3))), PRODUCTS * TERMS


def system(monkeypatch, threshold: int):
    monkeypatch.setattr(normal, "SPARSE_UNKNOWNS", threshold)
    lin, prior, u = region()
    out = assemble(lin, prior, u, groups(lin.columns))
    out.add_blocks([(np.arange(p * TERMS, (p + 1) * TERMS), np.eye(TERMS) / 100.0) for p in range(PRODUCTS)])
    return out


def test_the_path_follows_the_threshold(monkeypatch):
    assert not system(monkeypatch, PRODUCTS * TERMS).is_sparse
    s = system(monkeypatch, PRODUCTS * TERMS - 1)
    assert s.is_sparse
    # each product's block, and its blocks with the products it shares points with: not the rest
    lin = region()[0]
    seen = sparse.coo_matrix((np.ones(lin.point.size), (lin.point, lin.columns[:, 0] // TERMS))).tocsr()
    shared = (seen.T @ seen).nnz
    assert s.N.nnz == shared * TERMS ** 2 < 0.7 * (PRODUCTS * TERMS) ** 2
    assert [cols.tolist() for cols in s.layouts] == [list(range(p * TERMS, (p + 1) * TERMS)) for p in range(PRODUCTS)]


def test_sparse_gives_the_dense_normal_matrix_step_and_cofactors(monkeypatch):
    dense, sparse_system = system(monkeypatch, 10 ** 6), system(monkeypatch, 0)
    N = sparse_system.N.toarray()
    assert np.max(np.abs(N - dense.N)) <= 1e-12 * np.max(np.abs(dense.N))
    assert np.array_equal(sparse_system.b, dense.b) and sparse_system.cost == dense.cost
    for lam in (0.0, 1e-3):
        dx_dense, z_dense, f_dense = ScaledSystem(dense).step(lam)
        scaled = ScaledSystem(sparse_system)
        dx, z, f = scaled.step(lam)
        assert np.max(np.abs(dx - dx_dense)) <= 1e-9 * np.max(np.abs(dx_dense))
        # the sparse step test bounds the dense one from above, within a factor of the coupling
        exact, bound = ScaledSystem(dense).relative(z_dense, f_dense, lam), scaled.relative(z, f, lam)
        assert exact <= bound <= 3.0 * exact
    Q_dense, Q = cofactors(dense), cofactors(sparse_system)
    assert sparse.issparse(Q) and Q.nnz == sparse_system.N.nnz  # only on the blocks of N
    for p in range(PRODUCTS):
        cols = np.arange(p * TERMS, (p + 1) * TERMS)
        block = Q_dense[np.ix_(cols, cols)]
        assert np.max(np.abs(cofactor_block(Q, cols, cols) - block)) <= 1e-9 * np.max(np.abs(block))
    rows, cols = sparse_system.N.nonzero()  # the couplings between products too
    assert np.max(np.abs(np.asarray(Q[rows, cols]).ravel() - Q_dense[rows, cols])) <= 1e-9 * np.abs(Q_dense).max()


def test_the_diagonal_bound_is_below_the_inverse_diagonal(monkeypatch):
    s = system(monkeypatch, 0)
    exact = np.diag(np.linalg.inv(s.N.toarray()))
    bound = inverse_diagonal_bound(s.N, s.layouts)
    assert np.all(bound <= exact * (1 + 1e-12)) and np.all(bound > 0.3 * exact)


def test_a_singular_matrix_is_refused():
    N = sparse.csc_matrix(np.array([[1.0, 1.0], [1.0, 1.0]]))
    with pytest.raises(NotPositiveDefinite):
        factorise(N)


@pytest.fixture(scope="module")
def mixed_block(tmp_path_factory) -> MixedBlock:
    return MixedBlock(tmp_path_factory.mktemp("mixed"))


def both_paths(monkeypatch, adjust) -> tuple:
    """``adjust()`` on the dense path, then on the sparse path forced (SPARSE_UNKNOWNS 0)."""
    dense = adjust()
    monkeypatch.setattr(normal, "SPARSE_UNKNOWNS", 0)
    return dense, adjust()


def assert_same_solution(dense, sparse_out) -> None:
    """Parameters' values to 1e-7 of their sigmas, sigmas to 1e-8 relative, the GCPs' redundancy
    numbers to 1e-7 and sigma0 to 1e-9. Not closer: a rigorous scene's position and attitude terms
    are correlated (condition ~1e8), so two factorisations' rounding differs there (and the
    statistics are taken at solutions that differ by it); measured: the mixed block's values 3e-8 of
    their sigmas, sigmas 2e-9, redundancy numbers 1e-8 relative; the RPC block's 1e-12 and 4e-10."""
    a, b = dense.adjustment.report, sparse_out.adjustment.report
    assert [p["name"] for p in a["parameters"]] == [p["name"] for p in b["parameters"]]
    va, vb = (np.array([[p["value"], p["sigma"] or np.nan] for p in r["parameters"]]) for r in (a, b))
    free = ~np.isnan(va[:, 1])
    assert np.all(np.abs(vb[free, 0] - va[free, 0]) <= 1e-7 * va[free, 1])
    assert np.all(np.abs(vb[free, 1] - va[free, 1]) <= 1e-8 * va[free, 1])
    assert np.array_equal(va[~free, 0], vb[~free, 0])
    ra, rb = (np.asarray(out.adjustment.points["redundancy"], float) for out in (dense, sparse_out))
    assert np.allclose(ra, rb, rtol=1e-7, atol=1e-12, equal_nan=True)
    assert abs(b["sigma0"] - a["sigma0"]) <= 1e-9 * a["sigma0"]


def test_a_mixed_block_adjusts_the_same_on_both_paths(mixed_block, monkeypatch):
    """Two rigorous scenes and an RPC product, GCPs and tie points (tests/support/mixed_block.py):
    the same solution, sigmas and redundancy numbers dense and sparse."""
    ties, gcps, _ = mixed_block.tables(mixed_block.true)
    dense, sparse_out = both_paths(monkeypatch, lambda: adjust_block(mixed_block.onboard, gcps, ties, SETTINGS))
    assert_same_solution(dense, sparse_out)


def test_an_rpc_ties_only_block_adjusts_the_same_on_both_paths(mixed_block, monkeypatch):
    """Three RPC products held by their vendor accuracy (RPC_SIGMA 5 px), no GCPs: the datum
    directions (core.adjust.datumdirections) are computed on the sparse path too."""
    ties, _, _ = mixed_block.tables(mixed_block.rpc_true)
    settings = replace(SETTINGS, rpc_sigma=5.0)
    dense, sparse_out = both_paths(monkeypatch, lambda: adjust_block(mixed_block.rpc_vendor, None, ties, settings))
    assert_same_solution(dense, sparse_out)
    assert dense.report["datum"] == sparse_out.report["datum"]
