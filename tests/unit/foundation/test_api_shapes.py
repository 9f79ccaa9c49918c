"""The core's public functions with array arguments refuse shapes numpy would broadcast into something
else (issue 28, hostile inputs): ground points of the wrong shape, per-point arguments of different
lengths, ground points that are not ECEF metres — each an InputError naming the argument (the shared
checks core.validation.per_point and ground_points). One point of shape (3,) is documented and
projected as the point it is."""
from __future__ import annotations

import numpy as np
import pytest

from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.geodesy import ecef_to_geodetic
from pushbroom_adjust.core.model.mixedblock import MixedBlock
from pushbroom_adjust.core.model.rpcscene import RpcCamera, RpcScene
from pushbroom_adjust.core.observations import gcps, tiepoints
from pushbroom_adjust.core.observations.tables import Heights
from pushbroom_adjust.core.validation import per_point
from tests.support.rpcdata import PLEIADES, pleiades_rpc, scaled


@pytest.fixture(scope="module", params=["rigorous", "rpc", "mixed block"])
def scene(request, shared_data):
    if request.param == "rigorous":
        return load_scene(shared_data / PLEIADES)  # the Pleiades sensor model
    rpc = RpcScene(scaled(pleiades_rpc(shared_data), 16.0), RpcCamera("PAN", 2500, 2500))
    return rpc if request.param == "rpc" else MixedBlock(None, {"P": rpc}, ["P"])


def _ground(scene) -> np.ndarray:
    """Three ECEF points (3, 3) the scene images at (100, 200), (400, 500), (700, 800) px, 50 m up."""
    return scene.image_to_ground([100.0, 400.0, 700.0], [200.0, 500.0, 800.0], 50.0)


def test_one_point_of_shape_3_is_that_point(scene):
    xyz = _ground(scene)
    col, row = scene.ground_to_image(xyz[1])
    assert col.shape == row.shape == (1,)
    assert abs(col[0] - 400.0) < 1e-4 and abs(row[0] - 500.0) < 1e-4
    all_col, all_row = scene.ground_to_image(xyz)
    assert np.allclose(all_col, [100.0, 400.0, 700.0], atol=1e-4) and np.allclose(all_row, [200.0, 500.0, 800.0],
                                                                                    atol=1e-4)


@pytest.mark.parametrize("shape", [(3, 2), (2, 2), (3, 3, 1), (4,)])
def test_ground_points_of_another_shape_are_refused_naming_xyz(scene, shape):
    xyz = np.resize(_ground(scene), shape)
    with pytest.raises(InputError, match=rf"^xyz: ground points are ECEF coordinates of shape \(n, 3\).*got shape "
                                         rf"\({shape[0]}"):
        scene.ground_to_image(xyz)


def test_geodetic_coordinates_given_as_ecef_are_refused(scene):
    """A longitude, latitude and height given where ECEF metres are expected: a point near the
    Earth's centre, once projected to NaN without a word."""
    lon, lat, h = ecef_to_geodetic(_ground(scene))
    with pytest.raises(InputError, match=r"^xyz: 1 point\(s\) \(index 0\) lie within 5000 km of the Earth's centre: "
                                         r"ground points are ECEF metres"):
        scene.ground_to_image(np.array([lon[0], lat[0], h[0]]))


def test_image_points_of_different_lengths_are_refused_naming_them(scene):
    with pytest.raises(InputError, match=r"^arguments of different lengths: col 3, row 2 "):
        scene.image_to_ground([1.0, 2.0, 3.0], [1.0, 2.0], 50.0)
    with pytest.raises(InputError, match=r"^arguments of different lengths: col 2, row 2, height 3 "):
        scene.image_to_ground([1.0, 2.0], [1.0, 2.0], [50.0, 60.0, 70.0])
    with pytest.raises(InputError, match=r"^row: one value per point is expected, shape \(n,\), got \(2, 1\)"):
        scene.image_to_ground([1.0, 2.0], [[1.0], [2.0]], 50.0)
    with pytest.raises(InputError, match=r"^height: contains NaN or infinite values"):
        scene.image_to_ground([1.0, 2.0], [1.0, 2.0], [50.0, np.nan])
    # single values stand for every point
    assert scene.image_to_ground(100.0, [200.0, 300.0], 50.0).shape == (2, 3)


def test_geodetic_points_of_different_lengths_are_refused(scene):
    if isinstance(scene, MixedBlock):
        pytest.skip("a block projects ECEF points only")
    lon, lat, h = ecef_to_geodetic(_ground(scene))
    with pytest.raises(InputError, match=r"^arguments of different lengths: lon 3, lat 2, h 3 "):
        scene.ground_to_image_geodetic(lon, lat[:2], h)
    col, _ = scene.ground_to_image_geodetic(lon, lat, h[0])
    assert np.allclose(col[0], 100.0, atol=0.1)  # one height for all: 50 m, the points' own


def test_gcp_table_columns_of_different_lengths_are_refused():
    heights = Heights("constant", "ellipsoid", value=100.0)
    with pytest.raises(InputError, match=r"^arguments of different lengths: ids 2, col 3, row 1, x 2, y 2 "):
        gcps.build_table(["a", "b"], [1.0, 2.0, 3.0], [1.0], [114.0, 114.1], [34.0, 34.1], crs="EPSG:4326",
                         heights=heights)
    with pytest.raises(InputError, match=r"^arguments of different lengths: .*camera 3"):
        gcps.build_table(["a", "b"], [1.0, 2.0], [1.0, 2.0], [114.0, 114.1], [34.0, 34.1], crs="EPSG:4326",
                         heights=heights, camera=["P", "P", "P"])
    table = gcps.build_table(["a", "b"], [1.0, 2.0], 5.0, [114.0, 114.1], [34.0, 34.1], crs="EPSG:4326",
                             heights=heights)
    assert len(table) == 2 and table.row.tolist() == [5.0, 5.0]


def test_tie_table_columns_of_different_lengths_are_refused():
    with pytest.raises(InputError, match=r"^arguments of different lengths: ids 2, col 3, row 1, camera 2 "):
        tiepoints.build_table(["a", "b"], ["x", "y"], [1.0, 2.0, 3.0], [1.0])
    with pytest.raises(InputError, match=r"^arguments of different lengths: .*sigma_px 3"):
        tiepoints.build_table(["a", "b"], ["x", "y"], [1.0, 2.0], [1.0, 2.0], sigma_px=[0.5, 0.5, 0.5])


def test_per_point_repeats_single_values_and_keeps_types():
    ids, col, flag = per_point(ids=["a", "b", "c"], col=2.5, flag=np.array(True))
    assert ids.tolist() == ["a", "b", "c"] and col.tolist() == [2.5] * 3 and flag.tolist() == [True] * 3
    (only,) = per_point(value=7)
    assert only.tolist() == [7]
