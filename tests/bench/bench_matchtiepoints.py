"""Tie points matched between the three cameras of a rendered TH-1 scene (pushbroom:matchtiepoints's
core) against the truth, and the self-calibrating adjustment with them against the same
adjustment with exact tie points (issue 12, criterion 3). Prints figures (no assertions).

Run:  PYTHONPATH=. PROJ_DATA=/usr/share/proj /usr/bin/python3 tests/bench/bench_matchtiepoints.py
      [--cols 6000] [--rows 6000] [--spacing 100] [--control 9] [--seed 3] [--out DIR]

The scene: the TH-1 preset (forward, nadir and backward lines at +-25 deg, 5 m GSD; its
trajectory, installation and interior errors) cut to --cols detectors and --rows lines per
camera (tests/matchscene.th1_cut: the interior errors scaled so the distortion bends a window
as in the full 12000 px camera), rendered, with 60 ground points (half of them check points,
0.3 px image noise). --out keeps the simulation (and reuses one already there).

Figures: tie points per camera pair; rejections by camera and reason; each FWD/BWD observation's
error against the truth (the true scene's projection of the true ground its NAD grid point sees):
median, 90th percentile, largest, share > 1 px; the matching's wall time. Then the same
adjustment (INTERIOR=default: self-calibration of every camera with the automatic removal, which
keeps the same 15 terms with matched and with exact tie points (measured: plan 1.88 m and 1.90 m,
against 2.04 m and 2.08 m with every term kept); robust estimation off: with it, exact tie points
leave the robust passes without a scale for the measured control points (their variance
components go to the 0.01 floor) and the run does not converge or keeps other terms; --control control points
nearest the nadir image's corners and edges)
with the matched tie points, with exact tie points at the same positions (same ids and sigmas),
and without tie points: the 3D check-point figures (report['check_points']['intersection']:
every check point intersected from its rays in the adjusted model).
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
from pushbroom_adjust.core.measure.matching import MatchSettings  # noqa: E402
from pushbroom_adjust.core.formats import load_scene  # noqa: E402
from pushbroom_adjust.simulation.measurements import GcpSettings  # noqa: E402
from pushbroom_adjust.simulation.simulator import SimulationResult, simulate  # noqa: E402
from pushbroom_adjust.core.observations.tiepoints import summary  # noqa: E402
from tests.support.matchscene import compare_ties, th1_cut  # noqa: E402

FIGURES = ("rmse_plan", "rmse_height", "ce90", "le90")


def scene(out: Path | None, cols: int, rows: int, seed: int) -> SimulationResult:
    """The rendered cut TH-1 simulation: made in ``out`` (or a temporary folder), reused when there."""
    folder = out or Path(tempfile.mkdtemp(prefix="bench_matchtie_"))
    names = ("NAD", "FWD", "BWD")
    if not (folder / "image_BWD.tif").exists():
        t = time.perf_counter()
        simulate(th1_cut(cols, rows), folder, seed=seed, render=True,
                 gcp_settings=GcpSettings(n_gcps=60, check_fraction=0.5, image_noise=0.3))
        print(f"simulated and rendered {cols} x {rows} px x 3 cameras into {folder} in {time.perf_counter() - t:.0f} s")
    return SimulationResult(folder, folder / "onboard_scene.json", folder / "true_scene.json", folder / "gcps.csv",
                            folder / "dem.tif", folder / "simulation.json",
                            images={n: folder / f"image_{n}.tif" for n in names})


def line(label: str, figures: dict) -> str:
    return f"  {label:<28}" + "  ".join(f"{k} {figures[k]:7.2f} m" for k in FIGURES) + \
        f"  ({figures['intersected']} of {figures['points']} check points intersected)"


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cols", type=int, default=6000)
    ap.add_argument("--rows", type=int, default=6000)
    ap.add_argument("--spacing", type=float, default=100.0)
    ap.add_argument("--control", type=int, default=9)
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--out", type=Path)
    ap.add_argument("--selection", choices=("significant", "keep"), default="significant",
                    help="INTERIOR_SELECTION of the adjustments")
    a = ap.parse_args()
    sim = scene(a.out, a.cols, a.rows, a.seed)
    settings = AdjustmentSettings(interior="default", robust="none", interior_selection=a.selection)
    load = os.getloadavg()[0]
    c = compare_ties(sim, a.control, MatchSettings(spacing=a.spacing, search=300.0), settings)
    s = summary(c.matched)
    print(f"matched {s['points']} tie points ({s['observations']} observations) in {c.seconds:.1f} s "
          f"(load average {load:.1f}); per camera pair: " + ", ".join(f"{k} {v}" for k, v in s["pairs"].items()))
    for name, counts in c.rejected.items():
        print(f"  NAD-{name} rejected: " + (", ".join(f"{v} {k}" for k, v in counts.items() if v) or "none"))
    print("error against the truth (px):")
    for name, e in c.errors.items():
        print(f"  {name}: {e.size} observations, median {np.median(e):.3f}, 90 % {np.percentile(e, 90):.3f}, "
              f"largest {e.max():.3f}, {100 * np.mean(e > 1):.1f} % > 1 px")
    onboard = load_scene(sim.onboard_scene)
    without = adjust(onboard, c.gcps, settings).report["check_points"]["intersection"]
    print(f"3D check points, adjustment with {a.control} control points, INTERIOR=default, "
          f"INTERIOR_SELECTION={a.selection}, robust off:")
    print(line("matched tie points", c.with_matched))
    print(line("exact tie points", c.with_exact))
    print(line("no tie points", without))
    ratio = {k: c.with_matched[k] / c.with_exact[k] for k in ("rmse_plan", "rmse_height")}
    print("matched / exact: " + ", ".join(f"{k} {v:.3f}" for k, v in ratio.items()))


if __name__ == "__main__":
    main()
