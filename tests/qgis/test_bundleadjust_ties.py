"""Tie points in pushbroom:bundleadjust, as a user runs them: a simulated TH-1 three-line scene
(Zhang et al. 2015) through simulatescene -> importgcps -> importtiepoints -> bundleadjust
(TIE_POINTS, CAMERA_TRAJECTORY, INTERIOR=default) -> orthorectify ALL_CAMERAS, by processing.run
and by qgis_process; multi-camera GCPs and check points; 4 GCPs and 0 GCPs; the adjusted
tie-point layer, its style, the log and the reports."""
import csv
import html
import json
from pathlib import Path

import numpy as np
import pytest
from osgeo import gdal, ogr
from qgis.core import QgsRenderContext, QgsVectorLayer

import processing
from tests.support.processing import RecordingFeedback
from pushbroom_adjust.core.geodesy import geodetic_to_ecef


STYLE = Path(__file__).resolve().parents[2] / "resources" / "styles" / "adjusted_tie_points.qml"
# 24 ground points, 4 of them control (the simulator's draw), each seen in all three cameras.
SIMULATION = {"PRESET": "th1_tlc", "SEED": 3, "N_GCPS": 24, "CHECK_FRACTION": 0.834, "N_TIE_POINTS": 60,
              "IMAGE_NOISE": 0.3}
IMPORT_GCPS = {"Z_FIELD": "h", "Z_DATUM": "ellipsoid", "ROLE_FIELD": "role", "CAMERA_FIELD": "camera",
               "SIGMA_PX": 0.3}
ADJUST = {"CAMERA_TRAJECTORY": "shared", "INTERIOR": "default"}
CAMERAS = ("NAD", "FWD", "BWD")


def blank_raw_images(folder: Path, scene_path) -> list[str]:
    """Raw images of the scene's cameras' sizes, in camera order (a constant grey: the test is of
    the chain and the georeferencing, not of the texture)."""
    cameras = json.loads(Path(scene_path).read_text())["cameras"]
    paths = []
    for cam in cameras:
        paths.append(str(folder / f"raw_{cam['name']}.tif"))
        ds = gdal.GetDriverByName("GTiff").Create(paths[-1], cam["cols"], cam["rows"], 1, gdal.GDT_Byte,
                                                  ["TILED=YES", "COMPRESS=DEFLATE"])
        ds.GetRasterBand(1).Fill(100)
        ds = None
    return paths


@pytest.fixture(scope="module")
def chain(provider, tmp_path_factory):
    """The chain by processing.run: the simulation, GCP layers with 4 and 0 control points, the
    tie-point layer and the 4-GCP adjustment with every output."""
    out = tmp_path_factory.mktemp("ties")
    sim = processing.run("pushbroom:simulatescene", {**SIMULATION, "OUTPUT_FOLDER": str(out / "sim")})
    base = {"SCENE": sim["ONBOARD_SCENE"], "INPUT_FILE": sim["GCPS"], **IMPORT_GCPS}
    gcps4 = processing.run("pushbroom:importgcps", {**base, "OUTPUT": str(out / "gcps4.gpkg")})["OUTPUT"]
    gcps0 = processing.run("pushbroom:importgcps", {**base, "CHECK_FRACTION": 1.0,
                                                    "OUTPUT": str(out / "gcps0.gpkg")})["OUTPUT"]
    ties = processing.run("pushbroom:importtiepoints", {
        "SCENE": sim["ONBOARD_SCENE"], "INPUT_FILE": sim["TIE_POINTS"], "CAMERA_FIELD": "camera", "SIGMA_PX": 0.3,
        "OUTPUT": str(out / "tie_points.gpkg")})["OUTPUT"]
    log = RecordingFeedback()
    result = processing.run("pushbroom:bundleadjust", {
        "SCENE": sim["ONBOARD_SCENE"], "GCPS": gcps4, "TIE_POINTS": ties, **ADJUST,
        "OUTPUT_SCENE": str(out / "adjusted.json"), "OUTPUT_REPORT": str(out / "report.html"),
        "OUTPUT_GCPS": str(out / "adjusted_gcps.gpkg"), "OUTPUT_TIE_POINTS": str(out / "adjusted_ties.gpkg")},
        feedback=log)
    return {"sim": sim, "gcps4": gcps4, "gcps0": gcps0, "ties": ties, "result": result, "log": log, "out": out}


def _intersection(report_json) -> tuple[dict, dict]:
    rep = json.loads(Path(report_json).read_text())
    return rep["check_points_before"]["intersection"], rep["check_points"]["intersection"]


def test_four_gcps_and_tie_points_improve_the_3d_check_figures(chain):
    before, after = _intersection(chain["result"]["OUTPUT_REPORT_JSON"])
    # measured: plan 41.77 -> 11.11 m, height 115.38 -> 7.01 m, LE90 120.4 -> 9.9 m (20 check points)
    assert after["intersected"] == before["intersected"] == 20
    assert 35.0 < before["rmse_plan"] < 50.0 and 100.0 < before["rmse_height"] < 130.0
    assert after["rmse_plan"] < 14.0 and before["rmse_plan"] / after["rmse_plan"] > 3.0
    assert after["rmse_height"] < 9.0 and before["rmse_height"] / after["rmse_height"] > 12.0
    assert after["le90"] < 13.0


