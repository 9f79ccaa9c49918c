"""Speed and memory of a whole adjustment of a region of RPC products, ties only (issue 31, "a
solver that scales"): :func:`core.adjust.block.adjust_block` end to end (set-up, determinability,
robust passes with variance components, statistics, report) on the sparse path. Prints figures
(no assertions).

Run:  PYTHONPATH=. PROJ_DATA=/usr/share/proj /usr/bin/python3 tests/bench/bench_rpc_region.py
      [--products 100 300 1000] [--ties 1000]

The region is synthetic, not :mod:`simulation.block` (no images, no orbit; the simulation of a
region is another part of issue 31): a square grid of products of 10 000 x 10 000 px over 0.1 x 0.1
degrees each (about 1.1 m pixels), 20 % overlap with each neighbour, an RPC00B model of first order
in longitude, latitude and height (neighbours see a height difference of 500 m as 120 px of
parallax in opposite directions, across and along: rolled and pitched about 13 degrees). The
vendor RPC is the true one; each product's observations carry a bias of its own (uniform 3-15 px
on each axis, the 5-20 m of vendor RPCs) plus 0.3 px noise. --ties tie points per product, each in
the overlap of a product and its right or lower neighbour, heights 0-500 m. RPC_CORRECTION affine,
RPC_SIGMA 20 px, no GCPs (the priors hold the datum). Each size runs in a child process: its wall
and CPU time, peak resident memory (VmHWM) of the adjustment alone, the tie RMS before and after,
and the RMS of each product's shift left after the adjustment less a plane over the grid (the
block's common shift and tilt of shifts are the priors', not the ties'). Then the growth exponents of time and memory.
"""
from __future__ import annotations

import argparse
import logging
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

from pushbroom_adjust.core.adjust import AdjustmentSettings  # noqa: E402
from pushbroom_adjust.core.adjust.block import adjust_block  # noqa: E402
from pushbroom_adjust.core.model.rpc import RpcModel  # noqa: E402
from pushbroom_adjust.core.model.rpcscene import RpcCamera, RpcScene  # noqa: E402
from pushbroom_adjust.core.observations.tiepoints import TieTable  # noqa: E402

SIZE_PX = 10_000
SPAN_DEG = 0.1
OVERLAP = 0.2
NOISE = 0.3
PARALLAX = 0.024  # of the half image per unit of normalised height (250 m): 120 px over the 500 m
SETTINGS = AdjustmentSettings(rpc_correction="affine", rpc_sigma=20.0)


def product(k: int, lon: float, lat: float, look: tuple[float, float]) -> RpcScene:
    """Product ``k``'s RPC scene centred at lon, lat (degrees), its height parallax ``look``
    (samples, lines per unit of normalised height)."""
    line_num, samp_num, den = np.zeros(20), np.zeros(20), np.zeros(20)
    den[0] = 1.0
    samp_num[1], samp_num[3] = 1.0, look[0]    # longitude, height (parallax across)
    line_num[2], line_num[3] = -1.0, look[1]   # latitude (rows grow southwards), height (along)
    half = SPAN_DEG / 2.0
    rpc = RpcModel(line_num, den.copy(), samp_num, den.copy(), lon, half, lat, half, 250.0, 500.0,
                   SIZE_PX / 2.0, SIZE_PX / 2.0, SIZE_PX / 2.0, SIZE_PX / 2.0)
    name = f"p{k:05d}"
    return RpcScene(rpc, RpcCamera(name, SIZE_PX, SIZE_PX))


