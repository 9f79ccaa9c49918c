"""The TH-1 self-calibration gap of Zhang et al. 2015 (seed 001) on the simulator's th1_tlc
preset: conventional adjustment (trajectory only) against the 10 camera terms of eq. 7 free
for every camera, and the floor (the true interior and installation given). Prints figures
(no assertions).

Run:  PYTHONPATH=. PROJ_DATA=/usr/share/proj /usr/bin/python3 tests/bench/bench_th1_selfcal_gap.py
      [--seeds 1 2 3] [--control 9] [--points 60]

Each block: one TH-1 scene with the preset's errors, --points ground points measured with
0.7 px image noise (seed 001: manual measurement, 0.5-1 px) and 0.1 m / 0.2 m ground noise,
--control of them control points, the others check points. Check figures: the monoplotted
planimetric RMSE the adjustment reports and the RMSE east / north / up of the check points
intersected from all their cameras with the adjusted model (seed 001's X, Y, Z).
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))
import tests.support.plugin_package  # noqa: E402,F401 (registers the package pushbroom_adjust)

from pushbroom_adjust.core.observations import gcps as G  # noqa: E402
from pushbroom_adjust.core.observations.tables import Heights  # noqa: E402
from pushbroom_adjust.core.adjust import AdjustmentSettings, adjust  # noqa: E402
from pushbroom_adjust.core.model.camera import CAMERA_TERMS  # noqa: E402
from pushbroom_adjust.core.geodesy import ecef_to_geodetic, enu_rotations, geodetic_to_ecef  # noqa: E402
from pushbroom_adjust.core.model.intersection import intersect  # noqa: E402
from pushbroom_adjust.core.formats import load_scene  # noqa: E402
from pushbroom_adjust.simulation.measurements import GcpSettings  # noqa: E402
from pushbroom_adjust.simulation.simulator import simulate  # noqa: E402

IMAGE_NOISE, GROUND_XY, GROUND_Z = 0.7, 0.1, 0.2
CAMERAS = ("NAD", "FWD", "BWD")
# Seed 001 corrects the attitude (bias and drift) of a GPS-positioned platform: the position
# is a bias held by the onboard GPS (the preset draws 3-10 m per axis).
SETTINGS = AdjustmentSettings(position_order=0, position_sigma=10.0, attitude_order=1, robust="none")
SELF_CALIBRATION = ", ".join(f"{cam}.{term}" for cam in CAMERAS for term in CAMERA_TERMS)


def intersected_rmse(scene, table, truth: dict) -> np.ndarray:
    """RMSE (east, north, up) m of the check points intersected with ``scene`` from every camera."""
    check = table.role == "check"
    ids, point = np.unique(table.id[check], return_inverse=True)
    camera = np.array([scene.camera_index(c) for c in table.camera[check]])
    out = intersect(scene, camera, table.col[check], table.row[check], point, ids.size)
    true = np.array([truth[i] for i in ids])
    lon, lat, _ = ecef_to_geodetic(true)
    rot = enu_rotations(lon, lat)
    enu = np.einsum("nij,nj->ni", rot, out.ground - true)
    ok = np.all(np.isfinite(enu), axis=1)
    return np.sqrt(np.mean(enu[ok] ** 2, axis=0))


def block(seed: int, points: int, control: int, folder: Path) -> dict:
    result = simulate("th1_tlc", folder, seed=seed, gcp_settings=GcpSettings(
        n_gcps=points, check_fraction=(points - control) / points, image_noise=IMAGE_NOISE,
        ground_noise_xy=GROUND_XY, ground_noise_z=GROUND_Z))
    table = G.read_csv(result.gcps, G.CsvMapping(z="h", role="role", camera="camera"), "EPSG:4326",
                       Heights("z", datum="ellipsoid"), sigma_px=IMAGE_NOISE, sigma_xy=GROUND_XY,
                       sigma_z=GROUND_Z)
    raw = np.genfromtxt(result.gcps, delimiter=",", names=True, dtype=None, encoding=None)
    truth = dict(zip(raw["id"], geodetic_to_ecef(raw["lon_true"], raw["lat_true"], raw["h_true"])))
    onboard, true = load_scene(result.onboard_scene), load_scene(result.true_scene)
    floor_scene = replace(onboard, cameras=true.cameras, _guess={})
    runs = {"conventional": (onboard, ""), "self-calibrated": (onboard, SELF_CALIBRATION),
            "floor (true interior)": (floor_scene, "")}
    figures = {}
    for name, (scene, interior) in runs.items():
        out = adjust(scene, table, replace(SETTINGS, interior=interior))
        ground = out.report["check_points"]["ground"]
        figures[name] = (ground["rmse_east"], ground["rmse_north"], *intersected_rmse(out.scene, table, truth))
    return figures


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    parser.add_argument("--control", type=int, default=9)
    parser.add_argument("--points", type=int, default=60)
    args = parser.parse_args()
    print(f"TH-1, {args.control} control points, {args.points - args.control} check points, "
          f"{IMAGE_NOISE} px image noise")
    print(f"{'seed':>4} {'adjustment':<22} {'mono E':>7} {'mono N':>7} {'X (E)':>7} {'Y (N)':>7} {'Z (up)':>7}  m")
    for seed in args.seeds:
        with tempfile.TemporaryDirectory() as tmp:
            for name, f in block(seed, args.points, args.control, Path(tmp)).items():
                print(f"{seed:>4} {name:<22} " + " ".join(f"{v:7.2f}" for v in f))


if __name__ == "__main__":
    main()
