"""The harness of the orthorectification benchmarks against gdalwarp (tests/bench/bench_ortho_vs_gdalwarp.py,
bench_ortho_rpc_vs_gdalwarp.py): both tools on the same image, DEM and output grid (bilinear,
nodata 0, the same output options), each run in its own process, alternating, timed by wall clock
with its peak resident memory; then the geometry against GDAL's RPC transformer and the shift
between the two orthoimages. Also the CBERS-02B scene of bench_ortho_vs_gdalwarp.py, which
tests/bench/bench_sensorcorrect.py uses too."""
from __future__ import annotations

import argparse
import json
import logging
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from osgeo import gdal
from pyproj import CRS

from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.formats.rpcfiles import sidecar_path, write_rpc
from pushbroom_adjust.core.products.mapping import OrthoGrid
from pushbroom_adjust.core.products.ortho import default_grid, orthorectify
from pushbroom_adjust.core.products.resampling import overview_levels
from pushbroom_adjust.core.products.rpcfit import dem_height_range, fit_rpc
from pushbroom_adjust.simulation.render import render_image
from pushbroom_adjust.simulation.simulator import simulate
from pushbroom_adjust.simulation.texture import texture_frame
from tests.support.ortho_compare import gdal_rpc_against_rigorous, image_difference
from tests.support.paths import REPO

gdal.UseExceptions()
log = logging.getLogger("bench_ortho")
OUTPUT_OPTIONS = ["TILED=YES", "BLOCKXSIZE=512", "BLOCKYSIZE=512", "COMPRESS=DEFLATE", "PREDICTOR=2",
                  "BIGTIFF=IF_SAFER", "NUM_THREADS=ALL_CPUS"]
# Runs a command and prints its peak resident memory (kB) last: each tool measured on its own.
MEASURE = ("import resource, subprocess, sys\n"
           "rc = subprocess.run(sys.argv[1:]).returncode\n"
           "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)\n"
           "sys.exit(rc)\n")


def prepare_cbers(work: Path) -> dict:
    """The scene of tests/bench/bench_ortho_vs_gdalwarp.py in ``work``: simulate the CBERS-02B HRC
    scene (seed 0), render its raw image, write the ellipsoidal DEM and the RPC; the common grid."""
    t0 = time.perf_counter()
    result = simulate("cbers02b_hrc", work / "sim", seed=0, n_gcps=5)
    true_scene, onboard = load_scene(result.true_scene), load_scene(result.onboard_scene)
    dem_path = Dem(result.dem, datum="geoid").write_ellipsoidal(work / "dem_ellipsoid.tif")
    dem = Dem(dem_path, datum="ellipsoid")
    raw = work / "raw.tif"
    render_image(true_scene, 0, dem, raw, texture_frame(true_scene, dem, 0))
    log.info("simulated and rendered %s in %.0f s", raw, time.perf_counter() - t0)
    rpc, report = fit_rpc(onboard, 0, dem_height_range(onboard, dem))
    write_rpc(rpc, sidecar_path(raw), report)
    grid = default_grid(onboard, 0, dem)
    return {"scene": str(result.onboard_scene), "raw": str(raw), "dem": str(dem_path), "rpc_check": report["check"],
            "grid": {"crs": grid.crs.to_wkt(), "x0": grid.x0, "y0": grid.y0, "resolution": grid.resolution,
                     "cols": grid.cols, "rows": grid.rows}}


def common_grid(setup: dict) -> OrthoGrid:
    """The output grid both tools write (``setup["grid"]``)."""
    g = setup["grid"]
    return OrthoGrid(CRS.from_wkt(g["crs"]), g["x0"], g["y0"], g["resolution"], g["cols"], g["rows"])


def run_ours(setup: dict, output: str) -> None:
    """Child process: our orthorectification onto the common grid (the timed work)."""
    figures = orthorectify(load_scene(setup["scene"]), setup["raw"], Dem(setup["dem"], datum="ellipsoid"), output,
                           grid=common_grid(setup), resampling="bilinear", nodata=0)
    print(json.dumps({k: v for k, v in figures.items() if k != "crs"}))


def gdalwarp_command(setup: dict, output: str) -> list[str]:
    """The gdalwarp command onto the common grid, with the image's RPC over the setup's DEM."""
    g = setup["grid"]
    crs = CRS.from_wkt(g["crs"]).to_string()
    xmax, ymin = g["x0"] + g["cols"] * g["resolution"], g["y0"] - g["rows"] * g["resolution"]
    cmd = ["gdalwarp", "-q", "-rpc", "-to", f"RPC_DEM={setup['dem']}", "-r", "bilinear", "-multi",
           "-wo", "NUM_THREADS=ALL_CPUS", "-t_srs", crs, "-te", *map(repr, (g["x0"], ymin, xmax, g["y0"])),
           "-ts", str(g["cols"]), str(g["rows"]), "-dstnodata", "0", "-overwrite"]
    for option in OUTPUT_OPTIONS:
        cmd += ["-co", option]
    return cmd + [setup["raw"], output]


