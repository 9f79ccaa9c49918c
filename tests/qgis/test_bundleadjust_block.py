"""pushbroom:bundleadjust on a block of scenes (SCENES, issue 23), as a user runs it: a simulated
TH-1 tri-stereo (pushbroom:simulateblock: nadir, forward and backward scenes of one pass, each its
own onboard errors, 600 x 600 px) -> importgcps with SCENES (the simulator's gcps.csv as it is) ->
bundleadjust with the simulator's tie_points.csv, by processing.run, by qgis_process and inside a
graphical model; each adjusted scene checked against the simulation's true scene, the report and
the layers; bad blocks refused naming the parameter."""
import html
import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from osgeo import ogr
from qgis.core import QgsProcessingException

import processing
from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.observations import gcps as gcp_io
from tests.support.tristereo_block import ADJUST, NAMES, block_model, check_px, simulate_tristereo
from tests.support.qgis_process import run_json
from tests.support.processing import RecordingFeedback

IMPORT = {"Z_FIELD": "h", "Z_DATUM": "ellipsoid", "SIGMA_PX_FIELD": "sigma_px", "SIGMA_XY_FIELD": "sigma_xy",
          "SIGMA_Z_FIELD": "sigma_z"}


@pytest.fixture(scope="module")
def block(provider, tmp_path_factory) -> dict:
    return simulate_tristereo(tmp_path_factory.mktemp("block"), n_gcps=24)


@pytest.fixture(scope="module")
def gcp_layer(block, tmp_path_factory) -> str:
    return processing.run("pushbroom:importgcps", {
        "SCENES": list(block["SCENES"]), "INPUT_FILE": block["GCPS"], **IMPORT,
        "OUTPUT": str(tmp_path_factory.mktemp("gcps") / "gcps.gpkg")})["OUTPUT"]


def test_the_simulators_block_gcps_import_as_they_are(block, gcp_layer):
    """importgcps with SCENES: every row keeps its scene, one id is measured by camera NAD of several
    scenes, and each row's a-priori residual is its own scene's projection minus the measurement."""
    table = gcp_io.read_gpkg(gcp_layer)
    lines = Path(block["GCPS"]).read_text().splitlines()
    header = lines[0].split(",")
    rows = [dict(zip(header, line.split(","))) for line in lines[1:]]
    assert sorted(zip(table.id, table.scene)) == sorted((r["id"], r["scene"]) for r in rows)
    ids, scenes_seen = np.unique(table.id, return_counts=True)
    assert scenes_seen.max() == 3 and set(table.camera) == {"NAD"}
    for name, path in zip(NAMES, block["SCENES"]):
        mine = table.select(table.scene == name)
        col, row = load_scene(path).ground_to_image(mine.ecef(), 0)
        ok = np.isfinite(col)
        assert ok.sum() >= 5 and np.allclose(mine.residuals.col[ok], (col - mine.col)[ok], atol=1e-6), name
        assert 5.0 < np.median(mine.residuals.px) < 30.0, name  # the onboard errors, 10 px or so


def test_a_blocks_gcps_against_one_scene_say_so(block, tmp_path):
    log = RecordingFeedback()
    processing.run("pushbroom:importgcps", {"SCENE": block["SCENES"][0], "INPUT_FILE": block["GCPS"], **IMPORT,
                                            "OUTPUT": str(tmp_path / "one.gpkg")}, feedback=log)
    assert any(line.startswith("SCENE_FIELD: the rows name 3 scenes (bwd, fwd, nad): all are checked against SCENE")
               for line in log.lines), log.lines


@pytest.mark.parametrize("column, value, message", [
    ("scene", "date9", r"^SCENE_FIELD: .*bad\.csv: scene\(s\) date9 of point\(s\) G\d+ are not scenes of the block "
                       r"\(nad, fwd, bwd\)"),
    ("camera", "PAN", r"^CAMERA_FIELD: scene nad: camera 'PAN' of point\(s\) G\d+ is not in the scene \(cameras: NAD\)"),
    ("scene", "", r"^SCENE_FIELD: .*bad\.csv: point\(s\) G\d+ name no scene; in a block of 3 scenes"),
])
def test_bad_block_gcps_are_refused_naming_the_field(block, tmp_path, column, value, message):
    lines = Path(block["GCPS"]).read_text().splitlines()
    header = lines[0].split(",")
    first = next(line.split(",") for line in lines[1:] if line.endswith(",nad"))
    first[header.index(column)] = value
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join([lines[0], ",".join(first)] + [line for line in lines[1:] if not line.startswith(
        first[0] + ",")]) + "\n")
    with pytest.raises(QgsProcessingException, match=message):
        processing.run("pushbroom:importgcps", {"SCENES": list(block["SCENES"]), "INPUT_FILE": str(bad), **IMPORT,
                                                "OUTPUT": str(tmp_path / "gcps.gpkg")})


