"""Speed and memory of a block adjustment (issue 23: 20 scenes x 20 000 ties in <= 30 s and
<= 2 GB): a simulated block of independent TH-1 three-line scenes adjusted by
:func:`core.adjust.block.adjust_block`. Prints figures (no assertions).

Run:  PYTHONPATH=. PROJ_DATA=/usr/share/proj /usr/bin/python3 tests/bench/bench_block.py
      [--scenes 20] [--ties 20000] [--gcps 20] [--out DIR] [--save FILE.npz]

The block (:func:`simulation.block.simulate_block`, not rendered): ceil(scenes / 2) neighbouring
strips of the full TH-1 preset (three cameras of 12 000 x 12 000 px, 5 m GSD; 60 km swath, 50 %
side-lap), each imaged on two dates (nadir; then rolled 8 degrees, another date) until there are
--scenes members: every tie point is seen by two scenes or more (the two dates, and in the
side-laps the neighbour strip), in every camera of them. Onboard errors per scene: position bias
20 m and drift 0.02 m/s, attitude bias 4e-5 rad (20 m on the ground) and drift 1e-7 rad/s; no
interior errors. 0.3 px image noise, GCPs with 0.5 m ground noise, a quarter of them check points.
It is simulated into DIR (kept, reused when it is there: simulating is not what is timed).

Settings: position and attitude polynomials of order 1 per scene, the onboard sigmas as the
simulated errors (20 m, 4e-5 rad), selection weights with variance components.

Timed in a child process (so that neither the simulation nor its memory counts): reading the
scenes and tables (the set-up), then the adjustment alone, wall time (time.perf_counter) and CPU
time, peak resident memory (VmHWM, reset through /proc/self/clear_refs after the set-up, so it
is the adjustment's peak with the inputs loaded). Printed: tie RMS before (onboard scenes,
onboard intersection) and after, check-point RMSE (image px and the adjusted scenes' error on the
ground against the truth), robust passes and iterations. --save writes the adjusted figures
(per-observation residuals, tie ground, check ground through each adjusted scene, sigma0) to an
.npz, to compare two versions of the code.
"""
from __future__ import annotations

import argparse
import csv
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
from pushbroom_adjust.core.adjust.block import adjust_block  # noqa: E402
from pushbroom_adjust.core.formats import load_scene  # noqa: E402
from pushbroom_adjust.core.geodesy import geodetic_to_ecef  # noqa: E402
from pushbroom_adjust.core.observations.gcps import GcpTable  # noqa: E402
from pushbroom_adjust.core.observations.tiepoints import TieTable  # noqa: E402
from pushbroom_adjust.simulation.block import BlockMember, simulate_block  # noqa: E402
from pushbroom_adjust.simulation.layouts import OTHER_DATE_ROLL, SECOND_DATE, swath_km  # noqa: E402
from pushbroom_adjust.simulation.measurements import GcpSettings  # noqa: E402
from pushbroom_adjust.simulation.presets import PRESETS  # noqa: E402

NOISE = 0.3      # px
GROUND = 0.5     # m: GCP ground noise, east, north and up
POSITION = 20.0  # m
ATTITUDE = 4e-5  # rad
# share of the swath neighbouring strips have in common: the block's bounding box (where the
# simulator draws candidate points) then holds enough ground seen twice for 20 000 tie points
SIDE_LAP = 0.5
ERRORS = {"position_bias": POSITION, "position_drift": 0.02, "attitude_bias": ATTITUDE, "attitude_drift": 1e-7,
          **{k: 0.0 for k in ("attitude_quadratic", "position_quadratic", "ccd_shift", "ccd_rotation", "installation",
                              "principal_point_x", "principal_point_y", "focal", "radial_k1", "radial_k2",
                              "decentring_p1", "decentring_p2", "affinity_b1", "affinity_b2", "affinity_b3")}}
SETTINGS = AdjustmentSettings(position_order=1, attitude_order=1, position_sigma=POSITION, attitude_sigma=ATTITUDE)
log = logging.getLogger("bench_block")


