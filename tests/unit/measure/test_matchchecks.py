"""core.measure.matchchecks on a constructed camera of three chips (1000 px each, overlapping by 20 px:
chip 1 delivers columns from 980, chip 2 from 1960) and grids of matches with known offsets."""
import numpy as np
import pytest

from pushbroom_adjust.core.measure.matchchecks import INCONSISTENT_PX, inconsistent, within_one_chip
from pushbroom_adjust.core.model.camera import Camera, Chip, LineTiming


def camera(offsets=(0, 980, 1960)) -> Camera:
    chips = [Chip(col_offset=o, n_pixels=1000, kind="look_angle", ux_poly=[0.0], uy_poly=[-0.01, 2e-5])
             for o in offsets]
    return Camera("PAN", offsets[-1] + 1000, 3000, LineTiming(-1.0, 1e-3), chips)


def test_a_window_within_one_chip_passes_and_one_across_a_seam_does_not():
    cam = camera()
    first = np.array([10.0, 950.0, 970.0, 990.0, 1950.0, 2500.0, 2940.0])
    last = np.array([40.0, 979.0, 990.0, 1020.0, 1970.0, 2530.0, 2959.0])
    expected = [True, True, False, True, False, True, True]  # 970-990 and 1950-1970 straddle a seam
    np.testing.assert_array_equal(within_one_chip(cam, first, last), expected)
    np.testing.assert_array_equal(within_one_chip(cam, last, first), expected)  # either order


def test_a_single_chip_camera_has_no_seam():
    cam = camera((0,))
    assert within_one_chip(cam, np.array([0.0, 10.0]), np.array([999.0, 500.0])).all()


def grid(cam: Camera, step: float = 100.0):
    """(col, row) (n,) of a grid of matches over the camera's image, 50 px from its edges."""
    col, row = np.meshgrid(np.arange(50.0, cam.cols, step), np.arange(50.0, cam.rows, step))
    return col.ravel(), row.ravel()


def smooth_offsets(col, row, rng):
    """A smooth offset field (an onboard model's error: ~0.1 px over 1000 px) plus 0.02 px of noise."""
    dc = 0.3 + 1e-4 * col - 5e-5 * row + rng.normal(0.0, 0.02, col.size)
    dr = -0.2 + 2e-4 * row + 3e-5 * col + rng.normal(0.0, 0.02, col.size)
    return dc, dr


def test_a_match_off_its_neighbours_by_a_pixel_or_more_is_rejected_and_no_other():
    cam = camera()
    rng = np.random.default_rng(1)
    col, row = grid(cam)
    dc, dr = smooth_offsets(col, row, rng)
    # 3 px and 1.5 px off (rejected), 0.6 px off (within INCONSISTENT_PX: kept)
    far, near, small = 100, 431, 777
    dc[far] += 3.0
    dr[near] += 1.5
    dc[small] += 0.6 * INCONSISTENT_PX
    ok = np.ones(col.size, bool)
    out = inconsistent(cam, col, row, col + dc, row + dr, ok)
    assert np.nonzero(out)[0].tolist() == [far, near]


def test_matches_not_ok_are_neither_judged_nor_neighbours():
    cam = camera()
    rng = np.random.default_rng(2)
    col, row = grid(cam)
    dc, dr = smooth_offsets(col, row, rng)
    wild = np.arange(0, col.size, 7)
    dc[wild] += rng.uniform(5.0, 50.0, wild.size)  # 1 in 7 matched elsewhere, known bad already
    ok = np.ones(col.size, bool)
    ok[wild] = False
    assert not inconsistent(cam, col, row, col + dc, row + dr, ok).any()
    ok[wild[0]] = True  # one of them judged: the only one rejected
    assert np.nonzero(inconsistent(cam, col, row, col + dc, row + dr, ok))[0].tolist() == [wild[0]]


def test_a_slope_the_surface_lacks_is_consistent():
    """A parallax ramp of 2 px per grid step (a slope the surface lacks): its neighbours' plane
    predicts it, where their median is 1-2 px off along the grid's edges."""
    cam = camera()
    col, row = grid(cam)
    dc, dr = smooth_offsets(col, row, np.random.default_rng(3))
    dr += 0.02 * row
    assert not inconsistent(cam, col, row, col + dc, row + dr, np.ones(col.size, bool)).any()


def test_matches_are_compared_with_those_of_their_own_chip():
    """Matches along one column of chip 0 (960) beside two columns of chip 1 (1000, 1040) whose
    offsets are 5 px apart from chip 0's: six of a chip-0 match's eight nearest matches are on
    chip 1, yet it is compared with its own chip's only. The same matches on a camera of one chip
    are rejected."""
    rows = np.arange(50.0, 3000.0, 100.0)
    col = np.repeat([960.0, 1000.0, 1040.0], rows.size)
    row = np.tile(rows, 3)
    dc, dr = smooth_offsets(col, row, np.random.default_rng(4))
    dc += np.where(col > 980, 5.0, 0.0)
    ok = np.ones(col.size, bool)
    assert not inconsistent(camera(), col, row, col + dc, row + dr, ok).any()
    assert inconsistent(camera((0,)), col, row, col + dc, row + dr, ok)[:rows.size].sum() > rows.size // 2


@pytest.mark.parametrize("n", [0, 5, 8])
def test_too_few_matches_to_compare_are_kept(n):
    cam = camera()
    col, row = grid(cam)
    col, row = col[:n], row[:n]
    assert not inconsistent(cam, col, row, col + np.arange(n) * 10.0, row, np.ones(n, bool)).any()
