"""core.runs.scenes: a block's scenes named as their observations name them, read once, with the
refusals of two scenes of one name naming SCENES."""
import pytest

from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.runs import scenes


def test_names_of_scene_files(tmp_path):
    paths = [tmp_path / "a" / "onboard_scene.json", tmp_path / "IMG_PHR_1_RPC.TXT", tmp_path / "b" / "scene.xml"]
    assert scenes.block_scene_names(paths) == ["a", "IMG_PHR_1", "scene"]


def test_two_scenes_of_one_name_are_refused(tmp_path):
    with pytest.raises(InputError, match="both named 'a'") as refused:
        scenes.block_scene_names([tmp_path / "a" / "true_scene.json", tmp_path / "x" / "a.json"])
    assert refused.value.parameter == scenes.SCENES
    with pytest.raises(InputError, match="listed twice"):
        scenes.block_scene_names([tmp_path / "a.json", tmp_path / "a.json"])


def test_a_block_is_read_by_name(th1, tmp_path):
    with pytest.raises(InputError, match="both named 'sim'"):  # one folder's scene JSON files
        scenes.block_from([th1["TRUE_SCENE"], th1["ONBOARD_SCENE"]])
    paths = []
    for name in ("true", "onboard"):
        paths.append(tmp_path / f"{name}.json")
        paths[-1].write_text(open(th1[f"{name.upper()}_SCENE"]).read())
    block, lines = scenes.block_from(paths)
    assert list(block.files) == ["true", "onboard"] and block.files["true"] == str(paths[0])
    assert [len(s.cameras) for s in block.scenes.values()] == [3, 3]
    assert all(line.parameter in (None, scenes.SCENES) for line in lines)
    with pytest.raises(InputError, match="no such file") as refused:
        scenes.block_from([th1["TRUE_SCENE"], str(tmp_path / "none.json")])
    assert refused.value.parameter == scenes.SCENES
    scene, _ = scenes.read_scene(th1["TRUE_SCENE"])
    assert [c.name for c in scene.cameras] == ["NAD", "FWD", "BWD"]
