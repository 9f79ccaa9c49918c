"""Hostile inputs of issue 28 (harness: tests/support/hostile.py): a camera column naming another camera
than a single-camera scene's, a GCP file whose rows name no scene of the block (or a column of cameras
or numbers given as SCENE_FIELD), SCENE and SCENES given together, an empty layer, GCPs that are all
check points. Each is a refusal naming the parameter and what was expected, or a correct result that
the log explains; the files given stay as they were."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from osgeo import ogr, osr

import processing
from pushbroom_adjust.core.observations import gcps as gcp_io
from tests.support.hostile import LogFeedback, assert_refused
from tests.support.tristereo_block import simulate_tristereo

IMPORT = {"Z_FIELD": "h", "Z_DATUM": "ellipsoid"}


@pytest.fixture(scope="module")
def rpc_product(simulated, tmp_path_factory) -> Path:
    """The simulated CBERS-02B scene's onboard model as an RPC product, base_RPC.TXT (one camera, 'base')."""
    out = tmp_path_factory.mktemp("rpc") / "base_RPC.TXT"
    processing.run("pushbroom:exportrpc", {"SCENE": simulated["ONBOARD_SCENE"], "OUTPUT": str(out)})
    return out


def test_a_single_camera_scene_takes_every_row_of_another_camera_and_says_so(simulated, rpc_product, tmp_path):
    """The simulator's gcps.csv names camera HRC; the RPC product's one camera is 'base': every row is
    its, the log says so, and each a-priori residual is the rigorous scene's (the RPC reproduces it)."""
    log = LogFeedback()
    out = processing.run("pushbroom:importgcps", {"SCENE": str(rpc_product), "INPUT_FILE": simulated["GCPS"], **IMPORT,
                                                  "OUTPUT": str(tmp_path / "rpc.gpkg")}, feedback=log)
    rows = len(Path(simulated["GCPS"]).read_text().splitlines()) - 1
    assert f"the camera column names camera 'HRC' for the points, but the scene has one camera, 'base': all {rows} " \
           "point(s) are taken as measured in it" in log.warnings, log.lines
    table = gcp_io.read_gpkg(out["OUTPUT"])
    assert len(table) == rows and set(table.camera) == {"base"}
    rigorous = gcp_io.read_gpkg(processing.run("pushbroom:importgcps", {
        "SCENE": simulated["ONBOARD_SCENE"], "INPUT_FILE": simulated["GCPS"], **IMPORT,
        "OUTPUT": str(tmp_path / "rigorous.gpkg")})["OUTPUT"])
    assert np.max(np.abs(table.residuals.px - rigorous.residuals.px)) < 0.05  # the RPC's fit error


def test_rows_naming_several_other_cameras_are_refused(three_line, rpc_product, tmp_path):
    """NAD, FWD and BWD rows against one camera: which are its cannot be told."""
    assert_refused("pushbroom:importgcps", {"SCENE": str(rpc_product), "INPUT_FILE": three_line["GCPS"], **IMPORT,
                                            "OUTPUT": str(tmp_path / "g.gpkg")}, "is not in the scene (cameras: base)",
                   watch=[Path(three_line["GCPS"]).parent, rpc_product.parent])


@pytest.fixture(scope="module")
def block(provider, tmp_path_factory) -> dict:
    return simulate_tristereo(tmp_path_factory.mktemp("block"), n_gcps=12)


def _without_scene_column(block, folder: Path) -> Path:
    lines = Path(block["GCPS"]).read_text().splitlines()
    header = lines[0].split(",")
    keep = [k for k, name in enumerate(header) if name != "scene"]
    path = folder / "no_scene.csv"
    path.write_text("\n".join(",".join(line.split(",")[k] for k in keep) for line in lines) + "\n")
    return path


@pytest.mark.parametrize("field, says", [
    ("", r"point(s) G"),
    ("camera", "scene(s) NAD of point(s) G"),
    ("col", "of point(s) G"),
], ids=["no scene column", "a column of cameras", "a column of numbers"])
def test_rows_naming_no_scene_of_the_block_are_refused_listing_its_scenes(block, tmp_path, field, says):
    csv = _without_scene_column(block, tmp_path) if not field else Path(block["GCPS"])
    message = assert_refused("pushbroom:importgcps", {"SCENES": list(block["SCENES"]), "INPUT_FILE": str(csv),
                                                      "SCENE_FIELD": field, **IMPORT,
                                                      "OUTPUT": str(tmp_path / "gcps.gpkg")},
                             f"SCENE_FIELD: {csv}: ", says, "(nad, fwd, bwd)", watch=[tmp_path, Path(block["GCPS"])])
    assert "more than once" not in message
    assert ("name no scene; in a block of 3 scenes" if not field else "are not scenes of the block") in message


