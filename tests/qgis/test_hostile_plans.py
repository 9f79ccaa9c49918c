"""Hostile inputs to the per-camera trajectory setting of bundleadjust (CAMERA_TRAJECTORY, Zhang
et al. 2024 Plans A-D) and to the per-camera corrections of a scene JSON: refused by name with
nothing written; a single-camera scene with per_camera is legitimate and adjusts as shared."""
import json
from pathlib import Path

import numpy as np
import pytest

import processing

from tests.support.hostile import assert_refused


@pytest.fixture(scope="module")
def gcps(simulated, tmp_path_factory) -> str:
    out = tmp_path_factory.mktemp("plans") / "gcps.gpkg"
    processing.run("pushbroom:importgcps", {
        "SCENE": simulated["ONBOARD_SCENE"], "INPUT_FILE": str(Path(simulated["OUTPUT_FOLDER"]) / "gcps.csv"),
        "Z_FIELD": "h", "Z_DATUM": "ellipsoid", "ROLE_FIELD": "role", "CAMERA_FIELD": "camera", "OUTPUT": str(out)})
    return str(out)


def _params(scene, gcps, folder: Path, **extra) -> dict:
    return {"SCENE": scene, "GCPS": gcps, "POSITION_ORDER": 0, "OUTPUT_SCENE": str(folder / "adjusted.json"), **extra}


@pytest.mark.parametrize("value, expected", [
    ("1", "option number"),                # an option number
    ("PER_CAMERA", "names are lower case"),  # the right name in capitals
    ("each", "not a value of this parameter"),  # no such value
])
def test_camera_trajectory_values_refused(simulated, gcps, tmp_path, value, expected):
    assert_refused("pushbroom:bundleadjust", _params(simulated["ONBOARD_SCENE"], gcps, tmp_path,
                                                     CAMERA_TRAJECTORY=value),
                   "CAMERA_TRAJECTORY", expected, watch=[tmp_path, gcps, simulated["ONBOARD_SCENE"]])


@pytest.mark.parametrize("corrections, expected", [
    ({"PAN": {}}, "platform.camera_corrections.PAN: names no camera of this scene (cameras: HRC)"),
    ({"HRC": [1, 2]}, "platform.camera_corrections.HRC: must be an object"),
    ([1, 2], "platform.camera_corrections: must be an object"),
])
def test_scene_with_bad_camera_corrections_refused(simulated, gcps, tmp_path, corrections, expected):
    d = json.loads(Path(simulated["ONBOARD_SCENE"]).read_text())
    d["platform"]["camera_corrections"] = corrections
    scene = tmp_path / "input" / "scene.json"
    scene.parent.mkdir()
    scene.write_text(json.dumps(d))
    assert_refused("pushbroom:bundleadjust", _params(str(scene), gcps, tmp_path), "SCENE", expected,
                   watch=[tmp_path, gcps])


def test_per_camera_on_a_single_camera_scene_adjusts_as_shared(simulated, gcps, tmp_path):
    """Legitimate: one camera, per_camera: the same corrections as shared, on the platform."""
    out = {}
    for mode in ("shared", "per_camera"):
        folder = tmp_path / mode
        folder.mkdir()
        processing.run("pushbroom:bundleadjust", _params(simulated["ONBOARD_SCENE"], gcps, folder,
                                                         CAMERA_TRAJECTORY=mode))
        out[mode] = json.loads((folder / "adjusted.json").read_text())["platform"]
    assert "camera_corrections" not in out["per_camera"]
    for block in ("position", "attitude"):
        np.testing.assert_allclose(out["per_camera"]["correction"][block]["coefficients"],
                                   out["shared"]["correction"][block]["coefficients"], rtol=1e-9, atol=1e-15)
