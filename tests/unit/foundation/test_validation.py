"""The scene-JSON schema check, the model checks and the value checks of core.validation, and
ray intersections that never return a point behind the satellite."""
import json

import numpy as np
import pytest

from pushbroom_adjust.core.errors import InputError, MetadataError
from pushbroom_adjust.core.geodesy import geodetic_to_ecef, ray_height_intersection
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.formats.scene_json import scene_to_dict
from pushbroom_adjust.core.formats.schema import check_scene_dict
from pushbroom_adjust.core.validation import (PLAUSIBLE_HEIGHTS, check_nodata, check_surface_heights,
                             check_terrain_height, implausible_heights, implausible_image_coordinates,
                             rpc_value_problem)
from tests.support.tiny_scene import tiny_scene


@pytest.fixture()
def scene_dict() -> dict:
    return json.loads(json.dumps(scene_to_dict(tiny_scene())))


def _check(d):
    return check_scene_dict(d, "s.json")


def test_the_tiny_scene_passes_unchanged(scene_dict):
    assert _check(scene_dict) is scene_dict


@pytest.mark.parametrize("mutate, message", [
    (lambda d: d["cameras"][0].update(focal_length=-3.3), r"^s.json: cameras\[0\].focal_length: must be > 0 \(got -3.3\)$"),
    (lambda d: d["cameras"][0].update(cols=0), r"cameras\[0\].cols: must be between 1 and 1000000 \(got 0\)"),
    (lambda d: d.update(version="two"), r"version: must be a whole number \(got 'two'\)"),
    (lambda d: d["platform"]["ephemeris"].update(order=0), r"platform.ephemeris.order: must be between 2 and 9 \(got 0\)"),
    (lambda d: d["info"].update(height_range=["0", "100"]), r"info.height_range: must hold only numbers"),
    (lambda d: d["cameras"][0]["timing"].update(period=-1e-3), r"cameras\[0\].timing.period: must be > 0"),
    (lambda d: d["platform"]["ephemeris"]["times"].__setitem__(3, -20.0),
     r"platform.ephemeris.times\[3\]: must be greater than the previous value"),
    (lambda d: d["platform"]["ephemeris"]["positions"].__setitem__(2, [7.0e3, 0.0, 0.0]),
     r"platform.ephemeris.positions\[2\]: is 7000 m from the Earth's centre"),
    (lambda d: d["cameras"][0]["chips"][0].update(n_pixels=900), r"cameras\[0\].chips: detectors end at column 900"),
])
def test_schema_names_the_key_path_and_value(scene_dict, mutate, message):
    mutate(scene_dict)
    with pytest.raises(MetadataError, match=message):
        _check(scene_dict)


def test_quaternions_slightly_off_unit_are_normalised_in_a_copy(tmp_path):
    scene = tiny_scene()
    from pushbroom_adjust.core.model.trajectory import QuaternionSamples
    t = np.linspace(-20.0, 20.0, 9)
    q = np.tile([0.5 ** 0.5, 0.0, -(0.5 ** 0.5), 0.0], (9, 1))
    scene.platform.attitude = QuaternionSamples(t, q)
    d = json.loads(json.dumps(scene_to_dict(scene)))
    d["platform"]["attitude"]["quaternions"] = (q * 1.004).tolist()
    checked = _check(d)
    assert np.allclose(np.linalg.norm(checked["platform"]["attitude"]["quaternions"], axis=1), 1.0, atol=1e-15)
    assert np.allclose(np.linalg.norm(d["platform"]["attitude"]["quaternions"], axis=1), 1.004)  # input untouched
    d["platform"]["attitude"]["quaternions"][4] = (q[4] * 1.02).tolist()
    with pytest.raises(MetadataError, match=r"platform.attitude.quaternions\[4\]: must be a unit quaternion"):
        _check(d)


