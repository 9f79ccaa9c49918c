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


def block_lines(true_scenes: dict, count: int = 8, points: int = 12, noise: float = 0.3, length: float = 2000.0,
                seed: int = 0) -> tuple[ControlLines, np.ndarray]:
    """Control lines of a block (issue 23) and their true ground: ``count`` straight ground lines
    ``length`` m long, in ``count`` directions evenly over 180 degrees, centred at points spread
    over the first scene's first camera image, each at its own ellipsoidal height (300-900 m);
    ``points`` image points evenly along each (5-95 % of its length), projected through every
    camera of every true scene (name -> SceneModel) that sees three of them or more 5 px inside
    its image, with ``noise`` px per axis: one image line per (line, scene, camera), naming its
    scene and the scene's own camera. Also the true ground (count * points, 3) ECEF m of the
    image points, line by line."""
    rng = np.random.default_rng(seed)
    ref = next(iter(true_scenes.values()))
    cam = ref.cameras[0]
    k = int(math.ceil(math.sqrt(count)))
    at = np.linspace(0.25, 0.75, k)
    col, row = (a.ravel()[:count] for a in np.meshgrid(at * cam.cols, at * cam.rows))
    height = rng.uniform(300.0, 900.0, count)
    lon0, lat0, _ = ecef_to_geodetic(ref.image_to_ground(col, row, height, 0))
    azimuth = np.arange(count) * math.pi / count
    half = 0.5 * length * np.stack([np.sin(azimuth), np.cos(azimuth)], axis=1)  # (count, 2) east, north m
    lon = lon0[:, None] + np.stack([-half[:, 0], half[:, 0]], 1) / (111320.0 * np.cos(np.radians(lat0)))[:, None]
    lat = lat0[:, None] + np.stack([-half[:, 1], half[:, 1]], 1) / 110574.0
    ends = geodetic_to_ecef(lon.ravel(), lat.ravel(), np.repeat(height, 2)).reshape(count, 2, 3)
    t = np.linspace(0.05, 0.95, points)
    truth = ends[:, :1] + t[None, :, None] * (ends[:, 1:] - ends[:, :1])  # (count, points, 3) on the chords
    ids = np.array([f"L{i}" for i in range(count)])
    parts = {"line_id": [], "scene": [], "camera": [], "col": [], "row": []}
    for name, scene in true_scenes.items():
        for c, camera in enumerate(scene.cameras):
            for i in range(count):
                pc, pr = scene.ground_to_image(truth[i], c)
                ok = np.isfinite(pc) & (pc > 5) & (pc < camera.cols - 5) & (pr > 5) & (pr < camera.rows - 5)
                if ok.sum() >= 3:
                    n = int(ok.sum())
                    for key, value in (("line_id", ids[i]), ("scene", name), ("camera", camera.name)):
                        parts[key].append(value)
                    parts["col"].append(pc[ok] + rng.normal(0.0, noise, n))
                    parts["row"].append(pr[ok] + rng.normal(0.0, noise, n))
    ground = GroundLines(ids, np.arange(count + 1) * 2, lon.ravel(), lat.ravel(), np.repeat(height, 2), 1.0, 2.0)
    start = np.r_[0, np.cumsum([len(p) for p in parts["col"]])]
    image = ImageLines(parts["line_id"], parts["camera"], start, np.concatenate(parts["col"]),
                       np.concatenate(parts["row"]), noise, parts["scene"])
    return ControlLines(ground, image), truth.reshape(-1, 3)