def test_multi_camera_gcps_use_every_camera(chain):
    rep = json.loads(Path(chain["result"]["OUTPUT_REPORT_JSON"]).read_text())
    obs = rep["observations"]
    # 4 control points and 20 check points, each seen by the three cameras: 12 and 60 observations
    assert obs["control_points"] == 4 and obs["image_observations"] == 12 and obs["check_points"] == 60
    layer = QgsVectorLayer(chain["result"]["OUTPUT_GCPS"], "gcps", "ogr")
    control = [f["camera"] for f in layer.getFeatures() if f["role"] == "control"]
    assert sorted(control) == sorted(CAMERAS * 4)
    assert all(f["res_px"] < 1.5 for f in layer.getFeatures() if f["role"] == "control")


def test_the_tie_point_layer_lies_at_the_adjusted_ground_positions(chain):
    rows = list(csv.DictReader(open(chain["sim"]["TIE_POINTS"])))
    ds = ogr.Open(chain["result"]["OUTPUT_TIE_POINTS"])
    lyr = ds.GetLayer(0)
    defn = lyr.GetLayerDefn()
    assert [defn.GetFieldDefn(i).GetName() for i in range(defn.GetFieldCount())] == [
        "id", "camera", "col", "row", "res_col", "res_row", "res_px", "w_col", "w_row", "weight", "flagged"]
    assert lyr.GetMetadataItem("PUSHBROOM_SCENE") == chain["result"]["OUTPUT_SCENE"]
    features = list(lyr)
    assert [f["id"] for f in features] == [r["id"] for r in rows]
    res = np.array([[f["res_col"], f["res_row"], f["res_px"]] for f in features])
    assert np.allclose(np.hypot(res[:, 0], res[:, 1]), res[:, 2])
    assert 0.1 < np.sqrt(np.mean(res[:, 2] ** 2)) < 0.6  # 0.3 px noise per coordinate
    got = geodetic_to_ecef(*np.array([[f.GetGeometryRef().GetX(), f.GetGeometryRef().GetY(),
                                       f.GetGeometryRef().GetZ()] for f in features]).T)
    truth = geodetic_to_ecef(*(np.array([float(r[k]) for r in rows]) for k in ("lon_true", "lat_true", "h_true")))
    error = np.linalg.norm(got - truth, axis=1)
    # As accurate as the check points intersected with the same adjusted model (measured: median
    # 17.1 m against a 3D check RMSE of about 13 m: 11 m plan, 7 m height), far from the onboard
    # model's 120 m.
    _, after = _intersection(chain["result"]["OUTPUT_REPORT_JSON"])
    assert np.median(error) < 1.5 * np.hypot(after["rmse_plan"], after["rmse_height"])


def test_the_tie_point_style_draws_flagged_observations_red(chain, tmp_path):
    layer = QgsVectorLayer(chain["result"]["OUTPUT_TIE_POINTS"], "ties", "ogr")
    message, ok = layer.loadNamedStyle(str(STYLE))
    assert ok, message
    rules = layer.renderer().rootRule().children()
    assert rules[0].label().startswith("Flagged") and rules[0].symbol().color().name() == "#d7191c"
    context = QgsRenderContext()
    layer.renderer().startRender(context, layer.fields())
    drawn = [bool(layer.renderer().symbolsForFeature(f, context)) for f in layer.getFeatures()]
    layer.renderer().stopRender(context)
    assert all(drawn)


def test_the_log_and_the_reports_give_the_tie_figures_and_the_datum(chain):
    lines = chain["log"].lines
    assert "176 tie observations from " + chain["ties"] in lines
    assert any(line.startswith("tie points: 60 points, 176 of 176 observations used; 0 observations flagged")
               for line in lines)
    residuals = next(line for line in lines if line.startswith("tie residuals RMSE"))
    assert all(f"{cam} 0." in residuals for cam in CAMERAS)
    rep = json.loads(Path(chain["result"]["OUTPUT_REPORT_JSON"]).read_text())
    assert rep["tie_points"]["points"] == 60 and rep["datum"]["control_points"] == 4
    yaw = rep["datum"]["yaw"]
    held = ("datum held by control points and onboard pseudo-observations: the yaw (block rotation about the "
            f"vertical) is held to {yaw['sigma_arcsec']:.1f} arcsec (posterior sigma), {yaw['edge_m']:.2f} m at the "
            f"scene's corners {yaw['radius_m'] / 1000:.1f} km from its centre")
    assert held in lines and 0 < yaw["sigma_arcsec"] < 60
    page = Path(chain["result"]["OUTPUT_REPORT"]).read_text()
    assert "<h2>Tie points</h2>" in page and html.escape(held) in page


