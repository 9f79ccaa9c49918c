"""Automatic GCPs by matching (pushbroom:matchgcps's core) on a rendered CBERS-02B HRC scene
with known truth, then the self-calibrating adjustment on them. Prints figures (no assertions).

Run:  PYTHONPATH=. PROJ_DATA=/usr/share/proj /usr/bin/python3 tests/bench/bench_matchgcps.py
      [--out DIR] [--seed 1] [--spacing 200] [--workers 2]

The scene: one CBERS-02B HRC scene (12246 x 12246 px, 2.36 m, three staggered CCDs) with the
preset's onboard errors (about 400 m on the ground) and CCD shifts of 1-3 px, rendered, with the
simulator's reference orthoimage (UTM, 5 m, blur, gain/offset/gamma, noise, changed land cover and
cloud patches). --out keeps the simulation (and reuses one already there).

Figures: matched points and rejections by reason; match error against the truth (the true
scene's projection of each GCP's ground point) of the points that pass: median, share > 1 px,
RMSE of the rest, how many lie within 2 of their own sigma; wall time of the matching (coarse
and fine passes; the images' decoding and the footprint check are reported apart) and points/s
with the load average of the machine, and the CPU time of the whole call (points per CPU-second:
what free cores give, whatever the load); then the adjustment with the matched GCPs (CCDs HRC-1 and
HRC-3 self-calibrated, robust selection) and the adjusted model's error at a 25 x 25 grid of true
image points (their true ground on the DEM projected through the adjusted model).
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))
import tests.support.plugin_package  # noqa: E402,F401 (registers the package pushbroom_adjust)

from pushbroom_adjust.core.adjust import AdjustmentSettings, adjust  # noqa: E402
from pushbroom_adjust.core.dem import Dem  # noqa: E402
from pushbroom_adjust.core.geodesy import geodetic_to_ecef  # noqa: E402
from pushbroom_adjust.core.measure.matching import MatchSettings, match_gcps  # noqa: E402
from pushbroom_adjust.core.formats import load_scene  # noqa: E402
from pushbroom_adjust.simulation.simulator import simulate  # noqa: E402


def scene_folder(out: Path | None, seed: int) -> Path:
    """A rendered CBERS-02B simulation (with reference.tif): reused from ``out`` when present."""
    folder = out or Path(tempfile.mkdtemp(prefix="bench_match_"))
    if not (folder / "reference.tif").exists():
        t = time.perf_counter()
        simulate("cbers02b_hrc", folder, seed=seed, n_gcps=200, render=True)
        print(f"simulated and rendered into {folder} in {time.perf_counter() - t:.0f} s")
    return folder


def grid_errors(true, adjusted, dem, n: int = 25) -> np.ndarray:
    """Distances (px) between true image points of an n x n grid and the adjusted model's
    projection of their true ground (on the DEM)."""
    cam = true.cameras[0]
    cc, rr = np.meshgrid(np.linspace(50, cam.cols - 50, n), np.linspace(50, cam.rows - 50, n))
    ground = true.image_to_ground_dem(cc.ravel(), rr.ravel(), dem, 0)
    col, row = adjusted.ground_to_image(ground, 0)
    return np.hypot(col - cc.ravel(), row - rr.ravel())


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", type=Path)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--spacing", type=float, default=200.0)
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args()
    folder = scene_folder(a.out, a.seed)
    onboard, true = load_scene(folder / "onboard_scene.json"), load_scene(folder / "true_scene.json")
    dem = Dem(folder / "dem.tif", "geoid")
    onboard_error = grid_errors(true, onboard, dem, 5)
    print(f"onboard model: error {np.mean(onboard_error):.1f} px = {np.mean(onboard_error) * 2.36:.0f} m "
          f"(mean over a 5 x 5 grid)")

    load_before = os.getloadavg()
    t, cpu = time.perf_counter(), time.process_time()
    result = match_gcps(onboard, 0, folder / "image_HRC.tif", folder / "reference.tif", dem,
                        MatchSettings(spacing=a.spacing, workers=a.workers))
    total, cpu = time.perf_counter() - t, time.process_time() - cpu
    load_after = os.getloadavg()
    table = result.table
    n = len(table)
    print(f"\nmatched {n} of {result.grid_points} grid points (spacing {a.spacing:g} px, window 31 px)")
    print("rejected: " + ", ".join(f"{k} {v}" for k, v in result.rejected.items()))
    c = result.coarse
    print(f"coarse to fine: the whole image at 1:{c['factor']} offset by ({c['offset_px'][0]:.1f}, "
          f"{c['offset_px'][1]:.1f}) px (correlation {c['peak']:.2f}, search +-{c['search_m']:.0f} m); local chips kept "
          + ", ".join(f"{v['kept']} of {v['chips']} at 1:{v['factor']}" for v in c["levels"]))

    col, row = true.ground_to_image(geodetic_to_ecef(table.lon, table.lat, table.h), 0)
    dc, dr = col - table.col, row - table.row
    e = np.hypot(dc, dr)
    gross = e > 1.0
    within = np.mean(np.maximum(np.abs(dc), np.abs(dr))[~gross] <= 2 * table.sigma_px[~gross])
    print(f"error vs truth: median {np.median(e):.3f} px, > 1 px {100 * gross.mean():.2f} % ({gross.sum()}), "
          f"RMSE of the rest {np.sqrt(np.mean(e[~gross] ** 2)):.3f} px, 90th percentile {np.percentile(e, 90):.3f} px")
    print(f"sigma_px median {np.median(table.sigma_px):.3f} px; {100 * within:.0f} % of the non-gross points "
          f"within 2 sigma per axis")
    print(f"speed: matching {result.seconds:.2f} s = {n / result.seconds:.0f} matched points/s "
          f"({result.grid_points / result.seconds:.0f} grid points/s) on {a.workers} threads; whole call "
          f"{total:.2f} s (with decoding the image and reference and the footprint check); load average "
          f"{load_before[0]:.1f} before, {load_after[0]:.1f} after, {os.cpu_count()} cores")
    print(f"CPU time of the whole call {cpu:.2f} s: {n / cpu:.0f} matched points per CPU-second, so "
          f"{a.workers * n / cpu:.0f} points/s on {a.workers} free cores (the whole call, decoding included)")

    t = time.perf_counter()
    out = adjust(onboard, table, AdjustmentSettings(interior="HRC-1.*, HRC-3.*", robust="selection"))
    rep = out.report
    flagged = np.asarray(out.points["flagged"], bool)
    ids = np.asarray(out.points["id"])
    truly_gross = set(table.id[gross])
    hits = sum(i in truly_gross for i in ids[flagged])
    errors = grid_errors(true, out.scene, dem)
    print(f"\nadjustment (CCDs HRC-1, HRC-3 self-calibrated, robust selection) in {time.perf_counter() - t:.1f} s: "
          f"sigma0 {rep['sigma0']:.3f}, {flagged.sum()} observations flagged, {hits} of them among the "
          f"{gross.sum()} matches > 1 px off")
    print(f"adjusted model at a 25 x 25 grid of true points: RMSE {np.sqrt(np.mean(errors ** 2)):.3f} px, "
          f"median {np.median(errors):.3f} px, max {np.max(errors):.3f} px")


if __name__ == "__main__":
    main()
