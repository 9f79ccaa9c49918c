"""simulation.runs: the simulate use cases return every file they wrote under the provider's output
names, and refuse a cut below the smallest one and a folder holding a user's file, naming them."""
import json

import pytest

from pushbroom_adjust.core.errors import PushbroomError
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.simulation import runs
from pushbroom_adjust.simulation.measurements import GcpSettings


def test_a_scene_s_files(tmp_path):
    folder = tmp_path / "sim"
    result = runs.run_scene(runs.SimulateSceneRequest(str(folder), "th1_tlc", seed=2, gcps=GcpSettings(
        n_gcps=12, image_noise=0.0), image_size=500))
    files = result.files
    assert files[runs.OUTPUT_FOLDER] == str(folder) and files[runs.IMAGES] == [] and files[runs.IMAGE] is None
    assert files[runs.TIE_POINTS] is None and files[runs.LINES] is None and files[runs.REFERENCE] is None
    assert load_scene(files[runs.TRUE_SCENE]).cameras[0].cols == 500
    assert sum(1 for _ in open(files[runs.GCPS])) - 1 >= 12
    assert json.load(open(files[runs.MANIFEST]))["seed"] == 2
    assert [line.text for line in result.lines] == [
        f"simulated th1_tlc_500x500 into {folder}: onboard_scene.json, true_scene.json, gcps.csv, dem.tif"]


def test_refusals_name_their_input(tmp_path):
    with pytest.raises(PushbroomError) as refused:
        runs.run_scene(runs.SimulateSceneRequest(str(tmp_path / "a"), "th1_tlc", image_size=20))
    assert refused.value.parameter == runs.IMAGE_SIZE
    (tmp_path / "b").mkdir()
    (tmp_path / "b" / "gcps.csv").write_text("mine\n")
    with pytest.raises(PushbroomError, match="gcps.csv") as refused:
        runs.run_scene(runs.SimulateSceneRequest(str(tmp_path / "b"), "th1_tlc", image_size=500))
    assert refused.value.parameter == runs.FOLDER
    assert (tmp_path / "b" / "gcps.csv").read_text() == "mine\n"


def test_a_block_names_each_scene_s_product(tmp_path):
    result = runs.run_block(runs.SimulateBlockRequest(str(tmp_path / "blk"), "th1_tlc", "stereo_pair",
                                                      n_gcps=10, n_tie_points=10, image_size=500))
    files = result.files
    assert len(files[runs.SCENES]) == len(files[runs.TRUE_SCENES]) == len(result.lines) == 2
    assert all(load_scene(path).cameras[0].cols == 500 for path in files[runs.SCENES])
    assert [line.text for line in result.lines] == [f"scene {p.split('/')[-2]}: {p}" for p in files[runs.SCENES]]
