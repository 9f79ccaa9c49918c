"""A region of rigorous three-line scenes (issue 31, "Regional rigorous": 100 TH-1 or ZY-3 scenes with
piecewise trajectories adjusted in <= 5 min): simulated without images (simulation.region.region_members
with rpc=False and all_cameras=True, simulated by simulation.block.simulate_block: tie observations
computed, not matched), adjusted by the use case behind pushbroom:bundleadjust with SCENES
(core.runs.bundleadjust.run: reading the scenes and the tie file, the block adjustment, writing every
output). Prints figures (no assertions).

The region: --strips x --per-strip scenes of the full preset (th1_tlc: three cameras of 12,000 x
12,000 px, 5 m GSD, 60 km swath; zy3_tlc: nadir 2.1 m, forward and backward 3.5 m), 20 % side-lap,
15 % forward overlap, strips on 3 dates, each at nadir. Onboard errors per scene: the preset's
trajectory errors (position bias 10 m and drift 0.02 m/s, attitude bias 1e-4 rad, drift 5e-7 rad/s
and quadratic 1e-9 rad/s^2), no interior or installation errors (as tests/bench/bench_block.py: the
bench measures the block's trajectories, not self-calibration). 0.3 px image noise. No GCPs: ties
alone, the onboard sigmas hold the datum.

Settings: piecewise trajectories, position and attitude 'spline' (piecewise quadratics; a three-line
scene spans about 70 s, the fore and aft cameras seeing the scene's ground some 30 s before and after
the nadir one, so the default 20 s knot interval gives about 4 pieces), one trajectory per scene
shared by its cameras, the simulated biases as the onboard sigmas (10 m, 1e-4 rad), selection weights
with variance components (the defaults).

Timed in a child process (neither the simulation nor its memory counts): the use case's wall and CPU
time and peak resident memory (tests/bench/peak.py). Accuracy against the truth at the simulator's
ground points (gcps.csv; none is used by the adjustment): the misregistration of neighbouring scenes
(the same point through two adjusted scenes, nadir cameras: the difference of their image errors
against the true scene, px RMS over every pair of scenes seeing a point) and the absolute error (m
RMS: each observation's true image position through its adjusted scene and camera to the point's
true height, against the true ground), both also for the onboard scenes. --profile writes a cProfile
of the child to FILE and prints its 25 largest cumulative entries.

Run:  PYTHONPATH=. PROJ_DATA=/usr/share/proj /usr/bin/python3 tests/bench/bench_region_rigorous.py
      [--preset th1_tlc] [--strips 10] [--per-strip 10] [--ties 150] [--out out/bench_region_rigorous]
      [--profile FILE]
--ties: tie points (ground points seen by two scenes or more) per scene. The simulated regions are
kept in --out and reused.
"""
from __future__ import annotations

import argparse
import cProfile
import json
import logging
import os
import pstats
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
from pushbroom_adjust.core.geodesy import geodetic_to_ecef  # noqa: E402
from pushbroom_adjust.core.runs import bundleadjust  # noqa: E402
from pushbroom_adjust.core.runs.adjustinputs import AdjustRequest, LayerFile  # noqa: E402
from pushbroom_adjust.simulation.block import simulate_block  # noqa: E402
from pushbroom_adjust.simulation.measurements import GcpSettings  # noqa: E402
from pushbroom_adjust.simulation.presets import PRESETS  # noqa: E402
from pushbroom_adjust.simulation.region import RegionLayout, region_members  # noqa: E402
from tests.bench.bench_block import read_columns  # noqa: E402
from tests.bench.bench_region import misregistration  # noqa: E402

NOISE = 0.3  # px
SIDE_LAP, FORWARD, DATES = 0.2, 0.15, 3
NO_INTERIOR = {k: 0.0 for k in ("ccd_shift", "ccd_rotation", "installation", "principal_point_x", "principal_point_y",
                                "focal", "radial_k1", "radial_k2", "decentring_p1", "decentring_p2", "affinity_b1",
                                "affinity_b2", "affinity_b3")}
SETTINGS = AdjustmentSettings(position_model="spline", attitude_model="spline", position_sigma=10.0,
                              attitude_sigma=1e-4)
log = logging.getLogger("bench_region_rigorous")


def region_folder(args) -> Path:
    return Path(args.out) / f"{args.preset}_{args.strips}x{args.per_strip}_{args.ties}"


def simulate(args) -> Path:
    """The region's folder, simulated there unless it already is."""
    folder = region_folder(args)
    if (folder / "block.json").exists():
        return folder
    layout = RegionLayout(args.strips, args.per_strip, side_lap=SIDE_LAP, forward_overlap=FORWARD, dates=DATES)
    members = region_members(layout, PRESETS[args.preset], rpc=False, all_cameras=True)
    for m in members:
        m.errors = NO_INTERIOR
    n = len(members)
    reset_peak()
    t0 = time.perf_counter()
    simulate_block(members, folder, seed=31,
                   gcp_settings=GcpSettings(n_gcps=20 * n, check_fraction=1.0, image_noise=NOISE,
                                            n_tie_points=args.ties * n))
    print(f"{n} {args.preset} scenes simulated in {time.perf_counter() - t0:.1f} s, peak {peak_mb():.0f} MB "
          "(not timed below)", flush=True)
    return folder


