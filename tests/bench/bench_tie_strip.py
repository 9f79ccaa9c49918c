"""Speed of a tie-point block: a simulated ZY-3 three-line strip of 20 scenes with 20 000 tie
points and 100 GCPs, adjusted. Prints figures (no assertions).

Run:  PYTHONPATH=. PROJ_DATA=/usr/share/proj /usr/bin/python3 tests/bench/bench_tie_strip.py
      [--scenes 20] [--ties 20000] [--gcps 100] [--out DIR]

The strip (one scene model of --scenes x 24 576 rows; the preset's trajectory and installation
errors, no chip or lens errors; 0.5 px image and 0.5 m GCP ground noise) is simulated into DIR (kept, reused when
it is there: simulating is not what is timed). Then, in this process: reading the scene, GCPs
and tie points (the set-up), and the adjustment alone (forward intersection of the tie points'
onboard rays, observations, robust selection-weight passes with variance components). For
each: wall time (and CPU time of the adjustment, which other work on the machine changes
less), and peak resident memory (VmHWM, tests/bench/peak.py; the peak is reset between the two
through /proc/self/clear_refs, so the adjustment's figure is its own). The machine's load
average is printed with the figures: other work on the machine slows the wall times.

Settings: orientation images every 20 s (Lagrange) for position and attitude, onboard
positions (20 m) and attitude (1e-4 rad) as pseudo-observations, installation angles of the
forward and backward cameras free, selection weights.
"""
from __future__ import annotations

import argparse
import csv
import logging
import os
import sys
import time
from dataclasses import fields
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))
import tests.support.plugin_package  # noqa: E402,F401 (registers the package pushbroom_adjust)
from tests.bench.peak import peak_mb, reset_peak  # noqa: E402

from pushbroom_adjust.core.observations import gcps as G  # noqa: E402
from pushbroom_adjust.core.observations.tables import Heights  # noqa: E402
from pushbroom_adjust.core.adjust import AdjustmentSettings, adjust  # noqa: E402
from pushbroom_adjust.core.geodesy import geodetic_to_ecef  # noqa: E402
from pushbroom_adjust.core.formats import load_scene  # noqa: E402
from pushbroom_adjust.simulation.presets import ErrorSettings  # noqa: E402
from pushbroom_adjust.simulation.measurements import GcpSettings  # noqa: E402
from pushbroom_adjust.simulation.simulator import simulate  # noqa: E402
from pushbroom_adjust.core.observations.tiepoints import TieTable  # noqa: E402

NOISE = 0.5  # px
GROUND = 0.5  # m: GCP ground noise, east, north and up
# The preset's trajectory and installation errors, which the settings below model: a speed
# bench of a converging block (chip and lens errors left unmodelled would add robust passes).
NO_CHIP_ERRORS = {f.name: 0.0 for f in fields(ErrorSettings)
                  if not f.name.startswith(("position", "attitude", "installation"))}
log = logging.getLogger("bench_tie_strip")


def read_ties(path: Path) -> tuple[TieTable, np.ndarray]:
    with path.open() as f:
        rows = list(csv.DictReader(f))
    col = {k: np.array([r[k] for r in rows]) for k in rows[0]}
    truth = geodetic_to_ecef(*(col[k].astype(float) for k in ("lon_true", "lat_true", "h_true")))
    return TieTable(col["id"], col["camera"], col["col"].astype(float), col["row"].astype(float), NOISE, ""), truth


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", type=int, default=20)
    ap.add_argument("--ties", type=int, default=20000)
    ap.add_argument("--gcps", type=int, default=100)
    ap.add_argument("--out", default="out/bench_tie_strip")
    args = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    folder = Path(args.out) / f"zy3_{args.scenes}_{args.ties}_{args.gcps}_v2"
    if not (folder / "tie_points.csv").exists():
        t0 = time.perf_counter()
        simulate("zy3_tlc", folder, seed=2, n_scenes=args.scenes, errors=NO_CHIP_ERRORS,
                 gcp_settings=GcpSettings(n_gcps=args.gcps, image_noise=NOISE, ground_noise_xy=GROUND,
                                          ground_noise_z=GROUND, n_tie_points=args.ties))
        print(f"simulated the strip in {time.perf_counter() - t0:.1f} s (not timed below)")
    logging.getLogger().setLevel(logging.WARNING)
    reset_peak()
    t0 = time.perf_counter()
    scene = load_scene(folder / "onboard_scene.json")
    gcps = G.read_csv(folder / "gcps.csv", G.CsvMapping(z="h", role="role", camera="camera"), "EPSG:4326",
                      Heights("z", datum="ellipsoid"), sigma_px=NOISE, sigma_xy=GROUND, sigma_z=GROUND)
    ties, truth = read_ties(folder / "tie_points.csv")
    setup_time, setup_peak = time.perf_counter() - t0, peak_mb()
    settings = AdjustmentSettings(position_model="lagrange", position_interval=20.0, attitude_model="lagrange",
                                  attitude_interval=20.0, position_sigma=20.0, attitude_sigma=1e-4,
                                  interior="FWD.roll, FWD.pitch, FWD.yaw, BWD.roll, BWD.pitch, BWD.yaw")
    reset_ok = reset_peak()
    t0, c0 = time.perf_counter(), time.process_time()
    out = adjust(scene, gcps, settings, ties=ties)
    adjust_time, adjust_cpu, adjust_peak = time.perf_counter() - t0, time.process_time() - c0, peak_mb()
    rep = out.report
    t = out.tie_points
    error = np.linalg.norm(geodetic_to_ecef(t["lon"], t["lat"], t["h"]) - truth, axis=1)
    for p in rep["robust"]["passes"]:
        print(f"  pass {p['pass']}: sigma0 {p['sigma0']:.3f}, {p['down_weighted']} down-weighted, largest weight "
              f"change {p['largest_change']:.3g}, largest component change {100 * p['component_change']:.2f} %")
    for group, c in rep["variance_components"].items():
        print(f"  variance component {group}: sigma0 {c['sigma0']:.3f}, redundancy {c['redundancy']:.1f}"
              + ("" if c["estimated"] else " (not estimated)"))
    load = os.getloadavg()
    print(f"strip: {args.scenes} ZY-3 scenes ({scene.cameras[0].rows} rows), {rep['observations']['control_points']} "
          f"GCPs ({rep['observations']['image_observations']} image observations), "
          f"{rep['tie_points']['points']} tie points ({rep['tie_points']['observations']} observations), "
          f"{rep['observations']['unknowns']} parameters, {rep['observations']['ground_unknowns']} ground unknowns")
    print(f"set-up (reading scene, GCPs, tie points): {setup_time:.1f} s, peak {setup_peak:.0f} MB")
    print(f"adjustment: {adjust_time:.1f} s wall ({adjust_cpu:.1f} s CPU, all threads), peak {adjust_peak:.0f} MB"
          + ("" if reset_ok else " (peak not reset: includes the set-up)")
          + f"; {len(rep['robust']['passes'])} robust passes, {len(rep['iterations'])} iterations in the last")
    print(f"sigma0 {rep['sigma0']:.3f}; tie residual RMSE col {rep['tie_points']['residuals']['rmse_col']:.3f} px, "
          f"row {rep['tie_points']['residuals']['rmse_row']:.3f} px; tie ground error against the truth: "
          f"median {np.nanmedian(error):.2f} m, max {np.nanmax(error):.2f} m; flagged {rep['tie_points']['flagged']}")
    print(f"load average (1, 5, 15 min): {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} on {os.cpu_count()} cores")


if __name__ == "__main__":
    main()