@pytest.mark.parametrize("alg, params, does", [
    ("importgcps", {"OUTPUT": "TEMPORARY_OUTPUT", **IMPORT},
     "give SCENE to check every point against one scene, or SCENES to check each row against the scene of the "
     "block it names (SCENE_FIELD), not both"),
    ("bundleadjust", {"OUTPUT_FOLDER": "TEMPORARY_OUTPUT"},
     "give SCENE to adjust one scene (its cameras, or the scenes of one strip), or SCENES to adjust several scenes "
     "together as a block, each observation naming its scene, not both"),
])
def test_scene_and_scenes_together_are_refused_saying_what_each_does(block, alg, params, does):
    gcp_key = "INPUT_FILE" if alg == "importgcps" else "GCPS"
    message = assert_refused(f"pushbroom:{alg}", {"SCENE": block["SCENES"][0], "SCENES": list(block["SCENES"]),
                                                  gcp_key: block["GCPS"], **params},
                             "SCENE and SCENES are both given: " + does)
    assert "tie point" not in message


def _empty_layer(path: Path, geometry=ogr.wkbPoint) -> str:
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(4326)
    ds = ogr.GetDriverByName("GPKG").CreateDataSource(str(path))
    layer = ds.CreateLayer("nothing", srs if geometry != ogr.wkbNone else None, geometry)
    layer.CreateField(ogr.FieldDefn("id", ogr.OFTString))
    ds = None
    return f"{path}|layername=nothing"


@pytest.mark.parametrize("geometry", [ogr.wkbPoint, ogr.wkbNone], ids=["points", "a table"])
@pytest.mark.parametrize("alg", ["groundtoimage", "imagetoground", "importgcps", "importtiepoints"])
def test_an_empty_layer_is_called_empty_naming_it(simulated, tmp_path, alg, geometry):
    layer = _empty_layer(tmp_path / "empty.gpkg", geometry)
    params = {"SCENE": simulated["ONBOARD_SCENE"], "INPUT": layer, "OUTPUT": str(tmp_path / "out.gpkg")}
    message = assert_refused(f"pushbroom:{alg}", params, "INPUT: the layer 'empty' is empty (it has no features)",
                             watch=[tmp_path / "empty.gpkg"])
    assert "NoGeometry" not in message


def test_a_table_given_as_points_is_called_a_table(simulated, tmp_path):
    path = tmp_path / "table.csv"
    path.write_text("id,x\n1,2\n")
    assert_refused("pushbroom:groundtoimage", {"SCENE": simulated["ONBOARD_SCENE"], "INPUT": str(path),
                                               "OUTPUT": str(tmp_path / "out.gpkg")},
                   "INPUT: the layer 'table' has no geometries (a table); a point layer is needed", watch=[path])


def test_gcps_that_are_all_check_points_are_refused_saying_so(simulated, tmp_path):
    lines = Path(simulated["GCPS"]).read_text().splitlines()
    role = lines[0].split(",").index("role")
    checks = tmp_path / "checks.csv"
    checks.write_text("\n".join([lines[0]] + [",".join("check" if k == role else v for k, v in
                                                       enumerate(line.split(","))) for line in lines[1:]]) + "\n")
    gcps = processing.run("pushbroom:importgcps", {"SCENE": simulated["ONBOARD_SCENE"], "INPUT_FILE": str(checks),
                                                   **IMPORT, "OUTPUT": str(tmp_path / "checks.gpkg")})["OUTPUT"]
    ids = {line.split(",")[0] for line in lines[1:]}
    assert_refused("pushbroom:bundleadjust", {"SCENE": simulated["ONBOARD_SCENE"], "GCPS": gcps,
                                              "OUTPUT_SCENE": str(tmp_path / "a.json")},
                   f"GCPS: all {len(ids)} points are check points (role 'check'): check points never enter the "
                   "adjustment, so none controls it", watch=[tmp_path / "checks.gpkg"])
    assert not (tmp_path / "a.json").exists()
    assert json.loads(Path(simulated["ONBOARD_SCENE"]).read_text())  # the scene is untouched (read only)
