"""A rendered region (issue 31, "Done when" 5 and 7): 12 TH-1 nadir RPC products in 3 strips of 4
(cuts of 600 x 600 px of 5 m, 20 % side-lap, 15 % forward overlap), matched on its overlap graph by
the use case of pushbroom:matchtiepoints with SCENES (the region's folder) on this machine's threads
and on a local Dask cluster, then adjusted without GCPs by that of pushbroom:bundleadjust (the
region's DEM with TIE_HEIGHT_SIGMA, RPC_SIGMA 10 px) and orthorectified by that of
pushbroom:orthorectify with SCENES (the mosaic and its co-registration check) with the true, the
vendor and the adjusted models. Prints figures (no assertions).

Run:  PYTHONPATH=. PROJ_DATA=/usr/share/proj /usr/bin/python3 tests/bench/bench_region_render.py
      [--out DIR] [--spacing 15] [--dask-workers 2] [--no-mosaic] [--tie-height-sigma 1]
      [--correction drift]

Matching: every pair of the overlap graph (side-lap, forward overlap and the corners where four
products meet), its ties, the points by number of images, time, and whether the Dask run gave the
same ties to the bit. Mosaic: each overlapping pair's co-registration RMS (phase correlation on
windows of the overlap, core.measure.mosaiccheck), min, median and max over the pairs and the
RMS over every window of every pair. --out keeps the region and the runs (and reuses a region
already there). Times depend on what else the machine runs: quote the load average printed.
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from distributed import LocalCluster

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))
import tests.support.plugin_package  # noqa: E402,F401 (registers the package pushbroom_adjust)

from pushbroom_adjust.core.adjust.settings import AdjustmentSettings  # noqa: E402
from pushbroom_adjust.core.observations import tiepoints  # noqa: E402
from pushbroom_adjust.core.runs import bundleadjust, matchtiepoints, orthorectify  # noqa: E402
from pushbroom_adjust.core.runs.adjustinputs import AdjustRequest, LayerFile  # noqa: E402
from pushbroom_adjust.core.runs.base import Terrain  # noqa: E402
from pushbroom_adjust.simulation.block import BLOCK_MANIFEST, simulate_block  # noqa: E402
from pushbroom_adjust.simulation.presets import PRESETS, cut_preset  # noqa: E402
from pushbroom_adjust.simulation.region import RegionLayout, region_members  # noqa: E402

LAYOUT = RegionLayout(3, 4)
SEARCH_M = 400.0


def region(folder: Path) -> list[str]:
    """The region's product names, rendered into ``folder`` when not there."""
    if not (folder / BLOCK_MANIFEST).exists():
        t = time.perf_counter()
        simulate_block(region_members(LAYOUT, cut_preset(PRESETS["th1_tlc"], 600, 600)), folder, seed=3, n_gcps=10,
                       n_tie_points=50, render=True)
        print(f"rendered {LAYOUT.n_products} products in {time.perf_counter() - t:.1f} s", flush=True)
    return LAYOUT.names()


def match(folder: Path, output: Path, spacing: float, scheduler: str = ""):
    wall, cpu = time.perf_counter(), time.process_time()
    result = matchtiepoints.run(matchtiepoints.MatchTiesRequest(
        str(output), (), scenes=(str(folder),), terrain=Terrain(str(folder / "dem.tif"), "geoid"),
        matching={"spacing": spacing, "search": SEARCH_M}, scheduler=scheduler))
    print(f"matched {'on Dask' if scheduler else 'on threads'}: {time.perf_counter() - wall:.1f} s wall, "
          f"{time.process_time() - cpu:.1f} s CPU in this process (load average {os.getloadavg()[0]:.1f})", flush=True)
    return result


def print_pairs(figures: dict) -> None:
    pairs = figures["overlap_pairs"]
    print(f"{len(pairs)} overlapping pairs; failed: {[p['pair'] for p in pairs if p['failure']] or 'none'}; "
          f"fewer than {figures['min_pair_ties']} ties: {figures['weak_pairs'] or 'none'}")
    kinds = {"side-lap": [], "forward": [], "corner": []}
    for p in pairs:
        a, b = (n.split("/")[0] for n in p["pair"].split("-"))
        kind = "forward" if a[:2] == b[:2] else "side-lap" if a[2:] == b[2:] else "corner"
        kinds[kind].append(p["chained"])
    for kind, ties in kinds.items():
        print(f"  {kind}: {len(ties)} pairs, ties {min(ties)}-{max(ties)} (median {np.median(ties):.0f})")
    print(f"tie points by number of images: {figures['points_by_rays']}; chains refused: "
          f"{figures['inconsistent_chains']}")


