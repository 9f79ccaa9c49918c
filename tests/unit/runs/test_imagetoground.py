"""core.runs.imagetoground: the use case behind pushbroom:imagetoground, on a cut of a simulated CBERS-02B
scene: the ground points lie on the terrain and project back onto the image points; points outside the
image are a warning, points off the DEM a refusal naming the features."""
import numpy as np
import pytest

from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.geodesy import geodetic_to_ecef
from pushbroom_adjust.core.runs import imagetoground as use_case
from pushbroom_adjust.core.runs.base import Terrain
from tests.support.ortho_compare import saved_cut


@pytest.fixture(scope="module")
def cut(tmp_path_factory):
    return saved_cut(tmp_path_factory.mktemp("runs_imagetoground"), seed=3, rows=400)


def grid(scene, n=5):
    cam = scene.cameras[0]
    col, row = np.meshgrid(np.linspace(10, cam.cols - 10, n), np.linspace(10, cam.rows - 10, n))
    return col.ravel(), row.ravel()


def test_the_ground_points_lie_on_the_dem_and_project_back(cut):
    scene_path, _, dem = cut
    scene = load_scene(scene_path)
    col, row = grid(scene)
    result = use_case.run(use_case.ImageToGroundRequest(scene_path, col, row, np.arange(col.size), terrain=Terrain(dem)))
    f = result.figures
    assert f["kept"].all() and result.lines == [] and result.files == {}
    assert np.abs(f["h"] - Dem(dem, "geoid").height(f["lon"], f["lat"])).max() < 0.05
    c, r = scene.ground_to_image(geodetic_to_ecef(f["lon"], f["lat"], f["h"]), 0)
    assert np.hypot(c - col, r - row).max() < 1e-3


def test_a_constant_height_and_points_outside_the_image(cut):
    scene_path, _, _ = cut
    scene = load_scene(scene_path)
    cam = scene.cameras[0]
    col, row = np.array([100.0, cam.cols + 50.0, 200.0]), np.array([100.0, 10.0, -30.0])
    result = use_case.run(use_case.ImageToGroundRequest(scene_path, col, row, np.arange(3),
                                                        terrain=Terrain(height=321.5)))
    assert np.allclose(result.figures["h"], 321.5, atol=1e-4)
    assert result.lines == [(f"2 points lie outside the image of camera {cam.name} ({cam.cols} x {cam.rows} px); "
                             "their lines of sight are extrapolated", True, None)]


def test_refusals_name_the_features(cut, tmp_path):
    scene_path, _, dem = cut
    col, row = np.array([1.0, np.nan, 3.0]), np.array([1.0, 2.0, np.inf])
    with pytest.raises(InputError, match=r"^2 features have missing or non-finite c/r values \(feature ids 11, 12")\
            as refused:
        use_case.run(use_case.ImageToGroundRequest(scene_path, col, row, np.array([10, 11, 12]), ("c", "r")))
    assert refused.value.parameter == use_case.POINTS
    # far beyond the image's end the lines of sight leave the DEM (it covers the cut with a margin)
    scene = load_scene(scene_path)
    with pytest.raises(InputError, match=r"^DEM: DEM .* gives no height for 1 of 2 points \(1 off its extent\): "
                                         r"their lines of sight leave it .*feature ids 8$") as refused:
        use_case.run(use_case.ImageToGroundRequest(scene_path, np.array([5.0, 5.0]),
                                                   np.array([5.0, 50 * scene.cameras[0].rows]), np.array([7, 8]),
                                                   terrain=Terrain(dem)))
    assert refused.value.parameter == "dem"
