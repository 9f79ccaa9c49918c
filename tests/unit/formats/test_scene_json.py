"""Scene JSON round trip and the reader dispatcher's errors on bad files."""
import json

import numpy as np
import pytest

from pushbroom_adjust.core.errors import MetadataError
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.formats.scene_json import save_scene, scene_to_dict
from tests.support.tiny_scene import tiny_scene


def test_scene_json_round_trip_keeps_geometry(tmp_path):
    scene = tiny_scene()
    save_scene(scene, tmp_path / "s.json")
    back = load_scene(tmp_path / "s.json")
    assert back.aberration and not back.refraction and back.info["sensor"] == "test"
    col, row = np.array([10.5, 500.5, 999.0]), np.array([0.5, 1000.0, 1999.5])
    assert np.abs(back.image_to_ground(col, row, 50.0) - scene.image_to_ground(col, row, 50.0)).max() < 1e-9
    written, read = scene_to_dict(scene), scene_to_dict(back)
    assert read["info"].pop("source").endswith("s.json")
    assert read == written
    assert not (tmp_path / "s.json.part").exists()


@pytest.mark.parametrize("content, message", [
    ('{"format": "pushbroom-scene", "version": 1, "epoch": "2020"', "invalid JSON"),
    ('{"format": "something-else"}', "not a Pushbroom Adjust scene"),
    ('{"format": "pushbroom-scene", "version": 99}', "newer than this plugin"),
    ('{"format": "pushbroom-scene", "version": 1, "epoch": "2020-01-01T00:00:00Z", "cameras": []}',
     "platform: required field is missing"),
    ("GIF89a binary junk", "neither scene JSON nor XML"),
    ("<?xml version='1.0'?><Dimap_Document><Metadata_Identification>", "not well-formed XML"),
    ("<?xml version='1.0'?><kml></kml>", "unrecognised XML metadata"),
    ("[" * 100_000, "nested far more deeply than a scene file"),
])
def test_bad_scene_files_get_clear_errors(tmp_path, content, message):
    path = tmp_path / "scene.txt"
    path.write_text(content)
    with pytest.raises(MetadataError, match=message) as err:
        load_scene(path)
    assert "scene.txt" in str(err.value)


def test_missing_file_is_named(tmp_path):
    with pytest.raises(MetadataError, match="nothere.json: no such file"):
        load_scene(tmp_path / "nothere.json")


def test_ground_to_image_rejects_nan_and_names_cameras(tmp_path):
    scene = tiny_scene()
    from pushbroom_adjust.core.errors import InputError
    with pytest.raises(InputError, match="NaN"):
        scene.ground_to_image(np.array([[np.nan, 0.0, 0.0]]))
    with pytest.raises(InputError, match="NaN"):
        scene.image_to_ground(np.array([np.nan]), np.array([1.0]), 0.0)
    with pytest.raises(InputError, match="cameras: PAN"):
        scene.camera_index("FWD")
    json.dumps(scene_to_dict(scene))  # everything in a scene is JSON-serialisable
