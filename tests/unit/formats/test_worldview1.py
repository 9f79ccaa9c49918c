"""The unmodified WorldView-1 product (Maxar isd XML, ISD version 28.3, with its TIL section) against
Maxar's own models for it: the RPB (RPC00B) and the IMD corner coordinates.

Data: tests/data/worldview1 (uw-cryo asp_plot test data, BSD-3-Clause; metadata (c) Maxar), a
Basic1B panchromatic part of 35180 x 24344 px over Antarctica, 18.8 deg off nadir. Unlike the
WorldView-3 file of tests/data (whose RPB the Ames Stereo Pipeline refitted), this RPB is Maxar's.

Measured with this reader (15 x 15 image points x 3 heights, RPB inverted to the ground):
no corrections 25.9 px max; with velocity aberration 1.32 px; with refraction too (the default)
0.118 px max, 0.077 px RMS. The IMD corners are met to 0.02 px.
"""
import pytest

from tests.support.vendor_rpc import imd_corner_misses, misfit, rpb_grid

NAME = "WV01_20210201005130_10200100A1865800_21FEB01005130-P1BS-016263048010_01_P001.xml"


@pytest.fixture(scope="module")
def wv1(shared_data):
    """(path, scene, rpc, ground points (n,3) ECEF, RPB col (n,), RPB row (n,))."""
    path = shared_data / "worldview1" / NAME
    return (path, *rpb_grid(path))


def test_model_meets_maxars_rpc(wv1):
    _, scene, _, ground, col, row = wv1
    worst, rms = misfit(scene, ground, col, row)
    assert worst <= 0.15 and rms <= 0.10


def test_each_correction_is_needed(wv1):
    _, scene, _, ground, col, row = wv1
    assert misfit(scene, ground, col, row, aberration=False, refraction=False)[0] > 20.0
    assert misfit(scene, ground, col, row, refraction=False)[0] > 1.0


def test_model_meets_imd_corners(wv1):
    """The IMD corners are the centres of the corner pixels, GDAL half-integers."""
    path, scene, *_ = wv1
    misses = imd_corner_misses(path, scene)
    assert sorted(misses) == ["LL", "LR", "UL", "UR"] and max(misses.values()) < 0.05, misses


def test_scene_metadata(wv1):
    _, scene, rpc, *_ = wv1
    info = scene.info
    assert (info["sensor"], info["isd_version"], info["rpb_origin"]) == ("WV01", "28.3", "Maxar")
    assert "warnings" not in info and info["corrections"]["aberration"] and info["corrections"]["refraction"]
    assert info["off_nadir_deg"] == 18.8 and info["catalog_id"] == "10200100A1865800"
    assert (scene.cameras[0].cols, scene.cameras[0].rows) == (35180, 24344)
    assert info["height_range"] == [rpc.height_off - rpc.height_scale, rpc.height_off + rpc.height_scale]
    assert 1.0 / scene.cameras[0].timing.mean_period() == pytest.approx(24000.0, rel=1e-6)
