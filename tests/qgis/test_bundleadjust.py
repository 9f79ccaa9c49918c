"""pushbroom:bundleadjust in QGIS: simulate -> import GCPs -> adjust, checked against the
simulation's truth, from processing.run and from qgis_process; bad input named."""
import json
from pathlib import Path

import numpy as np
import pytest
from osgeo import ogr
from qgis.core import QgsProcessingException, QgsVectorLayer

import processing
from core.gcps import read_gpkg
from core.scene_io import load_scene

from .test_qgis_process import _run_json, qgis_process  # noqa: F401 (fixture)

INTERIOR = "HRC-1.*, HRC-3.*"


@pytest.fixture(scope="module")
def chain(provider, tmp_path_factory):
    """A simulated CBERS-02B scene, its GCPs imported, then adjusted with the CCD terms."""
    out = tmp_path_factory.mktemp("adjust")
    sim = processing.run("pushbroom:simulatescene", {"SEED": 5, "N_GCPS": 600, "IMAGE_NOISE": 0.5,
                                                     "CHECK_FRACTION": 0.5, "GROSS_FRACTION": 0.05,
                                                     "GROUND_NOISE_XY": 1.0, "GROUND_NOISE_Z": 1.0,
                                                     "OUTPUT_FOLDER": str(out / "sim")})
    gcps = processing.run("pushbroom:importgcps", {"SCENE": sim["ONBOARD_SCENE"], "INPUT_FILE": sim["GCPS"],
                                                   "Z_FIELD": "h", "DEM_DATUM": 1, "ROLE_FIELD": "role",
                                                   "CAMERA_FIELD": "camera", "SIGMA_PX": 0.5,
                                                   "OUTPUT": str(out / "gcps.gpkg")})["OUTPUT"]
    result = processing.run("pushbroom:bundleadjust", {
        "SCENE": sim["ONBOARD_SCENE"], "GCPS": gcps, "INTERIOR": INTERIOR,
        "OUTPUT_SCENE": str(out / "adjusted.json"), "OUTPUT_REPORT": str(out / "report.html"),
        "OUTPUT_GCPS": str(out / "adjusted_gcps.gpkg"), "OUTPUT_RESIDUALS": str(out / "residuals.gpkg")})
    return sim, gcps, result


def test_outputs_and_accuracy(chain):
    sim, gcps, result = chain
    report = json.loads(Path(result["OUTPUT_REPORT_JSON"]).read_text())
    assert report["check_points_before"]["image"]["rmse"] > 50.0  # the onboard model: ~180 px off
    assert report["check_points"]["without_blunders"]["image"]["rmse"] < 1.0  # noise 0.5 px per axis
    assert abs(report["sigma0"] - 1.0) < 0.15 and report["robust"]["flagged"] > 0  # measured 0.94
    html = Path(result["OUTPUT_REPORT"]).read_text()
    assert html.count("data:image/png;base64,") == 3
    # the adjusted scene, as any algorithm reads it, meets the check points as the layer says
    scene = load_scene(result["OUTPUT_SCENE"])
    layer = read_gpkg(result["OUTPUT_GCPS"])
    checks = layer.select(layer.role == "check")
    col, row = scene.ground_to_image(checks.ecef())
    assert np.allclose(col - checks.col, checks.residuals.col, atol=1e-6)
    assert np.allclose(row - checks.row, checks.residuals.row, atol=1e-6)


def test_chip_shifts_are_recovered_within_three_sigma(chain):
    sim, _, result = chain
    report = json.loads(Path(result["OUTPUT_REPORT_JSON"]).read_text())
    truth = json.loads(Path(sim["MANIFEST"]).read_text())["truth"]["interior"][0]["chips"]
    params = {p["name"]: p for p in report["parameters"]}
    for chip in (truth[0], truth[2]):
        for term, key in (("dx", "dx_m"), ("dy", "dy_m"), ("theta", "dtheta_rad")):
            p = params[f"{chip['chip']}.{term}"]
            assert abs(p["value"] - chip[key]) < 3 * p["sigma"], p["name"]


def test_layers_have_the_adjustment_fields_and_one_feature_per_point(chain):
    _, gcps, result = chain
    n_in = QgsVectorLayer(gcps, "in", "ogr").featureCount()
    ds = ogr.Open(result["OUTPUT_GCPS"])
    lyr = ds.GetLayer(0)
    names = [lyr.GetLayerDefn().GetFieldDefn(i).GetName() for i in range(lyr.GetLayerDefn().GetFieldCount())]
    assert {"res_col", "res_row", "res_px", "res_m", "w_col", "w_row", "redundancy", "weight", "flagged"} <= set(names)
    assert lyr.GetFeatureCount() == n_in
    flagged = sum(f.GetField("flagged") for f in lyr)
    vectors_ds = ogr.Open(result["OUTPUT_RESIDUALS"])  # the layer lives only as long as its data source
    vectors = vectors_ds.GetLayer(0)
    assert vectors.GetFeatureCount() == n_in and vectors.GetGeomType() == ogr.wkbLineString
    assert sum(f.GetField("flagged") for f in vectors) == flagged > 0


def test_bad_input_is_named(chain, tmp_path):
    sim, gcps, _ = chain
    base = {"SCENE": sim["ONBOARD_SCENE"], "GCPS": gcps, "OUTPUT_SCENE": str(tmp_path / "a.json"),
            "OUTPUT_REPORT": str(tmp_path / "r.html"), "OUTPUT_GCPS": str(tmp_path / "g.gpkg"),
            "OUTPUT_RESIDUALS": str(tmp_path / "v.gpkg")}
    csv_layer = QgsVectorLayer(f"file://{sim['GCPS']}?type=csv&xField=lon&yField=lat&crs=EPSG:4326", "csv",
                               "delimitedtext")
    with pytest.raises(QgsProcessingException, match="GCPS: .* is not a GeoPackage"):
        processing.run("pushbroom:bundleadjust", {**base, "GCPS": csv_layer})
    with pytest.raises(QgsProcessingException, match=r"'HRC-7\.\*' matches none of this scene's parameters"):
        processing.run("pushbroom:bundleadjust", {**base, "INTERIOR": "HRC-7.*"})
    with pytest.raises(QgsProcessingException, match="OUTPUT_SCENE: expected a .json file"):
        processing.run("pushbroom:bundleadjust", {**base, "OUTPUT_SCENE": str(tmp_path / "a.txt")})
    assert not (tmp_path / "g.gpkg").exists()


def test_bundleadjust_from_the_command_line(qgis_process, chain, tmp_path):  # noqa: F811
    sim, gcps, _ = chain
    results = _run_json(qgis_process, "pushbroom:bundleadjust", SCENE=sim["ONBOARD_SCENE"], GCPS=gcps,
                        INTERIOR=INTERIOR, POSITION_MODEL=1, POSITION_INTERVAL=2, ATTITUDE_MODEL=1,
                        ATTITUDE_INTERVAL=2, OUTPUT_SCENE=tmp_path / "s.json", OUTPUT_REPORT=tmp_path / "r.html",
                        OUTPUT_GCPS=tmp_path / "g.gpkg", OUTPUT_RESIDUALS=tmp_path / "v.gpkg")
    report = json.loads(Path(results["OUTPUT_REPORT_JSON"]).read_text())
    assert report["settings"]["position_model"] == "lagrange" and len(report["trajectory"]["position_knots"]) >= 4
    assert report["check_points"]["without_blunders"]["image"]["rmse"] < 1.0
    assert load_scene(results["OUTPUT_SCENE"]).platform.correction.position.kind == "lagrange"