def members(n: int) -> list[BlockMember]:
    """ceil(n / 2) neighbouring strips on a first date, then the same strips rolled on a second date."""
    spec = PRESETS["th1_tlc"]
    strips = math.ceil(n / 2)
    step = (1.0 - SIDE_LAP) * swath_km(spec)
    out = []
    for k in range(n):
        strip, date = k % strips, k // strips
        offset = (strip - (strips - 1) / 2.0) * step
        out.append(BlockMember(f"s{strip:02d}d{date + 1}", spec, orbit_offset_km=offset, errors=ERRORS,
                               view=(0.0, OTHER_DATE_ROLL * date), date=SECOND_DATE if date else None))
    return out


def read_columns(path: Path, names: tuple[str, ...] | None = None) -> dict:
    """Columns (all, or ``names``) of a CSV file as arrays of strings."""
    with path.open() as f:
        reader = csv.DictReader(f)
        names = names or tuple(reader.fieldnames)
        values = [[] for _ in names]
        for row in reader:
            for v, k in zip(values, names):
                v.append(row[k])
    return {k: np.array(v) for k, v in zip(names, values)}


def read_inputs(folder: Path) -> tuple[list[str], dict, GcpTable, TieTable, dict]:
    """(scene names, onboard scenes, GCP table, tie table, GCP columns) of a simulated block."""
    names = sorted(p.name for p in folder.iterdir() if (p / "onboard_scene.json").exists())
    names.sort(key=lambda n: (n[3:], n[:3]))  # the block's order: first date's strips, then the second's
    onboard = {n: load_scene(folder / n / "onboard_scene.json") for n in names}
    g = read_columns(folder / "gcps.csv")
    f = {k: g[k].astype(float) for k in ("col", "row", "lon", "lat", "h")}
    gcps = GcpTable(g["id"], g["role"], g["camera"], f["col"], f["row"], f["lon"], f["lat"], f["h"], NOISE, GROUND,
                    GROUND, scene=g["scene"])
    t = read_columns(folder / "tie_points.csv", ("id", "camera", "col", "row", "scene"))
    ties = TieTable(t["id"], t["camera"], t["col"].astype(float), t["row"].astype(float), NOISE, t["scene"])
    return names, onboard, gcps, ties, g


def check_ground_error(out, true: dict, g: dict) -> float:
    """RMS (m) over the check observations of the distance between the true ground of the check
    point and where the adjusted scene puts its true image position at the true height."""
    check = g["role"] == "check"
    errors = []
    for name, scene in out.scenes.items():
        for c, cam in enumerate(scene.cameras):
            m = check & (g["scene"] == name) & (g["camera"] == cam.name)
            if m.any():
                lon, lat, h = (g[k][m].astype(float) for k in ("lon_true", "lat_true", "h_true"))
                got = scene.image_to_ground(g["col_true"][m].astype(float), g["row_true"][m].astype(float), h, c)
                errors.append(np.linalg.norm(got - geodetic_to_ecef(lon, lat, h), axis=1))
    return float(np.sqrt(np.mean(np.concatenate(errors) ** 2))) if errors else float("nan")


def save_figures(path: Path, out, true: dict, g: dict) -> None:
    """The adjusted figures to compare two versions of the code (see the module docstring)."""
    adj = out.adjustment
    check = {}
    for name, scene in out.scenes.items():
        truth = true[name]
        lon, lat = np.meshgrid(np.linspace(0, 1, 5), np.linspace(0, 1, 5))
        for c, cam in enumerate(truth.cameras):
            col, row = (a.ravel() for a in np.meshgrid(np.linspace(0, cam.cols, 5), np.linspace(0, cam.rows, 5)))
            ground = truth.image_to_ground(col, row, np.full(col.size, 300.0), c)
            check[f"{name}/{cam.name}"] = np.stack(scene.ground_to_image(ground, c), axis=1)
    np.savez(path, sigma0=out.report["block"]["sigma0"], tie_res=np.stack([adj.tie_points["res_col"],
                                                                          adj.tie_points["res_row"]], axis=1),
             gcp_res=np.stack([adj.points["res_col"], adj.points["res_row"]], axis=1),
             tie_ground=np.stack([out.tie_points[k] for k in ("lon", "lat", "h")], axis=1),
             **{f"image:{k}": v for k, v in check.items()})


