"""Hostile tie-point input to pushbroom:bundleadjust (TIE_POINTS, OUTPUT_TIE_POINTS, GCPS left out):
each case one bad input, refused with a message naming the parameter and what is wrong while the
inputs and the output folder stay unchanged — or, where the input is legitimate, adjusted with a
warning."""
from dataclasses import replace

import numpy as np
import pytest
from osgeo import gdal

import processing
from pushbroom_adjust.core.observations import tiepoints

from tests.support.hostile import assert_refused, assert_refused_cli
from tests.support.processing import RecordingFeedback

ALG = "pushbroom:bundleadjust"


@pytest.fixture(scope="module")
def block(three_line, tmp_path_factory):
    """The TH-1 fixture's GCP layer (10 control points in three cameras) and tie-point layer
    (40 points), imported against its onboard scene; the checked TieTable."""
    d = tmp_path_factory.mktemp("hostile_ties")
    scene = three_line["ONBOARD_SCENE"]
    gcps = processing.run("pushbroom:importgcps", {
        "SCENE": scene, "INPUT_FILE": three_line["GCPS"], "Z_FIELD": "h", "Z_DATUM": "ellipsoid",
        "ROLE_FIELD": "role", "CAMERA_FIELD": "camera", "SIGMA_PX": 0.3, "OUTPUT": str(d / "gcps.gpkg")})["OUTPUT"]
    ties = processing.run("pushbroom:importtiepoints", {
        "SCENE": scene, "INPUT_FILE": three_line["TIE_POINTS"], "CAMERA_FIELD": "camera", "SIGMA_PX": 0.3,
        "OUTPUT": str(d / "ties.gpkg")})["OUTPUT"]
    return {"scene": scene, "gcps": gcps, "ties": ties, "table": tiepoints.read_gpkg(ties), "dir": d}


def _layer(block, tmp_path, table) -> str:
    """``table`` written as a tie-point GeoPackage beside the test (no checks on the way)."""
    path = tmp_path / "bad_ties.gpkg"
    tiepoints.write_gpkg(table, path)
    return str(path)


def _other_camera(t):
    return replace(t, camera=np.where(t.camera == "FWD", "PAN", t.camera))


def _duplicate(t):
    return t.select(np.r_[np.arange(len(t)), 0])


def _corner(t):
    return replace(t, col=t.col / 20.0, row=t.row / 20.0)


def _outside(t):
    return replace(t, col=np.where(t.id == t.id[0], 99999.0, t.col))


def _gcp_ids(t):
    return replace(t, id=np.where(t.id == t.id[0], "G1", t.id))


# Each case: (edit of the imported tie table, extra parameters, texts in the message).
CASES = {
    "another scene's cameras": (_other_camera, {}, ["TIE_POINTS", "camera 'PAN'", "NAD, FWD, BWD"]),
    "duplicate observations": (_duplicate, {}, ["TIE_POINTS", "more than once"]),
    "all in one image corner": (_corner, {}, ["TIE_POINTS", "one corner"]),
    "outside the image": (_outside, {}, ["TIE_POINTS", "outside their camera's image"]),
    "an id that is also a GCP's": (_gcp_ids, {}, ["TIE_POINTS", "also GCP ids", "G1"]),
    "free network without onboard data": (lambda t: t, {"GCPS": None, "POSITION_SIGMA": 0.0},
                                          ["datum defect", "with 0 control point(s)", "POSITION_SIGMA",
                                           "ATTITUDE_SIGMA"]),
    "0 GCPs, positions but no attitude": (lambda t: t, {"GCPS": None},
                                          ["datum defect", "roll (rotation about the flight line)",
                                           "ATTITUDE_SIGMA"]),
}


@pytest.mark.parametrize("case", list(CASES))
def test_bad_tie_points_are_refused(block, tmp_path, case):
    edit, extra, texts = CASES[case]
    ties = _layer(block, tmp_path, edit(block["table"]))
    out = tmp_path / "out"
    out.mkdir()
    params = {"SCENE": block["scene"], "GCPS": block["gcps"], "TIE_POINTS": ties,
              "OUTPUT_SCENE": str(out / "a.json"), "OUTPUT_TIE_POINTS": str(out / "t.gpkg"), **extra}
    params = {k: v for k, v in params.items() if v is not None}
    message = assert_refused(ALG, params, *texts, watch=[ties, block["gcps"], out])
    assert "singular" not in message.lower()


def test_an_empty_tie_layer_is_refused(block, tmp_path):
    ties = _layer(block, tmp_path, block["table"].select(np.zeros(len(block["table"]), bool)))
    assert_refused(ALG, {"SCENE": block["scene"], "GCPS": block["gcps"], "TIE_POINTS": ties,
                         "OUTPUT_SCENE": str(tmp_path / "a.json")}, "TIE_POINTS", "holds no tie points",
                   watch=[tmp_path])


