"""Regions of RPC products (issue 31): simulated without images (simulation.rpcregion: ZY-3-like
nadir products, 2.1 m, 51 km swath, 20 % side-lap, 15 % forward overlap, vendor biases of 5-20 m
and drifts of up to 2 m, 0.3 px noise, ~2,000 tie observations per product, no GCPs) at 100, 300 and
1,000 products (3,000 with --sizes), and adjusted by the use case behind pushbroom:bundleadjust with
SCENES (core.runs.bundleadjust.run: reading the products and the tie file, the block adjustment,
writing every output). Prints figures (no assertions).

Per size: the simulation's time and peak; the adjustment's wall and CPU time and peak resident
memory (tests/bench/peak.py; in a child process, so neither the simulation nor an earlier size
counts); accuracy against the truth at the check points: the misregistration of neighbouring
products (the same check point through two adjusted products: the difference of their image
errors, px RMS over every pair of products seeing a point) and the absolute error (m RMS: each
product's true image position of a check point through its adjusted model to the point's true
height, against the true ground), both also for the vendor RPCs; then the growth exponents of time
and memory between sizes (log ratio over log ratio of the products).

Tie points seen only by consecutive products of one strip (the forward overlaps) are left out
unless --forward-ties: those products see them along the same rays (one pass, one detector line),
so their heights are undetermined without a height reference, and today's intersection of the
tie points started them on the rays' meeting point, towards the Earth's centre (the run stopped at
100 products); they now start on their first ray at a height (core.adjust.ties.start_from_height) and
the DEM holds their heights: run --forward-ties --tie-height-sigma.

A size is run only when the peak memory extrapolated from the smaller sizes (at their growth
exponent) fits in the memory available now; otherwise the estimate is printed and the size left out
(--force runs it anyway).

Run:  PYTHONPATH=. PROJ_DATA=/usr/share/proj /usr/bin/python3 tests/bench/bench_region.py
      [--sizes 100,300,1000] [--ties 2000] [--correction shift] [--rpc-sigma 10] [--out out/bench_region]
      [--drift-m 2] [--forward-ties] [--force]
      [--tie-height-sigma M (the tie heights held to the region's DEM at M metres)]
The simulated regions are kept in --out and reused.
"""
from __future__ import annotations

import argparse
import json
import logging
import math
import os
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
from pushbroom_adjust.core.formats import load_scene  # noqa: E402
from pushbroom_adjust.core.formats.rpcfiles import read_rpc_text  # noqa: E402
from pushbroom_adjust.core.geodesy import geodetic_to_ecef  # noqa: E402
from pushbroom_adjust.core.runs import bundleadjust  # noqa: E402
from pushbroom_adjust.core.runs.adjustinputs import AdjustRequest, LayerFile  # noqa: E402
from pushbroom_adjust.simulation.memory import available_bytes  # noqa: E402
from pushbroom_adjust.simulation.region import RegionLayout  # noqa: E402
from pushbroom_adjust.simulation.rpcregion import RegionSettings, simulate_region  # noqa: E402
from tests.bench.bench_block import read_columns  # noqa: E402

# strips x products per strip of each size (wider than long: strips of 51 km, products 44 km apart)
LAYOUTS = {100: (10, 10), 300: (15, 20), 1000: (25, 40), 3000: (50, 60)}
SIDE_LAP, FORWARD = 0.2, 0.15
DRIFT_M = RegionSettings().drift_m   # m: the vendor drift's largest displacement of the last row, per axis
log = logging.getLogger("bench_region")


def layout_of(n: int) -> RegionLayout:
    strips, per = LAYOUTS.get(n, (max(2, round(math.sqrt(n))), math.ceil(n / max(2, round(math.sqrt(n))))))
    return RegionLayout(strips, per, side_lap=SIDE_LAP, forward_overlap=FORWARD, dates=3)


def settings_of(args) -> AdjustmentSettings:
    """The adjustment's settings: the RPC correction asked, the vendor accuracy as the prior, robust
    selection with variance components (the defaults), the DEM height reference with --tie-height-sigma."""
    return AdjustmentSettings(rpc_correction=args.correction, rpc_sigma=args.rpc_sigma,
                              **height_reference(args, region_folder(args, args.child)))


