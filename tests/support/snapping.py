"""A rendered scene with roads and clicks along them, for snapping digitised image lines to the
road (core.measure.snapping, pushbroom:snaplines, the digitising dock's Snap): a CBERS-02B HRC
scene cut to its first ROWS rows with three roads (along track, across track, curved) rendered
into its raw image, and each road's true image from the simulator's truth."""
from __future__ import annotations

import math
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np
import pytest

from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.geodesy import ecef_to_geodetic, geodetic_to_ecef
from pushbroom_adjust.core.observations.lines import ImageLines
from pushbroom_adjust.simulation.render import render_image
from pushbroom_adjust.simulation.roads import RoadSettings, road_curve
from pushbroom_adjust.simulation.simulator import simulate
from pushbroom_adjust.simulation.texture import plane_to_lonlat, texture_frame, texture_plane

ROWS = 600
"""The rows of the rendered scene (its first camera cut to them)."""


def road_through(scene, dem, centre, a, b, k0=0.0) -> dict:
    """A road definition through image points a and b (col, row) of camera 0 (in the texture plane
    about ``centre``; curvature ``k0``)."""
    g = scene.image_to_ground_dem(np.array([a[0], b[0]]), np.array([a[1], b[1]]), dem, 0)
    lon, lat, _ = ecef_to_geodetic(g)
    x, y = texture_plane(lon, lat, centre)
    return {"x0": float(x.mean()), "y0": float(y.mean()), "azimuth": math.atan2(x[1] - x[0], y[1] - y[0]),
            "length": float(np.hypot(x[1] - x[0], y[1] - y[0])), "k0": k0, "k1": 0.0}


def render_roads(folder: Path) -> tuple:
    """Simulate a CBERS-02B HRC scene (seed 4) into ``folder``/sim, cut it to ROWS rows and render
    its raw image with three roads into ``folder``/img.tif; (image path, cut true scene, the roads'
    true images: one (n, 2) array of (col, row) per road)."""
    result = simulate("cbers02b_hrc", folder / "sim", seed=4, n_gcps=10)
    true = load_scene(result.true_scene)
    small = replace(true, cameras=[replace(true.cameras[0], rows=ROWS)], _guess={})
    dem = Dem(result.dem, datum="geoid")
    frame = texture_frame(true, dem, 4)
    centre = tuple(frame["centre"])
    roads = [road_through(small, dem, centre, (2000, -50), (2300, 650)),             # along track
             road_through(small, dem, centre, (5000, 280), (9500, 330)),             # across track
             road_through(small, dem, centre, (600, 650), (4000, -80), k0=1 / 2500)]  # curved, diagonal
    frame["roads"] = {"settings": asdict(RoadSettings()), "roads": roads}
    render_image(small, 0, dem, folder / "img.tif", frame)
    truth = []
    for road in roads:  # the road's true image: its centre line on the DEM through the true scene
        lon, lat = plane_to_lonlat(*road_curve(road, 0.5), centre)
        col, row = small.ground_to_image(geodetic_to_ecef(lon, lat, dem.height(lon, lat)), 0)
        truth.append(np.stack([col, row], axis=1)[np.isfinite(col)])
    return folder / "img.tif", small, truth


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """:func:`render_roads` in a temporary folder: (image path, cut true scene, true road images)."""
    return render_roads(tmp_path_factory.mktemp("snap"))


def clicks_along(truth, spacing, noise, rng, cols) -> ImageLines:
    """Clicks every ~spacing px along each true image line (inside the image) with noise px."""
    parts = []
    for t in truth:
        inside = t[(t[:, 1] > 15) & (t[:, 1] < ROWS - 15) & (t[:, 0] > 15) & (t[:, 0] < cols - 15)]
        arc = np.r_[0, np.cumsum(np.hypot(*np.diff(inside, axis=0).T))]
        at = np.arange(0.0, arc[-1], spacing)
        pts = np.stack([np.interp(at, arc, inside[:, 0]), np.interp(at, arc, inside[:, 1])], axis=1)
        parts.append(pts + rng.normal(0.0, noise, pts.shape))
    return ImageLines([f"R{i}" for i in range(len(parts))], "HRC", np.r_[0, np.cumsum([len(p) for p in parts])],
                      np.concatenate(parts)[:, 0], np.concatenate(parts)[:, 1], noise)


def across_error(lines: ImageLines, truth) -> np.ndarray:
    """Distance (px) of every vertex to its line's true image (a dense polyline)."""
    out = []
    for i in range(len(lines)):
        sl = slice(lines.start[i], lines.start[i + 1])
        p = np.stack([lines.col[sl], lines.row[sl]], axis=1)[:, None, :]
        a, b = truth[i][None, :-1], truth[i][None, 1:]
        d = b - a
        t = np.clip(np.sum((p - a) * d, axis=2) / np.sum(d * d, axis=2), 0, 1)
        out.append(np.min(np.linalg.norm(p - a - t[..., None] * d, axis=2), axis=1))
    return np.concatenate(out)