def test_a_raster_as_tie_points_is_refused(block, tmp_path):
    raster = tmp_path / "image.tif"
    gdal.GetDriverByName("GTiff").Create(str(raster), 10, 10, 1).FlushCache()
    assert_refused(ALG, {"SCENE": block["scene"], "GCPS": block["gcps"], "TIE_POINTS": str(raster),
                         "OUTPUT_SCENE": str(tmp_path / "a.json")}, "TIE_POINTS", watch=[tmp_path])


def test_a_layer_without_the_tie_fields_is_refused(block, tmp_path):
    table = tmp_path / "table.csv"
    table.write_text("id,camera,x,y\nT1,NAD,1,2\n")
    assert_refused(ALG, {"SCENE": block["scene"], "GCPS": block["gcps"], "TIE_POINTS": str(table),
                         "OUTPUT_SCENE": str(tmp_path / "a.json")}, "TIE_POINTS",
                   "table.csv: no column 'col' (columns: id, camera, x, y)", watch=[tmp_path])  # read as CSV


def test_the_output_must_not_replace_the_tie_points(block, tmp_path):
    assert_refused(ALG, {"SCENE": block["scene"], "GCPS": block["gcps"], "TIE_POINTS": block["ties"],
                         "OUTPUT_SCENE": str(tmp_path / "a.json"), "OUTPUT_TIE_POINTS": block["ties"]},
                   "OUTPUT_TIE_POINTS", "TIE_POINTS", watch=[block["dir"], tmp_path])


def test_adjusted_tie_points_need_tie_points(block, tmp_path):
    assert_refused(ALG, {"SCENE": block["scene"], "GCPS": block["gcps"], "OUTPUT_SCENE": str(tmp_path / "a.json"),
                         "OUTPUT_TIE_POINTS": str(tmp_path / "t.gpkg")}, "OUTPUT_TIE_POINTS", "need TIE_POINTS",
                   watch=[tmp_path])


def test_neither_gcps_nor_tie_points(block, tmp_path):
    assert_refused(ALG, {"SCENE": block["scene"], "OUTPUT_SCENE": str(tmp_path / "a.json")},
                   "GCPS: no GCP layer given", "TIE_POINTS", watch=[tmp_path])


def test_gcp_outputs_without_gcps(block, tmp_path):
    assert_refused(ALG, {"SCENE": block["scene"], "TIE_POINTS": block["ties"], "ATTITUDE_SIGMA": 10.0,
                         "OUTPUT_SCENE": str(tmp_path / "a.json"), "OUTPUT_GCPS": str(tmp_path / "g.gpkg")},
                   "OUTPUT_GCPS", "no GCPS given", watch=[tmp_path])


def test_one_camera_points_only_are_left_out_with_a_warning(block, tmp_path):
    """Legitimate but useless: every tie point in the nadir camera only. The GCPs adjust the
    block; the warning names the points left out."""
    t = block["table"]
    ties = _layer(block, tmp_path, t.select(t.camera == "NAD"))
    log = RecordingFeedback()
    result = processing.run(ALG, {"SCENE": block["scene"], "GCPS": block["gcps"], "TIE_POINTS": ties,
                                  "OUTPUT_SCENE": str(tmp_path / "a.json")}, feedback=log)
    assert result["OUTPUT_SCENE"]
    assert any("40 tie point(s) seen in one camera only" in w for w in log.warnings), log.warnings
    assert any("none of the 40 tie observations entered the adjustment" in w for w in log.warnings), log.warnings


def test_tie_points_checked_against_another_scene_file_warn(block, tmp_path):
    """Legitimate (e.g. re-adjusting an adjusted scene): the layer's scene metadata names another
    file; the run goes on and says so."""
    ties = _layer(block, tmp_path, replace(block["table"], scene_path="/elsewhere/other_scene.json"))
    log = RecordingFeedback()
    processing.run(ALG, {"SCENE": block["scene"], "GCPS": block["gcps"], "TIE_POINTS": ties,
                         "OUTPUT_SCENE": str(tmp_path / "a.json")}, feedback=log)
    assert any("checked against the scene /elsewhere/other_scene.json" in w for w in log.warnings), log.warnings


def test_free_network_from_the_command_line(block, qgis_process, tmp_path):
    assert_refused_cli(qgis_process, ALG, {"SCENE": block["scene"], "TIE_POINTS": block["ties"], "POSITION_SIGMA": 0,
                                           "OUTPUT_SCENE": str(tmp_path / "a.json")},
                       "datum defect", "POSITION_SIGMA", watch=[block["dir"], tmp_path])
