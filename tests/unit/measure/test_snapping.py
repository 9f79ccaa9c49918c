"""Snapping digitised image lines to rendered roads (core.measure.snapping): clicks with 2 px error
refined across the road, against the road's true image from the simulator's truth (the scene: the
fixture ``rendered`` of tests/support/snapping.py, made available by tests/conftest.py)."""
from __future__ import annotations

import numpy as np
import pytest
from osgeo import gdal

from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.observations.lines import ImageLines
from pushbroom_adjust.core.measure.snapping import SnapSettings, snap_lines
from tests.support.snapping import across_error, clicks_along


def test_clicks_with_2px_error_snap_to_the_road_centre_within_0_3px(rendered):
    path, scene, truth = rendered
    lines = clicks_along(truth, 40.0, 2.0, np.random.default_rng(1), scene.cameras[0].cols)
    before = across_error(lines, truth)
    result = snap_lines(path, lines)
    after = across_error(result.lines, truth)
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
    lines = clicks_along(truth[:1], 40.0, 2.0, np.random.default_rng(2), scene.cameras[0].cols)
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