def same_ties(a: Path, b: Path) -> bool:
    x, y = tiepoints.read_gpkg(str(a)), tiepoints.read_gpkg(str(b))
    return all(np.array_equal(getattr(x, k), getattr(y, k)) for k in x.ARRAYS)


def mosaic(folder: Path, names: list[str], label: str, scenes: list[str], out: Path) -> None:
    t = time.perf_counter()
    result = orthorectify.run(orthorectify.OrthoRequest(
        "", str(out / f"mosaic_{label}"), Terrain(str(folder / "dem.tif"), "geoid"), scenes=tuple(scenes),
        images=tuple(str(folder / n / f"{n}.tif") for n in names)))
    checks = result.figures["coregistration"]
    rms = np.array([c["rms_px"] for c in checks])
    used = np.array([c["used"] for c in checks])
    pooled = np.sqrt(np.nansum(rms ** 2 * used) / used.sum())
    print(f"{label}: {len(checks)} pairs, RMS per pair {np.nanmin(rms):.3f}-{np.nanmax(rms):.3f} px (median "
          f"{np.nanmedian(rms):.3f}), over every window {pooled:.3f} px; windows per pair {used.min()}-{used.max()} "
          f"of {sorted({c['window_px'] for c in checks})} px; no window: {int((used == 0).sum())}; "
          f"{time.perf_counter() - t:.1f} s wall", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--spacing", type=float, default=15.0, help="SPACING of the matching grid (px)")
    parser.add_argument("--dask-workers", type=int, default=2, help="Dask worker processes (0: no Dask run)")
    parser.add_argument("--no-mosaic", action="store_true", help="match only")
    parser.add_argument("--tie-height-sigma", type=float, default=1.0, help="TIE_HEIGHT_SIGMA (m; 0: no DEM)")
    parser.add_argument("--correction", default="drift", help="RPC_CORRECTION")
    args = parser.parse_args()
    out = args.out or Path(tempfile.mkdtemp(prefix="bench_region_render_"))
    folder = out / "region"
    names = region(folder)
    threads = match(folder, out / "ties.gpkg", args.spacing)
    print_pairs(threads.figures)
    if args.dask_workers:
        with LocalCluster(n_workers=args.dask_workers, processes=True, threads_per_worker=1, host="127.0.0.1",
                          dashboard_address=None) as cluster:
            match(folder, out / "ties_dask.gpkg", args.spacing, cluster.scheduler_address)
        print("Dask gave the same ties to the bit:", same_ties(out / "ties.gpkg", out / "ties_dask.gpkg"))
    if args.no_mosaic:
        return
    height = ({"dem": str(folder / "dem.tif"), "dem_datum": "geoid", "tie_height_sigma": args.tie_height_sigma}
              if args.tie_height_sigma > 0 else {})
    rpcs = {n: str(folder / n / f"{n}_RPC.TXT") for n in names}
    t = time.perf_counter()
    adjusted = bundleadjust.run(AdjustRequest(
        scenes=rpcs, ties=LayerFile(str(out / "ties.gpkg")), folder=str(out / "adjusted"),
        settings=AdjustmentSettings(rpc_correction=args.correction, rpc_sigma=10.0, **height)))
    block = adjusted.figures["report"]["block"]
    print(f"adjusted ({args.correction}, TIE_HEIGHT_SIGMA {args.tie_height_sigma:g} m): sigma0 {block['sigma0']:.3f}, "
          f"tie RMS {block['tie_rmse_px']:.3f} px, {time.perf_counter() - t:.1f} s wall", flush=True)
    mosaic(folder, names, "true", [str(folder / n / "true_scene.json") for n in names], out)
    mosaic(folder, names, "vendor", list(rpcs.values()), out)
    mosaic(folder, names, "adjusted", [str(out / "adjusted" / f"{n}_adjusted.json") for n in names], out)


if __name__ == "__main__":
    main()