def height_reference(args, folder: Path) -> dict:
    """The fields of AdjustmentSettings that hold tie points' heights to the region's DEM (issue 31
    'A height reference': DEM + TIE_HEIGHT_SIGMA, core.adjust.tieheights), {} without
    --tie-height-sigma. The simulated DEM (EGM96 heights) is the truth the tie points lie on; its
    stated sigma is --tie-height-sigma."""
    if args.tie_height_sigma is None:
        return {}
    return {"dem": str(folder / "dem.tif"), "dem_datum": "geoid", "tie_height_sigma": args.tie_height_sigma}


def check_errors(scenes: dict, truth: dict, g: dict) -> tuple[float, float, int, int]:
    """(misregistration px RMS over pairs of products seeing a check point, absolute ground error m
    RMS over check observations, pairs, observations) of ``scenes`` {name: model} against ``truth``."""
    check = g["role"] == "check"
    ids = g["id"][check]
    lon, lat, h = (g[k][check].astype(float) for k in ("lon_true", "lat_true", "h_true"))
    col_t, row_t = (g[k][check].astype(float) for k in ("col_true", "row_true"))
    err = np.full((ids.size, 2), np.nan)
    ground = np.full(ids.size, np.nan)
    for name, scene in scenes.items():
        m = g["scene"][check] == name
        if not m.any():
            continue
        c, r = scene.ground_to_image_geodetic(lon[m], lat[m], h[m])
        tc, tr = truth[name].ground_to_image_geodetic(lon[m], lat[m], h[m])
        err[m] = np.stack([c - tc, r - tr], axis=1)
        got = scene.image_to_ground(col_t[m], row_t[m], h[m])
        ground[m] = np.linalg.norm(got - geodetic_to_ecef(lon[m], lat[m], h[m]), axis=1)
    order = np.argsort(ids, kind="stable")
    ids, err = ids[order], err[order]
    first = np.r_[True, ids[1:] != ids[:-1]]
    start = np.nonzero(first)[0]
    diffs = []
    for a, b in zip(start, np.r_[start[1:], ids.size]):  # a few observations per point: pairs within each
        e = err[a:b]
        i, j = np.triu_indices(b - a, 1)
        diffs.append(e[i] - e[j])
    d = np.concatenate(diffs) if diffs else np.zeros((0, 2))
    return (float(np.sqrt(np.mean(np.sum(d ** 2, axis=1)))), float(np.sqrt(np.mean(ground ** 2))), len(d),
            int(ground.size))


def run_child(args, n: int) -> None:
    """The child process: adjust the region of ``n`` products, print a JSON line of figures."""
    logging.getLogger().setLevel(logging.WARNING)
    folder = region_folder(args, n)
    manifest = json.loads((folder / "region.json").read_text())
    products = {p["name"]: str(folder / p["rpc"]) for p in manifest["products"]}
    out = folder / f"adjusted_{args.correction}"
    request = AdjustRequest(scenes=products, ties=LayerFile(str(folder / "tie_points.csv")),
                            settings=settings_of(args), folder=str(out))
    reset_peak()
    t0, c0 = time.perf_counter(), time.process_time()
    result = bundleadjust.run(request)
    wall, cpu, peak = time.perf_counter() - t0, time.process_time() - c0, peak_mb()
    block = result.figures["report"]["block"]
    truth = {name: load_scene(folder / p["true_scene"]) for name, p in zip(products, manifest["products"])}
    adjusted = {name: load_scene(out / f"{name}_adjusted.json") for name in products}
    vendor = {name: read_rpc_text(Path(path)) for name, path in products.items()}
    g = read_columns(folder / "gcps.csv")
    mis, absolute, pairs, obs = check_errors(adjusted, truth, g)
    mis0, absolute0, _, _ = check_errors(vendor, truth, g)
    print(json.dumps({"n": n, "wall_s": wall, "cpu_s": cpu, "peak_mb": peak, "sigma0": block["sigma0"],
                      "tie_rmse_before_px": block["tie_rmse_before_px"], "tie_rmse_px": block["tie_rmse_px"],
                      "misregistration_px": mis, "misregistration_vendor_px": mis0, "absolute_m": absolute,
                      "absolute_vendor_m": absolute0, "check_pairs": pairs, "check_observations": obs,
                      "tie_observations": manifest["points"]["tie_observations"]}))


def region_folder(args, n: int) -> Path:
    drift = "" if args.drift_m == DRIFT_M else f"_drift{args.drift_m:g}"
    return Path(args.out) / f"region_{n}_{args.ties}{'_forward' if args.forward_ties else ''}{drift}"


