"""Speed of the rigorous sensor model, printed (no assertions).

Run:  PYTHONPATH=. /usr/bin/python3 tests/bench/bench_sensor.py [--points N]

Measures, after a warm-up call (trajectory tables and first-guess rasters built), on
the simulated default CBERS-02B HRC scene (three staggered CCDs, aberration and refraction
on) with its DEM, and on the real Pleiades 1B scene with its DEM:
  - ground -> image, points/s
  - image -> ground on the DEM, points/s
  - round-trip error image -> ground(DEM) -> image, px (next to a seam of the simulated
    scene's misaligned CCDs, where ground is imaged twice, the ground distance between what
    the two pixels see, in px; see tests/seams.py), and how many points fell there
and the peak resident memory of the process.
"""
from __future__ import annotations

import argparse
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))
import tests.support.plugin_package  # noqa: E402,F401 (registers the package pushbroom_adjust)

from pushbroom_adjust.core.dem import Dem  # noqa: E402
from pushbroom_adjust.core.formats import load_scene  # noqa: E402
from pushbroom_adjust.simulation.simulator import simulate  # noqa: E402
from tests.support.seams import round_trip_errors  # noqa: E402

PLEIADES = REPO / "tests" / "data" / "pleiades"


def bench(name: str, scene, dem, n: int, seed: int = 0) -> None:
    cam = scene.cameras[0]
    rng = np.random.default_rng(seed)
    col = rng.uniform(0, cam.cols, n)
    row = rng.uniform(0, cam.rows, n)
    warm = scene.image_to_ground_dem(col[:1000], row[:1000], dem)
    scene.ground_to_image(warm[np.isfinite(warm[:, 0])])
    t0 = time.perf_counter()
    ground = scene.image_to_ground_dem(col, row, dem)
    t1 = time.perf_counter()
    on_dem = np.isfinite(ground[:, 0])
    col2, row2 = scene.ground_to_image(ground[on_dem])
    t2 = time.perf_counter()
    err, duplicate = round_trip_errors(scene, dem, col[on_dem], row[on_dem], col2, row2)
    print(f"{name}: {n} points, image->ground(DEM) {n / (t1 - t0):,.0f} pts/s, "
          f"ground->image {on_dem.sum() / (t2 - t1):,.0f} pts/s, round trip max {np.nanmax(err):.2e} px "
          f"({int(duplicate.sum())} seam duplicates), rays off the DEM {int((~on_dem).sum())}, "
          f"unsolved {int(np.isnan(err).sum())}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--points", type=int, default=1_000_000)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        simulate("cbers02b_hrc", tmp, seed=1, n_gcps=10)
        scene = load_scene(Path(tmp) / "true_scene.json")
        bench("CBERS-02B HRC (simulated)", scene, Dem(Path(tmp) / "dem.tif", datum="geoid"), args.points)
    pleiades = load_scene(next(PLEIADES.glob("PHRDIMAP_*.XML")))
    bench("Pleiades 1B (real)", pleiades, Dem(next(PLEIADES.glob("MNT_*.tif")), datum="geoid"), args.points)
    print(f"peak resident memory {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:,.0f} MiB")


if __name__ == "__main__":
    main()
