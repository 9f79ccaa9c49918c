"""core.measure.prediction: where the models put a raw image's pixels in a reference, on a
simulated CBERS-02B scene and a reference grid of twice its GSD: the window's biquadratic map
against the exact mapping of every pixel, the reference's scale, and the coarse lattice."""
import numpy as np
import pytest

from pushbroom_adjust.core.dem import ConstantHeight
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.geodesy import ecef_to_geodetic
from pushbroom_adjust.core.measure.prediction import lattice_positions, predicted_positions, reference_scale
from pushbroom_adjust.simulation.simulator import simulate

HEIGHT = 800.0


class LonLatGrid:
    """A reference whose array positions are a north-up lon/lat grid of ``pixel`` m (at the
    latitude ``lat0``): ground_pixel as the matcher's references offer it."""

    def __init__(self, lon0: float, lat0: float, pixel: float):
        self.lon0, self.lat0 = lon0, lat0
        self.dlat = pixel / 111_320.0
        self.dlon = self.dlat / np.cos(np.radians(lat0))

    def ground_pixel(self, ground: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        lon, lat, _ = ecef_to_geodetic(np.asarray(ground).reshape(-1, 3))
        return (lon - self.lon0) / self.dlon, (self.lat0 - lat) / self.dlat


@pytest.fixture(scope="module")
def scene_and_ref(tmp_path_factory):
    result = simulate("cbers02b_hrc", tmp_path_factory.mktemp("prediction"), seed=6, n_gcps=10)
    scene = load_scene(result.true_scene)
    cam = scene.cameras[0]
    centre = scene.image_to_ground_dem(np.array([cam.cols / 2]), np.array([cam.rows / 2]), ConstantHeight(HEIGHT), 0)
    lon, lat, _ = ecef_to_geodetic(centre)
    gsd = 2.36  # m: CBERS-02B HRC at nadir
    return scene, LonLatGrid(float(lon[0]) - 0.2, float(lat[0]) + 0.2, 2 * gsd)


def exact(scene, ref, col, row):
    x, y = ref.ground_pixel(scene.image_to_ground_dem(col.ravel(), row.ravel(), ConstantHeight(HEIGHT), 0))
    return x.reshape(col.shape), y.reshape(col.shape)


def test_a_windows_map_is_the_exact_mapping_of_its_pixels(scene_and_ref):
    scene, ref = scene_and_ref
    col, row = np.array([1500.0, 6000.5, 11000.0]), np.array([900.0, 4000.0, 10000.5])
    size, step, half = 31, 1.0, 15.0
    px, py, ground = predicted_positions(scene, 0, ConstantHeight(HEIGHT), ref, col, row, half, size, step)
    k = step * (np.arange(size) - (size - 1) / 2)
    cc = col[:, None, None] + k[None, None, :] + 0 * k[None, :, None]
    rr = row[:, None, None] + k[None, :, None] + 0 * k[None, None, :]
    ex, ey = exact(scene, ref, cc, rr)
    assert px.shape == (3, size, size) and ground.shape == (3, 3)
    assert np.abs(px - ex).max() < 1e-3 and np.abs(py - ey).max() < 1e-3
    # the centre is exact: the ground returned is the grid point's
    cx, cy = ref.ground_pixel(ground)
    np.testing.assert_allclose(cx, px[:, 15, 15], atol=1e-9)


def test_the_warp_rectifies_the_window_at_the_offsets_found(scene_and_ref):
    """With offsets that grow across the image, node q is moved by -(d(q) - d(p0)): the window's
    positions equal the exact mapping of the pixels moved so."""
    scene, ref = scene_and_ref
    warp = lambda c, r: (0.01 * c, -0.02 * r)  # noqa: E731
    col, row = np.array([5000.0]), np.array([5000.0])
    px, py, _ = predicted_positions(scene, 0, ConstantHeight(HEIGHT), ref, col, row, 15.0, 31, 1.0, warp=warp)
    k = np.arange(31) - 15.0
    cc = col[0] + k[None, :] * (1 - 0.01) + 0 * k[:, None]
    rr = row[0] + k[:, None] * (1 + 0.02) + 0 * k[None, :]
    ex, ey = exact(scene, ref, cc, rr)
    assert np.abs(px[0] - ex).max() < 1e-3 and np.abs(py[0] - ey).max() < 1e-3


def test_a_reference_of_twice_the_gsd_has_half_the_scale(scene_and_ref):
    scene, ref = scene_and_ref
    assert reference_scale(scene, 0, ConstantHeight(HEIGHT), ref) == pytest.approx(0.5, rel=0.08)


def test_the_coarse_lattice_is_exact_at_its_nodes_and_close_between(scene_and_ref):
    scene, ref = scene_and_ref
    step, shape = 16.0, (40, 50)
    x, y = lattice_positions(scene, 0, ConstantHeight(HEIGHT), ref, 100.0, 200.0, step, shape)
    jj, ii = np.meshgrid(np.arange(shape[1]), np.arange(shape[0]))
    ex, ey = exact(scene, ref, 100.0 + step * jj.astype(float), 200.0 + step * ii.astype(float))
    nodes = (ii % 8 == 0) & (jj % 8 == 0)
    assert np.abs(x - ex)[nodes].max() < 1e-9 and np.abs(y - ey)[nodes].max() < 1e-9
    assert np.abs(x - ex).max() < 0.05 and np.abs(y - ey).max() < 0.05