def simulate(args, n: int) -> Path:
    folder = region_folder(args, n)
    if not (folder / "region.json").exists():
        reset_peak()
        t0 = time.perf_counter()
        simulate_region(layout_of(n), folder, seed=31,
                        settings=RegionSettings(ties_per_product=args.ties, forward_ties=args.forward_ties,
                                                drift_m=args.drift_m))
        print(f"{n} products: simulated in {time.perf_counter() - t0:.1f} s, peak {peak_mb():.0f} MB "
              f"({layout_of(n).strips} strips x {layout_of(n).products_per_strip}; not timed below)", flush=True)
    return folder


def exponent(a: dict, b: dict, key: str) -> float:
    return math.log(b[key] / a[key]) / math.log(b["n"] / a["n"])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="100,300,1000")
    ap.add_argument("--ties", type=int, default=2000, help="tie observations per product")
    ap.add_argument("--correction", default="shift", help="RPC_CORRECTION: shift, drift or affine")
    ap.add_argument("--rpc-sigma", type=float, default=10.0, help="RPC_SIGMA (px): 20 m / 2.1 m")
    ap.add_argument("--tie-height-sigma", type=float, default=None, help="m: tie heights held to the DEM")
    ap.add_argument("--forward-ties", action="store_true",
                    help="also tie points seen only by consecutive products of one strip (parallel rays: their "
                         "heights need --tie-height-sigma)")
    ap.add_argument("--drift-m", type=float, default=DRIFT_M, help="the simulated vendor drift (m at the last row)")
    ap.add_argument("--out", default="out/bench_region")
    ap.add_argument("--force", action="store_true", help="run a size even when its memory estimate does not fit")
    ap.add_argument("--child", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args()
    logging.basicConfig(level=logging.WARNING, format="%(message)s")
    if args.child:
        run_child(args, args.child)
        return
    rows = []
    for n in (int(s) for s in args.sizes.split(",")):
        if len(rows) >= 2 and not args.force:
            k = exponent(rows[-2], rows[-1], "peak_mb")
            estimate = rows[-1]["peak_mb"] * (n / rows[-1]["n"]) ** k
            have = available_bytes() / 2 ** 20
            if estimate > 0.8 * have:
                print(f"{n} products: not run; the adjustment's peak extrapolated at n^{k:.2f} is about "
                      f"{estimate / 1024:.1f} GB, more than 80 % of the {have / 1024:.1f} GB available", flush=True)
                continue
        simulate(args, n)
        child = [sys.executable, __file__, "--child", str(n), "--ties", str(args.ties), "--out", args.out,
                 "--correction", args.correction, "--rpc-sigma", str(args.rpc_sigma)]
        child += (["--forward-ties"] if args.forward_ties else []) + ["--drift-m", str(args.drift_m)]
        if args.tie_height_sigma is not None:
            child += ["--tie-height-sigma", str(args.tie_height_sigma)]
        done = subprocess.run(child, capture_output=True, text=True)
        if done.returncode:
            print(f"{n} products: the adjustment failed (exit {done.returncode}):\n{done.stderr[-2000:]}", flush=True)
            break
        row = json.loads(done.stdout.strip().splitlines()[-1])
        rows.append(row)
        print(f"{n} products, {row['tie_observations']} tie observations: adjusted in {row['wall_s']:.1f} s wall "
              f"({row['cpu_s']:.1f} s CPU), peak {row['peak_mb']:.0f} MB; sigma0 {row['sigma0']:.3f}, tie RMS "
              f"{row['tie_rmse_before_px']:.2f} -> {row['tie_rmse_px']:.3f} px; neighbours' misregistration "
              f"{row['misregistration_px']:.3f} px RMS (vendor {row['misregistration_vendor_px']:.2f}; "
              f"{row['check_pairs']} pairs), absolute {row['absolute_m']:.2f} m RMS (vendor "
              f"{row['absolute_vendor_m']:.2f}; {row['check_observations']} check observations)", flush=True)
    for a, b in zip(rows, rows[1:]):
        print(f"growth {a['n']} -> {b['n']} products: time n^{exponent(a, b, 'wall_s'):.2f} wall, "
              f"n^{exponent(a, b, 'cpu_s'):.2f} CPU, memory n^{exponent(a, b, 'peak_mb'):.2f}")
    load = os.getloadavg()
    print(f"load average (1, 5, 15 min): {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} on {os.cpu_count()} cores")


if __name__ == "__main__":
    main()