def check_errors(scenes: dict, truth: dict, g: dict) -> tuple[float, float, int, int]:
    """(misregistration px RMS over pairs of scenes seeing a ground point in their nadir camera,
    absolute ground error m RMS over every observation, pairs, observations) of ``scenes`` {name:
    model} against ``truth``, at the ground points of the gcps.csv columns ``g``."""
    lon, lat, h = (g[k].astype(float) for k in ("lon_true", "lat_true", "h_true"))
    col_t, row_t = (g[k].astype(float) for k in ("col_true", "row_true"))
    err = np.full((lon.size, 2), np.nan)
    ground = np.full(lon.size, np.nan)
    for name, scene in scenes.items():
        for c, cam in enumerate(scene.cameras):
            m = (g["scene"] == name) & (g["camera"] == cam.name)
            if not m.any():
                continue
            got = scene.image_to_ground(col_t[m], row_t[m], h[m], c)
            ground[m] = np.linalg.norm(got - geodetic_to_ecef(lon[m], lat[m], h[m]), axis=1)
            if c == 0:
                col, row = scene.ground_to_image_geodetic(lon[m], lat[m], h[m], c)
                tc, tr = truth[name].ground_to_image_geodetic(lon[m], lat[m], h[m], c)
                err[m] = np.stack([col - tc, row - tr], axis=1)
    nadir = np.isfinite(err[:, 0])
    mis, pairs = misregistration({"id": g["id"][nadir], "image": err[nadir]})
    return mis, float(np.sqrt(np.nanmean(ground ** 2))), pairs, int(np.isfinite(ground).sum())


def run_child(args) -> None:
    """The child process: adjust the region, print a JSON line of figures."""
    logging.getLogger().setLevel(logging.WARNING)
    folder = region_folder(args)
    manifest = json.loads((folder / "block.json").read_text())
    names = [m["name"] for m in manifest["members"]]
    scenes = {n: str(folder / n / "onboard_scene.json") for n in names}
    out = folder / "adjusted"
    request = AdjustRequest(scenes=scenes, ties=LayerFile(str(folder / "tie_points.csv")), settings=SETTINGS,
                            folder=str(out))
    profile = cProfile.Profile() if args.profile else None
    reset_peak()
    t0, c0 = time.perf_counter(), time.process_time()
    if profile:
        profile.enable()
    result = bundleadjust.run(request)
    if profile:
        profile.disable()
    wall, cpu, peak = time.perf_counter() - t0, time.process_time() - c0, peak_mb()
    if profile:
        profile.dump_stats(args.profile)
        pstats.Stats(args.profile, stream=sys.stderr).sort_stats("cumulative").print_stats(25)
    report = result.figures["report"]
    block, eng = report["block"], report["adjustment"]
    truth = {n: load_scene(folder / n / "true_scene.json") for n in names}
    onboard = {n: load_scene(path) for n, path in scenes.items()}
    adjusted = {n: load_scene(out / f"{n}_adjusted.json") for n in names}
    g = read_columns(folder / "gcps.csv")
    mis, absolute, pairs, obs = check_errors(adjusted, truth, g)
    mis0, absolute0, _, _ = check_errors(onboard, truth, g)
    print(json.dumps({"scenes": len(names), "wall_s": wall, "cpu_s": cpu, "peak_mb": peak, "sigma0": block["sigma0"],
                      "tie_rmse_before_px": block["tie_rmse_before_px"], "tie_rmse_px": block["tie_rmse_px"],
                      "tie_points": block["tie_points"]["points"], "unknowns": eng["observations"]["unknowns"],
                      "observations": eng["observations"]["tie_observations"],
                      "passes": len(eng["robust"]["passes"]), "iterations": len(eng["iterations"]),
                      "misregistration_px": mis, "misregistration_onboard_px": mis0, "absolute_m": absolute,
                      "absolute_onboard_m": absolute0, "check_pairs": pairs, "check_observations": obs}))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--preset", default="th1_tlc", choices=("th1_tlc", "zy3_tlc"))
    ap.add_argument("--strips", type=int, default=10)
    ap.add_argument("--per-strip", type=int, default=10)
    ap.add_argument("--ties", type=int, default=150,
                    help="tie points per scene (at most about 160 at 100 scenes: the simulator draws 50,000 candidates)")
    ap.add_argument("--out", default="out/bench_region_rigorous")
    ap.add_argument("--profile", help="write a cProfile of the adjustment to this file")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    logging.basicConfig(level=logging.WARNING, format="%(message)s")
    if args.child:
        run_child(args)
        return
    simulate(args)
    child = [sys.executable, __file__, "--child", "--preset", args.preset, "--strips", str(args.strips),
             "--per-strip", str(args.per_strip), "--ties", str(args.ties), "--out", args.out]
    child += ["--profile", args.profile] if args.profile else []
    done = subprocess.run(child, capture_output=True, text=True)
    if args.profile:
        print(done.stderr[-12000:])
    if done.returncode:
        print(f"the adjustment failed (exit {done.returncode}):\n{done.stderr[-3000:]}", flush=True)
        return
    r = json.loads(done.stdout.strip().splitlines()[-1])
    print(f"{r['scenes']} {args.preset} scenes, {r['tie_points']} tie points ({r['observations']} image "
          f"observations), {r['unknowns']} unknowns: adjusted in {r['wall_s']:.1f} s wall ({r['cpu_s']:.1f} s CPU), "
          f"peak {r['peak_mb']:.0f} MB; {r['passes']} robust passes, {r['iterations']} iterations in the last")
    print(f"sigma0 {r['sigma0']:.3f}; tie RMS {r['tie_rmse_before_px']:.2f} -> {r['tie_rmse_px']:.3f} px; "
          f"neighbours' misregistration {r['misregistration_px']:.3f} px RMS (onboard "
          f"{r['misregistration_onboard_px']:.2f}; {r['check_pairs']} pairs), absolute {r['absolute_m']:.2f} m RMS "
          f"(onboard {r['absolute_onboard_m']:.2f}; {r['check_observations']} check observations)")
    load = os.getloadavg()
    print(f"load average (1, 5, 15 min): {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} on {os.cpu_count()} cores")


if __name__ == "__main__":
    main()