def region(n: int, ties: int, seed: int = 11) -> tuple[dict, TieTable, np.ndarray]:
    """(scenes by name, the tie table, each product's bias (n, 2) px)."""
    rng = np.random.default_rng(seed)
    side = math.ceil(math.sqrt(n))
    step = SPAN_DEG * (1.0 - OVERLAP)
    scenes = {}
    for k in range(n):
        r, c = divmod(k, side)
        # neighbours look from opposite sides (rolled and pitched +-13 degrees: 120 px per 500 m)
        look = (PARALLAX * (1 if c % 2 else -1), PARALLAX * (1 if r % 2 else -1))
        scenes[f"p{k:05d}"] = product(k, 100.0 + c * step, 30.0 - r * step, look)
    names = list(scenes)
    bias = rng.uniform(3.0, 15.0, (n, 2)) * rng.choice([-1.0, 1.0], (n, 2))
    first = np.repeat(np.arange(n), ties)
    r, c = divmod(first, side)
    right = rng.random(first.size) < 0.5
    second = np.where(right, first + 1, first + side)
    ok = np.where(right, c + 1 < side, r + 1 < side) & (second < n)
    second = np.where(ok, second, np.where(c > 0, first - 1, first - side))
    lon0 = 100.0 + (first % side) * step
    lat0 = 30.0 - (first // side) * step
    dlon = (second % side - first % side) * step
    dlat = -(second // side - first // side) * step
    half = SPAN_DEG / 2.0
    # a point in the two products' overlap: the strip of width OVERLAP * SPAN_DEG between them
    u, v = rng.uniform(-half, half, first.size), rng.uniform(-half, half, first.size)
    edge = (half - OVERLAP * SPAN_DEG / 2.0)
    lon = lon0 + np.where(dlon != 0, np.sign(dlon) * edge + u * OVERLAP * 0.8, u * 0.8)
    lat = lat0 + np.where(dlat != 0, np.sign(dlat) * edge + v * OVERLAP * 0.8, v * 0.8)
    h = rng.uniform(0.0, 500.0, first.size)
    ids, cams, cols, rows = [], [], [], []
    for who in (first, second):
        for k in np.unique(who):
            m = who == k
            col, row = scenes[names[k]].rpc.ground_to_image(lon[m], lat[m], h[m])
            cols.append(col + bias[k, 0] + rng.normal(0.0, NOISE, col.size))
            rows.append(row + bias[k, 1] + rng.normal(0.0, NOISE, row.size))
            ids.append(np.char.add("t", np.nonzero(m)[0].astype(str)))
            cams.append(np.full(col.size, names[k]))
    cam = np.concatenate(cams)
    table = TieTable(np.concatenate(ids), cam, np.concatenate(cols), np.concatenate(rows), NOISE, cam)
    return scenes, table, bias


def run(n: int, ties: int) -> None:
    """The child process: one size."""
    logging.getLogger().setLevel(logging.WARNING)
    t0 = time.perf_counter()
    scenes, table, _ = region(n, ties)
    built = time.perf_counter() - t0
    reset_peak()
    t0, c0 = time.perf_counter(), time.process_time()
    out = adjust_block(scenes, None, table, SETTINGS)
    wall, cpu, peak = time.perf_counter() - t0, time.process_time() - c0, peak_mb()
    rep = out.report
    eng = out.adjustment.report
    print(f"{n:5d} products, {len(table)} tie observations, {eng['observations']['unknowns']} parameters: "
          f"adjustment {wall:.1f} s wall ({cpu:.1f} s CPU), peak {peak:.0f} MB; "
          f"{len(eng['robust']['passes'])} robust passes; tie RMS {rep['block']['tie_rmse_before_px']:.2f} px before, "
          f"{rep['block']['tie_rmse_px']:.3f} px after (building the region {built:.1f} s, not timed)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--products", type=int, nargs="+", default=[100, 300, 1000])
    ap.add_argument("--ties", type=int, default=1000, help="tie points per product")
    ap.add_argument("--child", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        run(args.child, args.ties)
        return
    figures = {}
    for n in args.products:
        out = subprocess.run([sys.executable, __file__, "--child", str(n), "--ties", str(args.ties)], check=True,
                             capture_output=True, text=True).stdout.strip()
        print(out, flush=True)
        figures[n] = (float(out.split("adjustment ")[1].split(" s wall")[0]), float(out.split("peak ")[1].split(" MB")[0]))
    for a, b in zip(args.products[:-1], args.products[1:]):
        (ta, ma), (tb, mb) = figures[a], figures[b]
        print(f"{a} -> {b} products: time exponent {math.log(tb / ta) / math.log(b / a):.2f}, memory exponent "
              f"{math.log(mb / ma) / math.log(b / a):.2f}")


if __name__ == "__main__":
    main()
