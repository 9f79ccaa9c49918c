"""core.measure.pyramid: the search radius clipped to the image (and said so), the local levels'
factors, the offset field of the kept chips (a plane follows a slope of parallax exactly), and the
neighbour test that keeps offsets agreeing with their neighbours'."""
from types import SimpleNamespace

import numpy as np

from pushbroom_adjust.core.measure.pyramid import CoarseOffsets, agreeing, local_factors, search_radius


def test_a_search_range_beyond_the_image_is_clipped_to_its_larger_side():
    cam = SimpleNamespace(cols=1024, rows=800)
    assert search_radius(300.0, 0.5, cam) == (600.0, 300.0, False)
    # issue 28's default on a 1024 px crop: 1000 m at 0.5 m is 2000 px, clipped to 1024 px = 512 m
    assert search_radius(1000.0, 0.5, cam) == (1024.0, 512.0, True)


def test_local_levels_run_coarse_to_fine_by_fours_down_to_two():
    assert local_factors(1) == []
    assert local_factors(2) == [2]
    assert local_factors(32) == [32, 8, 2]
    assert local_factors(128) == [128, 32, 8, 2]


def coarse(offset=(3.0, -2.0)) -> CoarseOffsets:
    return CoarseOffsets(radius_px=100.0, search_m=50.0, clipped=False, factor=8, offset=offset, peak=0.9)


def test_without_kept_chips_the_global_offset_is_predicted_everywhere():
    dc, dr = coarse().predict(np.array([0.0, 500.0, 999.0]), np.array([10.0, 20.0, 30.0]))
    assert np.all(dc == 3.0) and np.all(dr == -2.0)


def test_the_field_of_the_kept_chips_follows_a_parallax_slope():
    """Chips whose offsets grow linearly across the image (relief the surface lacks, a slope): the
    planes fitted to the nearest chips reproduce it at any position, where a median would flatten
    it."""
    rng = np.random.default_rng(3)
    points = rng.uniform(0, 2000, (60, 2))
    slope = np.stack([0.004 * points[:, 0] + 1.0, -0.002 * points[:, 1] + 0.5], axis=1)
    out = coarse()
    out.set_field(points, slope, 2000, 2000, 50.0)
    col, row = rng.uniform(100, 1900, (2, 200))
    dc, dr = out.predict(col, row)
    np.testing.assert_allclose(dc, 0.004 * col + 1.0, atol=1e-6)
    np.testing.assert_allclose(dr, -0.002 * row + 0.5, atol=1e-6)
    assert out.summary()["offset_px"] == [3.0, -2.0] and out.summary()["clipped"] is False


def test_offsets_off_their_neighbours_are_not_kept():
    rng = np.random.default_rng(5)
    xy = rng.uniform(0, 1000, (80, 2))
    d = np.tile([4.0, -1.0], (80, 1)) + rng.normal(0, 0.3, (80, 2))
    d[[7, 40]] += [[6.0, 0.0], [0.0, -3.5]]
    keep = agreeing(xy, d, 2.0)
    assert not keep[7] and not keep[40] and keep.sum() == 78
    # too few to tell: all kept
    assert agreeing(xy[:4], d[:4] + [[50, 0], [0, 0], [0, 0], [0, 0]], 2.0).all()