def params(block, gcp_layer, folder, **kw) -> dict:
    return {"SCENES": list(block["SCENES"]), "GCPS": gcp_layer, "TIE_POINTS": block["TIE_POINTS"], **ADJUST,
            "OUTPUT_FOLDER": str(folder), **kw}


@pytest.fixture(scope="module")
def adjusted(block, gcp_layer, tmp_path_factory):
    log = RecordingFeedback()
    folder = tmp_path_factory.mktemp("adjusted") / "out"
    result = processing.run("pushbroom:bundleadjust", params(block, gcp_layer, folder, WRITE_RPCS=True), feedback=log)
    return result, log, folder


def test_the_block_meets_the_truth(block, adjusted):
    """Measured (SEED 3; 24 ground points, 18 control and 6 check, each seen in 1-3 scenes, 48 control
    observations; 60 tie points, 170 observations; image noise 0.3 px): check RMSE through the onboard
    scenes nad 10.65, fwd 10.17, bwd 9.64 px; adjusted 0.25, 0.26, 0.20 px. What is left is mostly
    the simulated interior distortion (principal point, focal length, lens terms of 0.03-0.4 px
    each), which a trajectory-only adjustment (INTERIOR empty) does not model."""
    result, _, folder = adjusted
    assert result["ADJUSTED_SCENES"] == [str(folder / f"{n}_adjusted.json") for n in NAMES]
    before, after = check_px(block, block["SCENES"]), check_px(block, result["ADJUSTED_SCENES"])
    for name in NAMES:
        assert before[name] > 5.0 and after[name] < 0.3, (name, before[name], after[name])


def test_the_block_report(adjusted):
    """Measured: sigma0 0.80; tie RMS 8.09 px before, 0.29 px after (per scene 6.75 -> 0.36, 10.19 ->
    0.27, 6.62 -> 0.26); check observations 0.49, 0.42, 0.55 px (residuals of the measurements, noise
    0.3 px); each scene moved 52-55 m from its onboard geolocation, its onboard sigma 147-155 m."""
    result, log, folder = adjusted
    report = json.loads(Path(result["OUTPUT_REPORT_JSON"]).read_text())
    assert Path(result["OUTPUT_REPORT_JSON"]) == folder / "block_report.json"
    block = report["block"]
    assert block["scenes"] == 3 and block["tie_rmse_px"] < 0.6 < 5.0 < block["tie_rmse_before_px"]
    assert 0.6 < block["sigma0"] < 1.5 and block["check_rmse_px"] < 0.6
    assert report["datum"].startswith("datum held by the")
    for name in NAMES:
        scene = report["scenes"][name]
        assert scene["ties"]["rmse_px"] < scene["ties"]["rmse_before_px"], name
        assert scene["control"]["observations"] > 0 and scene["control"]["rmse_px"] < 0.6, name
        assert scene["check_points"]["observations"] > 0 and scene["check_points"]["rmse_px"] < 0.7, name
    page = (folder / "block_report.html").read_text()
    assert "Block of 3 scenes" in page and html.escape(report["datum"]) in page
    text = "\n".join(log.lines)
    assert "scene fwd: control" in text and "block of 3 scenes: sigma0" in text and report["datum"] in text


