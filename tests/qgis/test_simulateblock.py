"""pushbroom:simulateblock in QGIS and on the command line: a block of independent scenes written as
the algorithm's outputs say, each scene loadable, observations naming their scene, the images
matching as one ground; a layout that is not one of the names refused."""
import numpy as np
import pytest
from qgis.core import QgsProcessingException

from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.measure.matching import MatchSettings
from pushbroom_adjust.core.measure.tiematching import View, match_block_tiepoints
from tests.support.csvrows import read_rows
from tests.support.qgis_process import run_json


@pytest.fixture(scope="module")
def block(provider, tmp_path_factory) -> dict:
    import processing
    return processing.run("pushbroom:simulateblock", {
        "PRESET": "th1_tlc", "LAYOUT": "tristereo_and_other_date", "IMAGE_SIZE": 600, "RENDER": True,
        "SEED": 3, "N_GCPS": 20, "N_TIE_POINTS": 40, "OUTPUT_FOLDER": str(tmp_path_factory.mktemp("block"))})


def test_the_block_holds_four_scenes_and_their_observations(block):
    assert len(block["SCENES"]) == len(block["TRUE_SCENES"]) == len(block["IMAGES"]) == 4
    scenes = [load_scene(path) for path in block["SCENES"]]
    assert block["SCENES"][3].endswith("date2_RPC.TXT") and type(scenes[3]).__name__ == "RpcScene"
    ties = read_rows(block["TIE_POINTS"])
    by_scene = {}
    for r in ties:
        by_scene.setdefault(r["scene"], set()).add(r["id"])
    assert set(by_scene) == {"nad", "fwd", "bwd", "date2"}
    # a tie point is one ground point: its id is seen in two scenes or more
    seen = [sum(i in ids for ids in by_scene.values()) for i in {r["id"] for r in ties}]
    assert min(seen) >= 2
    assert {r["scene"] for r in read_rows(block["GCPS"])} <= set(by_scene)


def test_the_rendered_scenes_tie_through_their_onboard_models(block):
    """Tie points matched between the nadir scene and the others (the RPC product included) from
    the algorithm's outputs alone (measured: 200-290 per scene of 324 grid points)."""
    views = [View(name, load_scene(scene), 0, image) for name, scene, image in
             zip(("nad", "fwd", "bwd", "date2"), block["SCENES"], block["IMAGES"])]
    table, _ = match_block_tiepoints(views, Dem(block["DEM"], "geoid"), MatchSettings(spacing=30, search=400.0))
    for name in ("fwd", "bwd", "date2"):
        assert np.sum(table.scene == name) > 150


def test_simulateblock_from_the_command_line(qgis_process, tmp_path):
    out = run_json(qgis_process, "pushbroom:simulateblock", PRESET="th1_tlc", LAYOUT="stereo_pair", IMAGE_SIZE=500,
                   N_GCPS=10, N_TIE_POINTS=10, OUTPUT_FOLDER=tmp_path / "pair")
    assert [p.split("/")[-2] for p in out["SCENES"]] == ["fwd", "bwd"] and not out["IMAGES"]


def test_a_layout_not_among_the_names_is_refused(provider, tmp_path):
    import processing
    with pytest.raises(QgsProcessingException, match="LAYOUT"):
        processing.run("pushbroom:simulateblock", {"LAYOUT": "quad-stereo", "OUTPUT_FOLDER": str(tmp_path / "x")})
    assert not (tmp_path / "x").exists()


def test_a_region_without_images_from_processing(provider, tmp_path):
    """LAYOUT rpc_region: 2 strips x 3 RPC products (TH-1 cut to 500 px), 200 tie observations each."""
    import processing
    out = processing.run("pushbroom:simulateblock", {
        "PRESET": "th1_tlc", "LAYOUT": "rpc_region", "IMAGE_SIZE": 500, "STRIPS": 2, "PRODUCTS_PER_STRIP": 3,
        "SIDE_LAP": 0.3, "FORWARD_OVERLAP": 0.2, "TIES_PER_PRODUCT": 200, "N_GCPS": 12, "N_TIE_POINTS": 0,
        "OUTPUT_FOLDER": str(tmp_path / "region")})
    assert [p.split("/")[-1] for p in out["SCENES"]] == [f"s{i}p{j}_RPC.TXT" for i in (1, 2) for j in (1, 2, 3)]
    assert type(load_scene(out["SCENES"][0])).__name__ == "RpcScene" and not out["IMAGES"]
    ties = read_rows(out["TIE_POINTS"])
    assert abs(len(ties) / 6 - 200) < 3 and {r["scene"] for r in ties} == {f"s{i}p{j}" for i in (1, 2) for j in (1, 2, 3)}
    assert len({r["id"] for r in read_rows(out["GCPS"])}) == 12


def test_a_rendered_region_is_refused_without_images_naming_render(provider, tmp_path):
    import processing
    with pytest.raises(QgsProcessingException, match="RENDER"):
        processing.run("pushbroom:simulateblock", {"PRESET": "th1_tlc", "LAYOUT": "rpc_region", "IMAGE_SIZE": 500,
                                                   "RENDER": True, "OUTPUT_FOLDER": str(tmp_path / "x")})
    assert not (tmp_path / "x").exists()