def test_bom_is_accepted_and_the_model_checks_run(tmp_path):
    text = json.dumps(scene_to_dict(tiny_scene()))
    (tmp_path / "bom.json").write_bytes(b"\xef\xbb\xbf" + text.encode())
    assert load_scene(tmp_path / "bom.json").cameras[0].cols == 1000
    d = json.loads(text)
    d["cameras"][0]["timing"]["t0"] = 500.0  # the image 480 s after the last ephemeris sample
    (tmp_path / "late.json").write_text(json.dumps(d))
    with pytest.raises(MetadataError, match=r"late.json: platform.ephemeris.times: samples from -20 to 20 s do not "
                                            r"cover the image lines, acquired from 500 to 502 s"):
        load_scene(tmp_path / "late.json")


def test_rays_never_meet_a_surface_behind_their_origin():
    origin = geodetic_to_ecef(10.0, 45.0, 700e3)[None]
    down = -origin / np.linalg.norm(origin)
    assert ray_height_intersection(origin, down, 0.0, newton_steps=0)[0] == pytest.approx(700e3, abs=10.0)
    # above the satellite: the surface would be met behind it (before: -300 km) or from inside
    assert np.isnan(ray_height_intersection(origin, down, 1e6, newton_steps=0)[0])
    assert np.isnan(ray_height_intersection(origin, -down, 0.0, newton_steps=0)[0])  # looking to space


def test_image_to_ground_above_the_satellite_is_nan():
    scene = tiny_scene()
    p = scene.image_to_ground(np.array([500.0]), np.array([1000.0]), np.array([1e6]))
    assert np.isnan(p).all()


def test_value_checks():
    assert check_terrain_height(8800.0, "HEIGHT") == 8800.0
    with pytest.raises(InputError, match=r"^HEIGHT: 1e\+06 m is not a terrain height \(plausible: -1000 to 9000 m"):
        check_terrain_height(1e6, "HEIGHT")
    with pytest.raises(InputError, match="HEIGHT: nan m"):
        check_terrain_height(float("nan"), "HEIGHT")
    assert implausible_heights([PLAUSIBLE_HEIGHTS[0], 0.0, np.nan, 1e308]).tolist() == [False, False, True, True]
    with pytest.raises(InputError, match="dem.tif: heights from -32768 to 1432 m"):
        check_surface_heights((-32768.0, 1432.0), "dem.tif")
    assert implausible_image_coordinates([0.0, 1e308, 5.0], [0.0, 1.0, np.inf]).tolist() == [False, True, True]


@pytest.mark.parametrize("value, dtype, ok", [
    (0, np.uint8, True), (255, np.uint8, True), (-5, np.uint8, False), (256, np.uint8, False),
    (float("nan"), np.uint8, False), (1.5, np.int16, False), (-32768, np.int16, True), (65535, np.uint16, True),
    (float("nan"), np.float32, True), (-9999.0, np.float32, True), (1e300, np.float32, False),
    (1e300, np.float64, True), (float("inf"), np.float64, False),
])
def test_nodata_fits_the_data_type(value, dtype, ok):
    if ok:
        check_nodata(value, dtype)
    else:
        with pytest.raises(InputError, match=f"nodata value .* cannot be stored in the output's data type "
                                             f"{np.dtype(dtype).name}"):
            check_nodata(value, dtype)


@pytest.mark.parametrize("field, value, problem", [
    ("lat_off", 1e300, "a plausible value lies between -90 and 90"), ("lat_off", 31.0, None),
    ("lon_off", 359.0, None), ("lon_off", -181.0, "between -180 and 360"),
    ("height_off", -12001.0, "between -12000 and 100000"), ("height_scale", -500.0, None),
    ("line_scale", 0.0, "a scale must be a non-zero number"), ("samp_scale", float("nan"), "non-zero number"),
    ("samp_off", 2e8, "between -1e+08 and 1e+08"), ("lat_scale", 91.0, "a plausible |scale| lies between 0 and 90"),
])
def test_rpc_offsets_and_scales_in_their_plausible_ranges(field, value, problem):
    """Every RPC reader (RPC text, RPB, GDAL metadata, DIMAP RFM, Maxar RPB) refuses an offset or |scale|
    no scene on the Earth has, naming the file and key with this reason."""
    found = rpc_value_problem(field, value)
    assert found is None if problem is None else problem in found
