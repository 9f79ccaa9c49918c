"""Control lines (Tommaselli & Marcato Junior 2012) for the tests of core.adjust.linepoints,
pushbroom:importlines and bundleadjust LINES: a simulated CBERS-02B HRC scene with roads (the
fixture ``roads``, imported by the test modules that use it) and straight lines all of one
direction (what leaves one direction free)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from pushbroom_adjust.core.adjust.linepoints import ControlLines
from pushbroom_adjust.core.geodesy import ecef_to_geodetic, geodetic_to_ecef
from pushbroom_adjust.core.observations.lines import GroundLines, ImageLines
from pushbroom_adjust.simulation.measurements import GcpSettings
from pushbroom_adjust.simulation.roads import RoadSettings
from pushbroom_adjust.simulation.simulator import simulate


@pytest.fixture(scope="module")
def roads(tmp_path_factory):
    """(simulation result, folder) of a CBERS-02B HRC scene (seed 2, no CCD errors) with 40 GCPs
    (half check points) and 20 roads, 10 % of them wrong on the map."""
    folder = tmp_path_factory.mktemp("roads")
    result = simulate("cbers02b_hrc", folder / "sim", seed=2, errors=dict(ccd_shift=0.0, ccd_rotation=0.0),
                      gcp_settings=GcpSettings(n_gcps=40, check_fraction=0.5, image_noise=0.5, ground_noise_xy=0.5,
                                               ground_noise_z=1.0),
                      road_settings=RoadSettings(n_lines=20, wrong_fraction=0.1))
    return result, folder


def parallel_lines(true_scene, count=5, points=10, noise=0.3, seed=0) -> ControlLines:
    """Straight east-west lines (5 km apart, 20 km long, at 500 m) and their image lines through the
    true scene with ``noise`` px."""
    rng = np.random.default_rng(seed)
    cam = true_scene.cameras[0]
    lon0, lat0, _ = ecef_to_geodetic(true_scene.image_to_ground(np.array([cam.cols / 2]), np.array([cam.rows / 2]),
                                                                500.0, 0))
    lon0, lat0 = float(lon0[0]), float(lat0[0])
    k = 1.0 / (111320.0 * math.cos(math.radians(lat0)))
    ids, parts, cols, rows = [], [], [], []
    for i, north in enumerate(np.linspace(-10e3, 10e3, count)):
        lon = lon0 + np.array([-10e3, 10e3]) * k
        lat = np.full(2, lat0 + north / 110574.0)
        ids.append(f"P{i}")
        parts.append((lon, lat))
        s = np.linspace(-9e3, 9e3, points) * k + lon0
        c, r = true_scene.ground_to_image(geodetic_to_ecef(s, np.full(points, lat[0]), np.full(points, 500.0)), 0)
        cols.append(c + rng.normal(0, noise, points))
        rows.append(r + rng.normal(0, noise, points))
    ground = GroundLines(ids, np.arange(count + 1) * 2, np.concatenate([p[0] for p in parts]),
                         np.concatenate([p[1] for p in parts]), np.full(2 * count, 500.0), 1.0, 2.0)
    image = ImageLines(ids, "HRC", np.arange(count + 1) * points, np.concatenate(cols), np.concatenate(rows), noise)
    return ControlLines(ground, image)
