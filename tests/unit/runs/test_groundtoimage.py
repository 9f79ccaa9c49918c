"""core.runs.groundtoimage: the use case behind pushbroom:groundtoimage, on a cut of a simulated CBERS-02B
scene: ground points made from known image points (in UTM, in 3D WGS84 with Z, on a constant height)
project back onto them; Z values without a datum and NaN coordinates are refused, naming the input."""
import numpy as np
import pytest
from pyproj import CRS, Transformer

from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.geodesy import ecef_to_geodetic
from pushbroom_adjust.core.runs import groundtoimage as use_case
from pushbroom_adjust.core.runs.base import Terrain
from tests.support.ortho_compare import saved_cut


@pytest.fixture(scope="module")
def cut(tmp_path_factory):
    return saved_cut(tmp_path_factory.mktemp("runs_groundtoimage"), seed=3, rows=400)


@pytest.fixture(scope="module")
def truth(cut):
    """(scene path, col, row, lon, lat) of image points and their ground at 450 m ellipsoidal."""
    scene = load_scene(cut[0])
    cam = scene.cameras[0]
    col, row = (a.ravel() for a in np.meshgrid(np.linspace(5, cam.cols - 5, 6), np.linspace(5, cam.rows - 5, 4)))
    lon, lat, _ = ecef_to_geodetic(scene.image_to_ground(col, row, 450.0, 0))
    return cut[0], col, row, lon, lat


def test_points_in_utm_on_a_constant_height_project_back(truth):
    scene_path, col, row, lon, lat = truth
    utm = CRS.from_epsg(32650)
    x, y = Transformer.from_crs(CRS.from_epsg(4326), utm, always_xy=True).transform(lon, lat)
    result = use_case.run(use_case.GroundToImageRequest(scene_path, x, y, np.full(x.shape, np.nan), np.arange(x.size),
                                                        utm, "EPSG:32650", terrain=Terrain(height=450.0)))
    f = result.figures
    assert np.hypot(f["col"] - col, f["row"] - row).max() < 1e-3 and f["inside"].all() and result.lines == []


def test_z_values_in_a_3d_crs_are_ellipsoidal_heights(truth):
    scene_path, col, row, lon, lat = truth
    z = np.full(lon.shape, 450.0)
    result = use_case.run(use_case.GroundToImageRequest(scene_path, lon, lat, z, np.arange(z.size),
                                                        CRS.from_epsg(4979), "EPSG:4979", terrain=Terrain(height=0.0)))
    assert np.hypot(result.figures["col"] - col, result.figures["row"] - row).max() < 1e-3
    # without USE_Z the terrain's 0 m apply: the points move across the image by the parallax of 450 m
    flat = use_case.run(use_case.GroundToImageRequest(scene_path, lon, lat, z, np.arange(z.size), CRS.from_epsg(4979),
                                                      "EPSG:4979", use_z=False, terrain=Terrain(height=0.0)))
    assert np.hypot(flat.figures["col"] - col, flat.figures["row"] - row).min() > 0.01


def test_points_outside_and_refusals(truth):
    scene_path, col, row, lon, lat = truth
    wgs84 = CRS.from_epsg(4326)
    x, y = np.append(lon[:2], lon[0] + 1.0), np.append(lat[:2], lat[0])  # the last a degree east: off the image
    result = use_case.run(use_case.GroundToImageRequest(scene_path, x, y, np.full(3, np.nan), np.arange(3), wgs84,
                                                        "EPSG:4326", terrain=Terrain(height=450.0)))
    cam = load_scene(scene_path).cameras[0]
    assert result.figures["inside"].tolist() == [True, True, False]
    assert result.lines == [(f"1 of 3 points fall outside the image of camera {cam.name} ({cam.cols} x {cam.rows} "
                             "px); they are kept with in_image = 0", True, None)]
    with pytest.raises(InputError, match=r"^2 points have Z values and the layer's CRS \(EPSG:4326\) does not say") \
            as refused:
        use_case.run(use_case.GroundToImageRequest(scene_path, lon[:2], lat[:2], np.array([1.0, 2.0]), np.arange(2),
                                                   wgs84, "EPSG:4326"))
    assert refused.value.parameter == use_case.Z_DATUM
    with pytest.raises(InputError, match=r"^1 features have missing or non-finite point coordinates \(feature ids 5")\
            as refused:
        use_case.run(use_case.GroundToImageRequest(scene_path, np.array([lon[0], np.nan]), lat[:2], np.full(2, np.nan),
                                                   np.array([4, 5]), wgs84, "EPSG:4326"))
    assert refused.value.parameter == use_case.POINTS
