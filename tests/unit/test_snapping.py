"""Snapping digitised image lines to rendered roads (core.measure.snapping): clicks with 2 px error
refined across the road, against the road's true image from the simulator's truth."""
from __future__ import annotations

import math
from dataclasses import asdict, replace

import numpy as np
import pytest
from osgeo import gdal

from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.geodesy import ecef_to_geodetic, geodetic_to_ecef
from pushbroom_adjust.core.observations.lines import ImageLines
from pushbroom_adjust.simulation.texture import texture_frame, texture_plane
from pushbroom_adjust.simulation.render import render_image
from pushbroom_adjust.simulation.texture import plane_to_lonlat
from pushbroom_adjust.simulation.roads import RoadSettings, road_curve
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.simulation.simulator import simulate
from pushbroom_adjust.core.measure.snapping import SnapSettings, snap_lines

ROWS = 600


def _road(scene, dem, centre, a, b, k0=0.0):
    """A road definition through image points a and b (col, row) of camera 0."""
    g = scene.image_to_ground_dem(np.array([a[0], b[0]]), np.array([a[1], b[1]]), dem, 0)
    lon, lat, _ = ecef_to_geodetic(g)
    x, y = texture_plane(lon, lat, centre)
    return {"x0": float(x.mean()), "y0": float(y.mean()), "azimuth": math.atan2(x[1] - x[0], y[1] - y[0]),
            "length": float(np.hypot(x[1] - x[0], y[1] - y[0])), "k0": k0, "k1": 0.0}


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    folder = tmp_path_factory.mktemp("snap")
    result = simulate("cbers02b_hrc", folder / "sim", seed=4, n_gcps=10)
    true = load_scene(result.true_scene)
    small = replace(true, cameras=[replace(true.cameras[0], rows=ROWS)], _guess={})
    dem = Dem(result.dem, datum="geoid")
    frame = texture_frame(true, dem, 4)
    centre = tuple(frame["centre"])
    roads = [_road(small, dem, centre, (2000, -50), (2300, 650)),             # along track
             _road(small, dem, centre, (5000, 280), (9500, 330)),             # across track
             _road(small, dem, centre, (600, 650), (4000, -80), k0=1 / 2500)]  # curved, diagonal
    frame["roads"] = {"settings": asdict(RoadSettings()), "roads": roads}
    render_image(small, 0, dem, folder / "img.tif", frame)
    truth = []
    for road in roads:  # the road's true image: its centre line on the DEM through the true scene
        lon, lat = plane_to_lonlat(*road_curve(road, 0.5), centre)
        col, row = small.ground_to_image(geodetic_to_ecef(lon, lat, dem.height(lon, lat)), 0)
        truth.append(np.stack([col, row], axis=1)[np.isfinite(col)])
    return folder / "img.tif", small, truth


def _clicks(truth, spacing, noise, rng, cols):
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


def _across_error(lines: ImageLines, truth) -> np.ndarray:
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


def test_clicks_with_2px_error_snap_to_the_road_centre_within_0_3px(rendered):
    path, scene, truth = rendered
    lines = _clicks(truth, 40.0, 2.0, np.random.default_rng(1), scene.cameras[0].cols)
    before = _across_error(lines, truth)
    result = snap_lines(path, lines)
    after = _across_error(result.lines, truth)
    rms_before, rms_after = np.sqrt(np.mean(before ** 2)), np.sqrt(np.mean(after[result.refined] ** 2))
    print(f"clicks: {before.size}, RMS across before {rms_before:.2f} px, after {rms_after:.3f} px, "
          f"refined {result.refined.sum()}, max {after[result.refined].max():.3f} px")
    assert rms_before > 1.0                       # the clicks really are ~2 px off (across part)
    assert result.refined.mean() >= 0.95           # (near) every vertex found the road
    assert rms_after <= 0.3
    # each refined vertex has its own sigma (>= the floor, < max_sigma), of the size of the real error
    sig = result.lines.sigma_px[result.refined]
    assert np.all((sig >= 0.1) & (sig < 0.5))
    assert 0.5 < np.sqrt(np.mean(sig ** 2)) / rms_after < 3.0
    assert np.all(result.lines.sigma_px[~result.refined] == 2.0)


def test_snapping_reads_an_array_as_the_raster(rendered):
    path, scene, truth = rendered
    lines = _clicks(truth[:1], 40.0, 2.0, np.random.default_rng(2), scene.cameras[0].cols)
    image = gdal.Open(str(path)).ReadAsArray()
    a, b = snap_lines(image, lines), snap_lines(path, lines)
    assert np.allclose(a.lines.col, b.lines.col) and np.allclose(a.lines.row, b.lines.row)


def test_a_click_far_from_any_road_is_not_refined(rendered):
    path, scene, truth = rendered
    # a line in an empty textured area: no bright band to find (or kept, not moved far)
    lines = ImageLines(["X"], "HRC", [0, 3], [8000.0, 8040.0, 8080.0], [100.0, 110.0, 120.0], 2.0)
    result = snap_lines(path, lines)
    assert np.all(result.moved[result.refined] <= SnapSettings().search + 0.01)


def test_bad_snap_settings_are_refused():
    with pytest.raises(InputError, match="mode"):
        SnapSettings(mode="middle").validate()
    with pytest.raises(InputError, match="width"):
        SnapSettings(width=20.0).validate()