def test_the_block_layers_and_rpcs(block, adjusted):
    result, _, folder = adjusted
    ds = ogr.Open(str(folder / "adjusted_tie_points.gpkg"))
    layer = ds.GetLayer(0)
    rows = [(f["id"], f["scene"], f["camera"], f["rays"], f["scenes"], f["convergence_deg"], f["res_px"])
            for f in layer]
    assert {r[1] for r in rows} == set(NAMES) and {r[2] for r in rows} == {"NAD"}
    assert all(r[3] == r[4] >= 2 for r in rows)  # one camera per scene: a ray per scene
    assert min(r[5] for r in rows) > 15.0  # two of nadir, +18 and -18 degrees
    assert np.sqrt(np.mean(np.array([r[6] for r in rows]) ** 2)) < 0.6
    table = gcp_io.read_gpkg(folder / "adjusted_gcps.gpkg")
    assert set(table.scene) == set(NAMES) and set(table.camera) == {"NAD"}
    for name in NAMES:
        rpc = folder / f"{name}_RPC.TXT"
        assert rpc.is_file() and json.loads(Path(f"{rpc}.json").read_text())["check"]["rms_px"] < 0.01


def test_a_block_from_the_command_line(block, gcp_layer, qgis_process, tmp_path):
    out = run_json(qgis_process, "pushbroom:bundleadjust", **params(block, gcp_layer, tmp_path / "cli"))
    after = check_px(block, out["ADJUSTED_SCENES"])
    assert all(v < 0.3 for v in after.values()), after
    assert sorted(p.name for p in (tmp_path / "cli").iterdir()) == sorted(
        ["adjusted_gcps.gpkg", "adjusted_tie_points.gpkg", "block_report.html", "block_report.json",
         *(f"{n}_adjusted.json" for n in NAMES)])


def test_the_dialogs_temporary_outputs_of_one_scene_are_ignored(block, gcp_layer, tmp_path):
    """The dialog gives the outputs of one scene as temporary files: a block run writes its folder only."""
    temporary = {name: "TEMPORARY_OUTPUT" for name in ("OUTPUT_SCENE", "OUTPUT_REPORT", "OUTPUT_GCPS",
                                                       "OUTPUT_TIE_POINTS", "OUTPUT_RESIDUALS")}
    out = processing.run("pushbroom:bundleadjust", params(block, gcp_layer, tmp_path / "out", **temporary))
    assert all(out[name] is None for name in temporary) and len(out["ADJUSTED_SCENES"]) == 3
    assert all(Path(p).is_file() for p in out["ADJUSTED_SCENES"])


def test_an_output_that_would_replace_an_input_is_refused(block, gcp_layer, tmp_path):
    """OUTPUT_FOLDER holding the GCP layer under the name the block writes its adjusted GCPs to."""
    mine = tmp_path / "adjusted_gcps.gpkg"
    mine.write_bytes(Path(gcp_layer).read_bytes())
    before = sorted(tmp_path.iterdir())
    with pytest.raises(QgsProcessingException, match=r"^OUTPUT_FOLDER: .*adjusted_gcps.gpkg is the file of GCPS"):
        processing.run("pushbroom:bundleadjust", params(block, str(mine), tmp_path))
    assert sorted(tmp_path.iterdir()) == before


def test_a_block_inside_a_graphical_model(block, gcp_layer, tmp_path):
    model = block_model()
    valid, problems = model.validate()
    assert valid, problems
    out = processing.run(model, {"scenes": list(block["SCENES"]), "gcps": gcp_layer, "ties": block["TIE_POINTS"],
                                 "adjust:adjusted": str(tmp_path / "model")})
    assert out["adjust:adjusted"] == str(tmp_path / "model")
    after = check_px(block, [tmp_path / "model" / f"{n}_adjusted.json" for n in NAMES])
    assert all(v < 0.3 for v in after.values()), after