def test_no_control_points_the_onboard_data_hold_the_datum(chain, tmp_path):
    """0 GCPs (every ground point a check point) with onboard positions and attitude: the block
    adjusts, the report says the datum is the onboard data's, and the tie residuals are those of
    the image noise; the absolute figures stay at the onboard level (no control)."""
    log = RecordingFeedback()
    result = processing.run("pushbroom:bundleadjust", {
        "SCENE": chain["sim"]["ONBOARD_SCENE"], "GCPS": chain["gcps0"], "TIE_POINTS": chain["ties"],
        "CAMERA_TRAJECTORY": "shared", "ATTITUDE_SIGMA": 10.0, "OUTPUT_SCENE": str(tmp_path / "a.json"),
        "OUTPUT_REPORT": str(tmp_path / "r.html")}, feedback=log)
    rep = json.loads(Path(result["OUTPUT_REPORT_JSON"]).read_text())
    assert rep["datum"]["held_by"] == "onboard pseudo-observations" and rep["observations"]["control_points"] == 0
    assert any(line.startswith("datum held by onboard pseudo-observations: no control points") for line in log.lines)
    before, after = _intersection(result["OUTPUT_REPORT_JSON"])
    assert after["intersected"] == 24 and 100.0 < after["rmse_height"] < 130.0 and before["rmse_plan"] > 35.0


def test_without_a_gcp_layer_at_all(chain, tmp_path):
    result = processing.run("pushbroom:bundleadjust", {
        "SCENE": chain["sim"]["ONBOARD_SCENE"], "TIE_POINTS": chain["ties"], "ATTITUDE_SIGMA": 10.0,
        "OUTPUT_SCENE": str(tmp_path / "a.json"), "OUTPUT_TIE_POINTS": str(tmp_path / "t.gpkg")})
    assert Path(result["OUTPUT_SCENE"]).is_file()
    assert QgsVectorLayer(result["OUTPUT_TIE_POINTS"], "t", "ogr").featureCount() == 176


def _cli(qgis_process, alg: str, *args) -> dict:
    done = qgis_process("--json", "run", alg, "--", *args)
    assert done.returncode == 0, done.stdout + done.stderr
    return json.loads(done.stdout)


def test_the_three_line_chain_from_the_command_line(qgis_process, tmp_path):
    """The worked example of docs/three-line-cameras.md: simulate, import GCPs and tie points, adjust with 4 GCPs,
    orthorectify every camera of the adjusted scene."""
    sim = _cli(qgis_process, "pushbroom:simulatescene", *(f"{k}={v}" for k, v in SIMULATION.items()),
               f"OUTPUT_FOLDER={tmp_path / 'sim'}")["results"]
    gcps = _cli(qgis_process, "pushbroom:importgcps", f"SCENE={sim['ONBOARD_SCENE']}", f"INPUT_FILE={sim['GCPS']}",
                *(f"{k}={v}" for k, v in IMPORT_GCPS.items()), f"OUTPUT={tmp_path / 'gcps.gpkg'}")["results"]
    ties = _cli(qgis_process, "pushbroom:importtiepoints", f"SCENE={sim['ONBOARD_SCENE']}",
                f"INPUT_FILE={sim['TIE_POINTS']}", "CAMERA_FIELD=camera", "SIGMA_PX=0.3",
                f"OUTPUT={tmp_path / 'ties.gpkg'}")["results"]
    adjusted = _cli(qgis_process, "pushbroom:bundleadjust", f"SCENE={sim['ONBOARD_SCENE']}", f"GCPS={gcps['OUTPUT']}",
                    f"TIE_POINTS={ties['OUTPUT']}", *(f"{k}={v}" for k, v in ADJUST.items()),
                    f"OUTPUT_SCENE={tmp_path / 'adjusted.json'}", f"OUTPUT_REPORT={tmp_path / 'report.html'}",
                    f"OUTPUT_TIE_POINTS={tmp_path / 'adjusted_ties.gpkg'}")
    before, after = _intersection(adjusted["results"]["OUTPUT_REPORT_JSON"])
    assert before["rmse_plan"] / after["rmse_plan"] > 3.0 and before["rmse_height"] / after["rmse_height"] > 12.0
    assert "datum held by control points and onboard pseudo-observations" in json.dumps(adjusted)
    images = blank_raw_images(tmp_path, adjusted["results"]["OUTPUT_SCENE"])
    ortho = _cli(qgis_process, "pushbroom:orthorectify", f"SCENE={adjusted['results']['OUTPUT_SCENE']}",
                 f"DEM={sim['DEM']}", "DEM_DATUM=geoid", "RESOLUTION=200", "ALL_CAMERAS=true",
                 *(f"INPUTS={i}" for i in images), f"ORTHO_FOLDER={tmp_path / 'ortho'}")["results"]
    assert [Path(p).name for p in ortho["ORTHOIMAGES"]] == [f"ortho_{c}.tif" for c in CAMERAS]
    for path in ortho["ORTHOIMAGES"]:
        ds = gdal.Open(path)  # kept: a band outlives its dataset only as a crash
        assert ds.GetRasterBand(1).ReadAsArray().max() == 100 and ds.GetGeoTransform()[1] == 200.0