def measured(cmd: list[str]) -> tuple[float, float, str]:
    """(wall s, peak resident GB, stdout) of a command run in its own process."""
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", MEASURE, *cmd], capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": str(REPO)})
    wall = time.perf_counter() - t0
    if proc.returncode:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{proc.stderr}")
    lines = proc.stdout.strip().splitlines()
    return wall, int(lines[-1]) / 1024 ** 2, "\n".join(lines[:-1])


def run_benchmark(prepare_setup, description: str, script: str) -> None:
    """The benchmark (command line: --repeats, --out, --keep) on the setup ``prepare_setup(work
    folder)`` makes; ``description`` is its --help text, and ``script`` (the benchmark's file) is
    re-run with --ours as the child that times our orthorectification."""
    parser = argparse.ArgumentParser(description=description, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=2, help="runs of each tool, alternating (default 2)")
    parser.add_argument("--out", type=Path, help="work folder (default: a temporary one, removed)")
    parser.add_argument("--keep", action="store_true", help="keep the work folder")
    parser.add_argument("--ours", help=argparse.SUPPRESS)  # child mode: SETUP_JSON:OUTPUT
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    if args.ours:
        setup_json, output = args.ours.split(":", 1)
        run_ours(json.loads(Path(setup_json).read_text()), output)
        return
    work = args.out or Path(tempfile.mkdtemp(prefix="bench_ortho_"))
    work.mkdir(parents=True, exist_ok=True)
    try:
        setup = prepare_setup(work)
        (work / "setup.json").write_text(json.dumps(setup))
        g = setup["grid"]
        print(f"grid {g['cols']} x {g['rows']} px at {g['resolution']:.3f} m; " + (
              f"RPC vs rigorous (onboard model): {setup['rpc_check']['rms_px']:.3f} px RMS, "
              f"{setup['rpc_check']['max_px']:.3f} px max" if "rpc_check" in setup else "the same RPC for both"))
        ours_out, gdal_out = str(work / "ours.tif"), str(work / "gdalwarp.tif")
        ours_cmd = [sys.executable, script, "--ours", f"{work / 'setup.json'}:{ours_out}"]
        levels = overview_levels(g["cols"], g["rows"])
        times = {"ours": [], "gdalwarp": [], "gdaladdo": []}
        for k in range(args.repeats):
            wall, peak, out = measured(ours_cmd)
            times["ours"].append((wall, peak))
            print(f"run {k + 1}: ours     {wall:6.1f} s wall, {peak:.2f} GB peak (incl. overviews; "
                  f"densification <= {json.loads(out)['densification_error_px']:.1e} px)")
            wall, peak, _ = measured(gdalwarp_command(setup, gdal_out))
            times["gdalwarp"].append((wall, peak))
            wall_ovr, peak_ovr, _ = measured(["gdaladdo", "-q", "-r", "average", "--config", "COMPRESS_OVERVIEW",
                                              "DEFLATE", "--config", "GDAL_NUM_THREADS", "ALL_CPUS", gdal_out,
                                              *map(str, levels)])
            times["gdaladdo"].append((wall_ovr, peak_ovr))
            print(f"run {k + 1}: gdalwarp {times['gdalwarp'][-1][0]:6.1f} s wall, {times['gdalwarp'][-1][1]:.2f} "
                  f"GB peak; + gdaladdo {wall_ovr:.1f} s")
        best = {k: min(v)[0] for k, v in times.items()}
        print(f"best of {args.repeats}: ours {best['ours']:.1f} s, gdalwarp {best['gdalwarp']:.1f} s "
              f"(+ overviews {best['gdalwarp'] + best['gdaladdo']:.1f} s): ratio {best['ours'] / best['gdalwarp']:.2f} "
              f"against gdalwarp alone, {best['ours'] / (best['gdalwarp'] + best['gdaladdo']):.2f} against the same "
              f"product; peak ours {max(p for _, p in times['ours']):.2f} GB, "
              f"gdalwarp {max(p for _, p in times['gdalwarp']):.2f} GB")
        err = gdal_rpc_against_rigorous(load_scene(setup["scene"]), setup["dem"], setup["raw"], common_grid(setup))
        print(f"geometry, ours vs GDAL's RPC transformer with the same DEM, {err.size} output pixels: "
              f"RMS {np.sqrt(np.mean(err ** 2)):.4f} px, max {err.max():.4f} px")
        diff = image_difference(ours_out, gdal_out)
        print(f"images: shift {np.hypot(*diff['shift_px']):.4f} px overall {diff['shift_px']}, worst of 8x8 blocks "
              f"{diff['worst_block_shift_px']:.4f} px, mean |difference| {diff['mean_abs_difference_dn']:.2f} DN; "
              f"pixels only ours {diff['coverage_only_ours']}, only gdalwarp {diff['coverage_only_gdal']}")
    finally:
        if not (args.keep or args.out):
            shutil.rmtree(work, ignore_errors=True)