# --- a block with an RPC product -------------------------------------------------------------
def test_a_block_with_an_rpc_product(provider, tmp_path):
    """The tri-stereo and a scene of another date delivered as an RPC product (LAYOUT
    tristereo_and_other_date): the RPC image keeps its own image-space correction (RPC_CORRECTION,
    Grodecki & Dial 2003), its refined RPC is written beside the rigorous scenes' fitted ones.
    Measured: check RMSE onboard nad 10.65, fwd 10.17, bwd 9.64, date2 (the vendor RPC) 6.69 px;
    adjusted 0.21, 0.23, 0.20, 0.18 px."""
    names = (*NAMES, "date2")
    block = processing.run("pushbroom:simulateblock", {
        "PRESET": "th1_tlc", "LAYOUT": "tristereo_and_other_date", "IMAGE_SIZE": 600, "RENDER": False, "SEED": 3,
        "N_GCPS": 24, "N_TIE_POINTS": 60, "CHECK_FRACTION": 0.25, "OUTPUT_FOLDER": str(tmp_path / "block")})
    assert Path(block["SCENES"][3]).name == "date2_RPC.TXT"
    gcps = processing.run("pushbroom:importgcps", {"SCENES": list(block["SCENES"]), "INPUT_FILE": block["GCPS"],
                                                   **IMPORT, "OUTPUT": str(tmp_path / "gcps.gpkg")})["OUTPUT"]
    log = RecordingFeedback()
    out = processing.run("pushbroom:bundleadjust", params(block, gcps, tmp_path / "out", WRITE_RPCS=True),
                         feedback=log)
    before, after = check_px(block, block["SCENES"], names), check_px(block, out["ADJUSTED_SCENES"], names)
    for name in names:
        assert before[name] > 5.0 and after[name] < 0.4, (name, before[name], after[name])
    report = json.loads(Path(out["OUTPUT_REPORT_JSON"]).read_text())
    assert report["scenes"]["date2"]["model"] == "rpc" and report["scenes"]["nad"]["model"] == "rigorous"
    # the refined RPC, read as GDAL reads it, meets the truth as the adjusted scene does
    date2 = {"TRUE_SCENES": block["TRUE_SCENES"][3:], "DEM": block["DEM"]}
    assert abs(check_px(date2, [tmp_path / "out" / "date2_RPC.TXT"], ("date2",))["date2"] - after["date2"]) < 0.01
    assert any(line.startswith("refined RPC of the RPC product date2") for line in log.lines)
    assert any(line.startswith("scene date2: control") and "from its vendor RPC" in line for line in log.lines)


# --- bad blocks ------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def bad_inputs(block, gcp_layer, tmp_path_factory) -> dict:
    """Inputs that break a block: GCPs without a scene field, GCPs naming a scene not in the block,
    tie points all measured in one scene, tie points that join nad and fwd only."""
    folder = tmp_path_factory.mktemp("bad")
    table = gcp_io.read_gpkg(gcp_layer)
    no_field, foreign = folder / "no_scene.gpkg", folder / "foreign.gpkg"
    gcp_io.write_gpkg(replace(table, scene=None), no_field)
    gcp_io.write_gpkg(replace(table, scene=np.where(table.scene == "bwd", "date9", table.scene)),
                      foreign)
    lines = Path(block["TIE_POINTS"]).read_text().splitlines()
    header, rows = lines[0], lines[1:]
    one = folder / "one_scene.csv"
    one.write_text("\n".join([header] + [r for r in rows if r.endswith(",nad")]) + "\n")
    nad_fwd = {r.split(",")[0] for r in rows if r.endswith(",nad")} & {r.split(",")[0] for r in rows
                                                                     if r.endswith(",fwd")}
    split = folder / "split.csv"  # the observations in nad and fwd of the points both see: none in bwd
    split.write_text("\n".join([header] + [r for r in rows if r.endswith((",nad", ",fwd"))
                                           and r.split(",")[0] in nad_fwd]) + "\n")
    return {"no_field": str(no_field), "foreign": str(foreign), "one": str(one), "split": str(split)}


