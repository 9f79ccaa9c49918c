"""Speed and memory of the reduced normal equations of a region (issue 31, "a solver that scales"):
assembly, one damped step, the step-size test and the cofactors the statistics read, on the dense
and the sparse path (:mod:`core.adjust.sparsenormal`). Prints figures (no assertions).

Run:  PYTHONPATH=. /usr/bin/python3 tests/bench/bench_solver.py [--products 20 60 200 1000]
      [--ties 1000] [--dense-up-to 1500]

The system is synthetic (not the block simulation, which takes tens of minutes at these sizes): a
square grid of products with 6 parameters each (an RPC image's affine correction), --ties tie
points per product, each seen by its product and one neighbour (right, below or diagonal), 2
observations of 2 rows per point (1,000 products: 1 M points, 2 M observations, 6,000 unknowns),
random derivatives of unit size, 0.3 px image sigma, a 10 px prior on every parameter (no GCPs).
Each size runs in a child process: peak resident memory (VmHWM) of that size alone. Then the growth
exponents of time and memory between the sizes. The sparse path is forced at every size (SPARSE_UNKNOWNS 0); the dense one runs up to
--dense-up-to unknowns, and where both run the largest difference of their steps and cofactor
blocks is printed.
"""
from __future__ import annotations

import argparse
import math
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))
import tests.support.plugin_package  # noqa: E402,F401 (registers the package pushbroom_adjust)
from tests.bench.peak import peak_mb, reset_peak  # noqa: E402

from pushbroom_adjust.core.adjust import normal  # noqa: E402
from pushbroom_adjust.core.adjust.normal import GroundPrior, Linearization, assemble, groups  # noqa: E402
from pushbroom_adjust.core.adjust.solver import ScaledSystem  # noqa: E402
from pushbroom_adjust.core.adjust.statistics import cofactor_block, cofactors  # noqa: E402

Q_TERMS = 6
SIGMA_PX = 0.3
PRIOR_PX = 10.0


def region(n_products: int, ties: int, seed: int = 3) -> tuple[Linearization, GroundPrior, int]:
    """The synthetic linearisation of a grid of ``n_products`` (see the module docstring)."""
    rng = np.random.default_rng(seed)
    side = math.ceil(math.sqrt(n_products))
    k = np.arange(n_products)
    first = np.repeat(k, ties)
    r, c = first // side, first % side
    move = rng.integers(0, 3, first.size)                          # 0 right, 1 below, 2 diagonal
    r2, c2 = r + (move > 0), c + (move != 1)
    wrap = (r2 >= side) | (c2 >= side) | (r2 * side + c2 >= n_products)
    second = np.where(wrap, np.where(first > 0, first - 1, 1), r2 * side + c2)
    n_points = first.size
    point = np.r_[np.arange(n_points), np.arange(n_points)]
    product = np.r_[first, second]
    order = np.lexsort((point, product))                           # observations sharing columns adjacent
    point, product = point[order], product[order]
    n = point.size
    columns = product[:, None] * Q_TERMS + np.arange(Q_TERMS)[None, :]
    values = rng.normal(size=(n, 2, Q_TERMS))
    jg = rng.normal(size=(n, 2, 3))
    lin = Linearization(rng.normal(scale=SIGMA_PX, size=(n, 2)), np.full((n, 2), SIGMA_PX ** -2), columns, values,
                        jg, point)
    return lin, GroundPrior(np.zeros((n_points, 3, 3)), np.zeros((n_points, 3))), n_products * Q_TERMS


def run(n_products: int, ties: int, dense: bool) -> None:
    """The child process: one size, one path; prints one line of figures."""
    lin, prior, u = region(n_products, ties)
    obs_groups = groups(lin.columns)
    normal.SPARSE_UNKNOWNS = 10 ** 9 if dense else 0  # each path whatever the size
    reset_peak()
    t0 = time.perf_counter()
    system = assemble(lin, prior, u, obs_groups)
    system.add_blocks([(np.arange(u), np.eye(u) / PRIOR_PX ** 2)] if dense else
                      [(np.arange(p * Q_TERMS, (p + 1) * Q_TERMS), np.eye(Q_TERMS) / PRIOR_PX ** 2)
                       for p in range(n_products)])
    t1 = time.perf_counter()
    scaled = ScaledSystem(system)
    dx, z, factor = scaled.step(0.0)
    t2 = time.perf_counter()
    relative = scaled.relative(z, factor, 0.0)
    t3 = time.perf_counter()
    Q = cofactors(system)
    t4 = time.perf_counter()
    nnz = system.N.nnz if system.is_sparse else u * u
    print(f"{'dense ' if dense else 'sparse'} {n_products:5d} products, {lin.r.shape[0]:8d} observations, {u:6d} "
          f"unknowns, N {nnz} entries: assembly {t1 - t0:7.2f} s, step {t2 - t1:7.2f} s, step test {t3 - t2:6.2f} s, "
          f"cofactors {t4 - t3:7.2f} s, total {t4 - t0:7.2f} s; peak {peak_mb():7.0f} MB (relative {relative:.3g})")
    save = Path(f"/tmp/bench_solver_{n_products}_{'dense' if dense else 'sparse'}.npz")
    blocks = np.stack([cofactor_block(Q, np.arange(Q_TERMS) + p * Q_TERMS, np.arange(Q_TERMS) + p * Q_TERMS)
                       for p in range(n_products)])
    np.savez(save, dx=dx, blocks=blocks)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--products", type=int, nargs="+", default=[20, 60, 200, 1000])
    ap.add_argument("--ties", type=int, default=1000, help="tie points per product")
    ap.add_argument("--dense-up-to", type=int, default=1500, help="largest number of unknowns run dense too")
    ap.add_argument("--child", nargs=3, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        run(int(args.child[0]), int(args.child[1]), args.child[2] == "dense")
        return
    figures = {}
    for n in args.products:
        for path in (("dense", "sparse") if n * Q_TERMS <= args.dense_up_to else ("sparse",)):
            out = subprocess.run([sys.executable, __file__, "--child", str(n), str(args.ties), path], check=True,
                                 capture_output=True, text=True).stdout
            print(out.strip(), flush=True)
            figures[(n, path)] = (float(out.split("total")[1].split("s;")[0]), float(out.split("peak")[1].split("MB")[0]))
        if (n, "dense") in figures:
            a, b = np.load(f"/tmp/bench_solver_{n}_dense.npz"), np.load(f"/tmp/bench_solver_{n}_sparse.npz")
            print(f"  dense against sparse: step {np.max(np.abs(a['dx'] - b['dx'])) / np.max(np.abs(a['dx'])):.2g}, "
                  f"cofactor blocks {np.max(np.abs(a['blocks'] - b['blocks'])) / np.max(np.abs(a['blocks'])):.2g} "
                  "(largest difference / largest value)")
    sizes = [n for n in args.products if (n, "sparse") in figures]
    for a, b in zip(sizes[:-1], sizes[1:]):
        ta, ma = figures[(a, "sparse")]
        tb, mb = figures[(b, "sparse")]
        print(f"sparse {a} -> {b} products: time exponent {math.log(tb / ta) / math.log(b / a):.2f} (the total "
              f"above), memory exponent {math.log(mb / ma) / math.log(b / a):.2f}")


if __name__ == "__main__":
    main()