def run_adjustment(folder: Path, save: str | None) -> None:
    """The child process: read the block, adjust it, print the figures."""
    logging.getLogger().setLevel(logging.WARNING)
    reset_peak()
    t0 = time.perf_counter()
    names, onboard, gcps, ties, g = read_inputs(folder)
    setup_time, setup_peak = time.perf_counter() - t0, peak_mb()
    reset_ok = reset_peak()
    t0, c0 = time.perf_counter(), time.process_time()
    out = adjust_block(onboard, gcps, ties, SETTINGS)
    adjust_time, adjust_cpu, adjust_peak = time.perf_counter() - t0, time.process_time() - c0, peak_mb()
    rep, eng = out.report, out.report["adjustment"]
    true = {n: load_scene(folder / n / "true_scene.json") for n in names}  # the truth, after the timing
    for p in eng["robust"]["passes"]:
        print(f"  pass {p['pass']}: sigma0 {p['sigma0']:.3f}, {p['down_weighted']} down-weighted, largest weight "
              f"change {p['largest_change']:.3g}")
    blk = rep["block"]
    cams = sum(len(s.cameras) for s in onboard.values())
    print(f"block: {len(onboard)} TH-1 scenes ({cams} cameras), {eng['observations']['control_points']} GCPs "
          f"({eng['observations']['image_observations']} observations), {blk['tie_points']['points']} tie points ({len(ties)} observations), "
          f"{eng['observations']['unknowns']} parameters, {eng['observations']['ground_unknowns']} ground unknowns")
    print(f"set-up (reading scenes, GCPs, tie points): {setup_time:.1f} s, peak {setup_peak:.0f} MB")
    print(f"adjustment: {adjust_time:.1f} s wall ({adjust_cpu:.1f} s CPU, all threads), peak {adjust_peak:.0f} MB"
          + ("" if reset_ok else " (peak not reset: includes the set-up)")
          + f"; {len(eng['robust']['passes'])} robust passes, {len(eng['iterations'])} iterations in the last")
    print(f"sigma0 {blk['sigma0']:.3f}; tie RMS {blk['tie_rmse_before_px']:.2f} px before, {blk['tie_rmse_px']:.3f} px "
          f"after; check points {blk['check_rmse_px']:.3f} px, on the ground against the truth "
          f"{check_ground_error(out, true, g):.2f} m RMS")
    load = os.getloadavg()
    print(f"load average (1, 5, 15 min): {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} on {os.cpu_count()} cores")
    if save:
        save_figures(Path(save), out, true, g)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="out/bench_block", help="the simulated blocks' folder")
    ap.add_argument("--save", help="write the adjusted figures to this .npz")
    ap.add_argument("--scenes", type=int, default=20)
    ap.add_argument("--gcps", type=int, default=20, help="ground points, a quarter of them check points")
    ap.add_argument("--ties", type=int, default=20000)
    ap.add_argument("--adjust-only", action="store_true", help=argparse.SUPPRESS)  # the child process
    args = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    folder = Path(args.out) / f"th1_{args.scenes}_{args.ties}_{args.gcps}"
    if args.adjust_only:
        run_adjustment(folder, args.save)
        return
    if not (folder / "block.json").exists():
        t0 = time.perf_counter()
        simulate_block(members(args.scenes), folder, seed=7,
                       gcp_settings=GcpSettings(n_gcps=args.gcps, check_fraction=0.25, image_noise=NOISE,
                                                ground_noise_xy=GROUND, ground_noise_z=GROUND,
                                                n_tie_points=args.ties))
        log.info("simulated the block in %.1f s (not timed below)", time.perf_counter() - t0)
    child = [sys.executable, __file__, "--adjust-only", "--scenes", str(args.scenes), "--ties", str(args.ties),
             "--gcps", str(args.gcps), "--out", args.out] + (["--save", args.save] if args.save else [])
    subprocess.run(child, check=True)


if __name__ == "__main__":
    main()