@pytest.mark.parametrize("change, message", [
    (lambda b, x: {"SCENE": b["SCENES"][0]}, r"^SCENE and SCENES are both given"),
    (lambda b, x: {"SCENES": []}, r"^give SCENE \(one scene\) or SCENES \(a block of scenes\): neither is given"),
    (lambda b, x: {"SCENES": b["SCENES"] + [b["SCENES"][1]]}, r"^SCENES: .*fwd/onboard_scene.json is listed twice"),
    (lambda b, x: {"SCENES": b["SCENES"] + [b["TRUE_SCENES"][1]]},
     r"^SCENES: .*onboard_scene.json and .*fwd/true_scene.json are both named 'fwd'"),
    (lambda b, x: {"SCENES": b["SCENES"][:2]}, r"^GCPS: scene\(s\) bwd of point\(s\) G1, .* are not scenes of the block \(nad, fwd\)$"),
    (lambda b, x: {"GCPS": x["no_field"]}, r"^GCPS: the layer has no field 'scene'; in a block of 3 scenes"),
    (lambda b, x: {"GCPS": x["foreign"]}, r"^GCPS: scene\(s\) date9 of point\(s\) G1, .* are not scenes of the block \(nad, fwd, bwd\)$"),
    (lambda b, x: {"TIE_POINTS": x["one"]}, r"^TIE_POINTS: tie points: point\(s\) T10, .* are seen in one scene only \(nad\)"),
    (lambda b, x: {"TIE_POINTS": x["split"]},
     r"^TIE_POINTS: no tie point joins the scenes of these groups to each other: nad, fwd; bwd"),
    (lambda b, x: {"TIE_POINTS": x["split"], "GCPS": None},
     r"^SCENES: scene\(s\) 'bwd' have no control point or tie point measured in them"),
    (lambda b, x: {"OUTPUT_SCENE": str(Path(x["one"]).with_name("a.json"))},
     r"^OUTPUT_SCENE: with SCENES the block's outputs go to OUTPUT_FOLDER \(it writes <name>_adjusted.json there\)"),
    (lambda b, x: {"OUTPUT_LINE_RESIDUALS": str(Path(x["one"]).with_name("r.gpkg"))},
     r"^OUTPUT_LINE_RESIDUALS: with SCENES the block's outputs go to OUTPUT_FOLDER \(it writes line_residuals.gpkg "
     r"with LINES there\)"),
])
def test_bad_blocks_are_refused_naming_the_parameter(block, gcp_layer, bad_inputs, tmp_path, change, message):
    given = {**params(block, gcp_layer, tmp_path / "out"), **change(block, bad_inputs)}
    with pytest.raises(QgsProcessingException, match=message):
        processing.run("pushbroom:bundleadjust", {k: v for k, v in given.items() if v is not None})
    assert not (tmp_path / "out").exists()


@pytest.fixture(scope="module")
def giza_ties(provider, shared_data, tmp_path_factory) -> dict:
    """The real Pleiades pair over Giza (tests/data/pleiades_gizeh): tie points matched between
    the two RPC products by pushbroom:matchtiepoints with SCENES."""
    gizeh = shared_data / "pleiades_gizeh"
    scenes = [str(gizeh / f"{n}_RPC.TXT") for n in ("img1", "img2")]
    out = processing.run("pushbroom:matchtiepoints", {
        "SCENES": scenes, "INPUTS": [str(gizeh / f"{n}.tif") for n in ("img1", "img2")], "HEIGHT": 75.0,
        "SPACING": 40.0, "WINDOW": 31, "SEARCH_RANGE": 60.0,
        "OUTPUT": str(tmp_path_factory.mktemp("giza") / "ties.gpkg")})
    return {"SCENES": scenes, "TIE_POINTS": out["OUTPUT"]}


def test_a_ties_only_block_of_rpc_products_is_held_by_rpc_sigma(giza_ties, tmp_path):
    """Two RPC products tied without GCPs: refused without RPC_SIGMA (nothing holds where the block
    lies), adjusted with it (the vendor's ~8 m CE90 as 10 px): the ties' reprojection RMS falls from
    0.25 to 0.05 px (measured 0.249 -> 0.048 in the core test), the report names the priors, and each
    image stays within its stated accuracy of the vendor geolocation."""
    run = dict(giza_ties, RPC_CORRECTION="shift")
    with pytest.raises(QgsProcessingException, match="RPC_SIGMA"):
        processing.run("pushbroom:bundleadjust", {**run, "OUTPUT_FOLDER": str(tmp_path / "none")})
    processing.run("pushbroom:bundleadjust", {**run, "RPC_SIGMA": 10.0, "OUTPUT_FOLDER": str(tmp_path / "held")})
    report = json.loads((tmp_path / "held" / "block_report.json").read_text())
    block = report["block"]
    assert block["tie_rmse_before_px"] > 0.2 and block["tie_rmse_px"] < 0.1, block
    assert "RPC correction priors" in report["datum"]
    assert all(s["moved_m"] < s["vendor_sigma_m"] for s in report["scenes"].values())
