"""pushbroom:bundleadjust in QGIS: simulate -> import GCPs -> adjust, checked against the
simulation's truth and recomputed from the output files, from processing.run and from
qgis_process; bad input named by its parameter; outputs styled when loaded."""
import csv
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from osgeo import ogr
from qgis.core import (QgsExpression, QgsExpressionContext, QgsExpressionContextUtils, QgsProcessingException,
                       QgsProject, QgsVectorLayer)

import processing
from pushbroom_adjust.core.observations.gcps import read_gpkg
from pushbroom_adjust.core.geodesy import enu_rotations, geodetic_to_ecef
from pushbroom_adjust.core.formats import load_scene

from tests.support.csvrows import read_rows, write_rows
from tests.support.qgis_process import run_json
from tests.support.processing import RecordingFeedback

INTERIOR = "HRC-1.*, HRC-3.*"
NEW_FIELDS = ("res_col", "res_row", "res_px", "res_m", "w_col", "w_row", "redundancy", "weight", "flagged")


def _outputs(folder: Path, prefix: str = "") -> dict:
    return {"OUTPUT_SCENE": str(folder / f"{prefix}adjusted.json"),
            "OUTPUT_REPORT": str(folder / f"{prefix}report.html"),
            "OUTPUT_GCPS": str(folder / f"{prefix}adjusted_gcps.gpkg"),
            "OUTPUT_RESIDUALS": str(folder / f"{prefix}residuals.gpkg")}


@pytest.fixture(scope="module")
def chain(provider, tmp_path_factory):
    """A simulated CBERS-02B scene (600 ground points, half of them check points, 0.5 px noise,
    5 % gross errors), its GCPs imported against the onboard model, then adjusted with the
    left and right CCDs' terms free and default settings otherwise."""
    out = tmp_path_factory.mktemp("adjust")
    sim = processing.run("pushbroom:simulatescene", {"SEED": 5, "N_GCPS": 600, "IMAGE_NOISE": 0.5,
                                                     "CHECK_FRACTION": 0.5, "GROSS_FRACTION": 0.05,
                                                     "GROUND_NOISE_XY": 1.0, "GROUND_NOISE_Z": 1.0,
                                                     "OUTPUT_FOLDER": str(out / "sim")})
    gcps = processing.run("pushbroom:importgcps", {"SCENE": sim["ONBOARD_SCENE"], "INPUT_FILE": sim["GCPS"],
                                                   "Z_FIELD": "h", "Z_DATUM": "ellipsoid", "ROLE_FIELD": "role",
                                                   "CAMERA_FIELD": "camera", "SIGMA_PX": 0.5,
                                                   "OUTPUT": str(out / "gcps.gpkg")})["OUTPUT"]
    log = RecordingFeedback()
    result = processing.run("pushbroom:bundleadjust", {"SCENE": sim["ONBOARD_SCENE"], "GCPS": gcps,
                                                       "INTERIOR": INTERIOR, **_outputs(out)}, feedback=log)
    return sim, gcps, result, log


def _truth_gross(sim, table) -> np.ndarray:
    """Whether the simulator put a gross error on each row of a GCP table."""
    with open(sim["GCPS"]) as f:
        gross = {(r["id"], r["camera"]): r["gross"] == "1" for r in csv.DictReader(f)}
    return np.array([gross[(i, c)] for i, c in zip(table.id, table.camera)])


def _rmse(v) -> float:
    return float(np.sqrt(np.mean(np.square(v))))


def test_check_points_before_and_after(chain):
    """Recomputed from the layers: the onboard model misses the check points by > 50 px, the
    adjusted one by the measurement noise."""
    sim, gcps, result, log = chain
    before = read_gpkg(gcps)
    after = read_gpkg(result["OUTPUT_GCPS"])
    assert list(after.id) == list(before.id) and list(after.role) == list(before.role)
    check = (after.role == "check") & ~_truth_gross(sim, after)
    rmse_before = _rmse(before.residuals.px[check & before.residuals.inside])
    rmse_after = _rmse(after.residuals.px[check])
    print(f"check points without gross errors ({check.sum()}): RMSE {rmse_before:.1f} px before, "
          f"{rmse_after:.3f} px after")
    assert rmse_before > 50.0  # the onboard model: ~180 px off
    assert rmse_after < 1.5  # 0.5 px noise per axis and 1 m ground noise (~0.5 px): ~1 px
    report = json.loads(Path(result["OUTPUT_REPORT_JSON"]).read_text())
    assert report["check_points_before"]["image"]["rmse"] > 50.0
    assert report["check_points"]["without_blunders"]["image"]["rmse"] < 1.5
    print(f"sigma0 {report['sigma0']:.3f}, {report['robust']['flagged']} control observations flagged; report: "
          f"check RMSE {report['check_points_before']['image']['rmse']:.1f} px before, "
          f"{report['check_points']['without_blunders']['image']['rmse']:.3f} px after without blunders")
    assert abs(report["sigma0"] - 1.0) < 0.15 and report["robust"]["flagged"] > 0  # measured 0.94
    # the headline figures went to the log
    text = "\n".join(log.infos)
    assert "sigma0" in text and "check points monoplotted, per observation, before: RMSE" in text
    assert f"check points monoplotted, per observation, after: RMSE {report['check_points']['image']['rmse']:.3f} px" \
        in text
    assert "check points 3D intersection: 0 of 300 check points intersected" in text  # one camera
    assert f"{report['robust']['flagged']} observations flagged" in text


def test_the_adjusted_scene_agrees_with_the_layer(chain):
    """The scene JSON, loaded as any algorithm loads it, projects the check points where the
    layer's residuals say, and its image -> ground gives the layer's res_m."""
    _, _, result, _ = chain
    scene = load_scene(result["OUTPUT_SCENE"])
    layer = read_gpkg(result["OUTPUT_GCPS"])
    checks = layer.select(layer.role == "check")
    col, row = scene.ground_to_image(checks.ecef())
    assert np.allclose(col - checks.col, checks.residuals.col, atol=1e-6)
    assert np.allclose(row - checks.row, checks.residuals.row, atol=1e-6)
    seen = scene.image_to_ground(checks.col, checks.row, checks.h)
    en = np.einsum("nij,nj->ni", enu_rotations(checks.lon, checks.lat), seen - checks.ecef())[:, :2]
    assert np.allclose(np.hypot(en[:, 0], en[:, 1]), checks.residuals.m, atol=1e-4)
    html = Path(result["OUTPUT_REPORT"]).read_text()
    assert "<html" in html.lower() and html.count("data:image/png;base64,") >= 1


def test_chip_shifts_are_recovered_within_three_sigma(chain):
    sim, _, result, _ = chain
    report = json.loads(Path(result["OUTPUT_REPORT_JSON"]).read_text())
    truth = json.loads(Path(sim["MANIFEST"]).read_text())["truth"]["interior"][0]["chips"]
    params = {p["name"]: p for p in report["parameters"]}
    worst = 0.0
    for chip in (truth[0], truth[2]):
        for term, key in (("dx", "dx_m"), ("dy", "dy_m"), ("theta", "dtheta_rad")):
            p = params[f"{chip['chip']}.{term}"]
            assert p["mode"] == "free" and p["sigma"] > 0
            worst = max(worst, abs(p["value"] - chip[key]) / p["sigma"])
            assert abs(p["value"] - chip[key]) < 3 * p["sigma"], (p, chip[key])
    assert params["HRC-2.dx"]["mode"] == "fixed"  # the middle chip is the reference
    print(f"chip terms: largest error {worst:.2f} sigma")


def test_layers_have_the_adjustment_fields_and_one_feature_per_point(chain):
    sim, gcps, result, _ = chain
    n_in = QgsVectorLayer(gcps, "in", "ogr").featureCount()
    out = QgsVectorLayer(result["OUTPUT_GCPS"], "out", "ogr")
    assert out.isValid() and out.featureCount() == n_in and out.crs().authid() == "EPSG:4979"
    assert out.wkbType() == QgsVectorLayer(gcps, "in", "ogr").wkbType()  # Point Z
    names = out.fields().names()
    assert set(QgsVectorLayer(gcps, "in", "ogr").fields().names()) <= set(names)
    assert set(NEW_FIELDS) <= set(names)
    layer = read_gpkg(result["OUTPUT_GCPS"])
    ds = ogr.Open(result["OUTPUT_GCPS"])
    flags = np.array([f.GetField("flagged") for f in ds.GetLayer(0)])
    control = layer.role == "control"
    # the flagged control observations are mostly the simulated gross errors
    gross = _truth_gross(sim, layer)
    found = (flags[control] == 1) & gross[control]
    print(f"control gross errors: {gross[control].sum()} simulated, {flags[control].sum()} flagged, "
          f"{found.sum()} of them right")
    # good points flagged: the test's alpha on two axes (~0.6 expected of ~290), against sigmas the
    # variance components estimate from ~300 redundancy (+-4 %): at most 1 %
    assert found.sum() >= 0.9 * gross[control].sum() and (flags[control] == 1)[~gross[control]].mean() <= 0.01
    # residual vectors: one line per point, res_m as in the GCP layer, drawn RESIDUAL_SCALE times longer
    vec_ds = ogr.Open(result["OUTPUT_RESIDUALS"])  # the layer lives only as long as its data source
    vectors = vec_ds.GetLayer(0)
    assert vectors.GetFeatureCount() == n_in and vectors.GetGeomType() == ogr.wkbLineString
    assert vectors.GetSpatialRef().GetAuthorityCode(None) == "4326"
    rows = [(f.GetField("id"), f.GetField("res_m"), f.GetField("flagged"), f.GetGeometryRef().GetPoints())
            for f in vectors]
    assert [r[0] for r in rows] == list(layer.id) and [r[2] for r in rows] == flags.tolist()
    res_m = np.array([r[1] for r in rows])
    assert np.allclose(res_m, layer.residuals.m, atol=1e-9)
    ends = np.array([(*r[3][0], *r[3][1]) for r in rows])
    start = geodetic_to_ecef(ends[:, 0], ends[:, 1], layer.h)
    end = geodetic_to_ecef(ends[:, 2], ends[:, 3], layer.h)
    drawn = np.einsum("nij,nj->ni", enu_rotations(layer.lon, layer.lat), end - start)[:, :2]
    assert np.allclose(ends[:, :2], np.stack([layer.lon, layer.lat], 1), atol=1e-12)
    length = np.hypot(drawn[:, 0], drawn[:, 1])
    short = 1000.0 * res_m < 10e3  # longer lines (gross errors) curve with the Earth away from the tangent plane
    print(f"residual vectors: {short.sum()} shorter than 10 km drawn at 1000 x res_m within "
          f"{np.max(np.abs(length[short] / (1000.0 * res_m[short]) - 1)):.1e}")
    assert short.sum() > 0.8 * len(short) and np.allclose(length[short], 1000.0 * res_m[short], rtol=1e-3)


def test_other_fields_of_the_gcp_layer_are_kept_and_outputs_are_styled(chain, tmp_path):
    """A field a user added to the GCP layer survives; loaded outputs get their styles."""
    sim, gcps, _, _ = chain
    edited = tmp_path / "edited.gpkg"
    shutil.copy(gcps, edited)
    ds = ogr.Open(str(edited), 1)
    lyr = ds.GetLayer(0)
    lyr.CreateField(ogr.FieldDefn("note", ogr.OFTString))
    for f in lyr:
        f.SetField("note", f"n{f.GetField('id')}")
        lyr.SetFeature(f)
    ds = lyr = None
    project = QgsProject.instance()
    result = processing.runAndLoadResults("pushbroom:bundleadjust", {
        "SCENE": sim["ONBOARD_SCENE"], "GCPS": str(edited), "RESIDUAL_SCALE": 500, **_outputs(tmp_path)})
    try:
        out = QgsVectorLayer(result["OUTPUT_GCPS"], "out", "ogr")
        assert [f["note"] for f in out.getFeatures()] == [f"n{f['id']}" for f in out.getFeatures()]
        loaded = {layer.source().split("|")[0]: layer for layer in project.mapLayers().values()}
        gcp_layer = loaded[result["OUTPUT_GCPS"]]
        rules = gcp_layer.renderer().rootRule().children()
        assert gcp_layer.renderer().type() == "RuleRenderer"
        assert [r.filterExpression() for r in rules][0] == '"flagged" = 1'
        # accepted points: a fill colour from green (no residual) to red (>= 3.5 sigma_px)
        fill = rules[1].symbol().symbolLayer(0)
        colour = QgsExpression(fill.dataDefinedProperties().property(fill.PropertyFillColor).expressionString())
        context = QgsExpressionContext(QgsExpressionContextUtils.globalProjectLayerScopes(gcp_layer))
        feature = next(gcp_layer.getFeatures())
        colours = []
        for res_px in (0.0, 0.875, 10.0):
            feature["res_px"], feature["sigma_px"] = res_px, 0.5
            context.setFeature(feature)
            colours.append(colour.evaluate(context))
        assert colours == ["26,150,65,255", "255,220,60,255", "215,25,28,255"]
        vec_layer = loaded[result["OUTPUT_RESIDUALS"]]
        assert vec_layer.renderer().type() == "categorizedSymbol"
        assert vec_layer.renderer().classAttribute() == "flagged"
        assert vec_layer.renderer().categories()[0].symbol().symbolLayer(0).layerType() == "ArrowLine"
    finally:
        project.removeAllMapLayers()


def test_bad_input_is_named(chain, tmp_path):
    sim, gcps, _, _ = chain
    base = {"SCENE": sim["ONBOARD_SCENE"], "GCPS": gcps, **_outputs(tmp_path)}
    csv_layer = QgsVectorLayer(f"file://{sim['GCPS']}?type=csv&xField=lon&yField=lat&crs=EPSG:4326", "csv",
                               "delimitedtext")
    with pytest.raises(QgsProcessingException, match="GCPS: .* is not a GeoPackage"):
        processing.run("pushbroom:bundleadjust", {**base, "GCPS": csv_layer})
    with pytest.raises(QgsProcessingException, match="GCPS: .*gcps.csv is not a GeoPackage"):
        processing.run("pushbroom:bundleadjust", {**base, "GCPS": sim["GCPS"]})
    footprint = processing.run("pushbroom:footprint", {"SCENE": sim["ONBOARD_SCENE"],
                                                       "OUTPUT": str(tmp_path / "fp.gpkg")})["OUTPUT"]
    with pytest.raises(QgsProcessingException, match="GCPS: .*fp.gpkg: layer .* lacks GCP field"):
        processing.run("pushbroom:bundleadjust", {**base, "GCPS": footprint})
    with pytest.raises(QgsProcessingException,
                       match=r"INTERIOR: interior parameter 'HRC-7\.\*' matches none.*chips HRC-1, HRC-2, HRC-3"):
        processing.run("pushbroom:bundleadjust", {**base, "INTERIOR": "HRC-7.*"})
    with pytest.raises(QgsProcessingException, match=r"INTERIOR: .*'HRC-1\.dx=abc'.*must be a number"):
        processing.run("pushbroom:bundleadjust", {**base, "INTERIOR": "HRC-1.dx=abc"})
    with pytest.raises(QgsProcessingException, match=r"GCPS: too few control points: 2 \(at least 3"):
        processing.run("pushbroom:bundleadjust", {**base, "GCPS": _few_gcps(sim, tmp_path, 2)})
    with pytest.raises(QgsProcessingException, match="GCPS: too few GCPs for the chosen model: .* equations for .* unknowns"):
        processing.run("pushbroom:bundleadjust", {**base, "GCPS": _few_gcps(sim, tmp_path, 6),
                                                  "POSITION_SIGMA": 0, "POSITION_ORDER": 2})
    with pytest.raises(QgsProcessingException, match="OUTPUT_SCENE: expected a .json file"):
        processing.run("pushbroom:bundleadjust", {**base, "OUTPUT_SCENE": str(tmp_path / "a.txt")})
    assert not any(Path(p).exists() for p in _outputs(tmp_path).values())


def _few_gcps(sim, folder: Path, n_control: int) -> str:
    """A GCP GeoPackage with only ``n_control`` control points (spread over the image) and some
    check points, imported as a user would."""
    rows = read_rows(sim["GCPS"])
    control = sorted((r for r in rows if r["role"] == "control" and r["gross"] == "0"),
                     key=lambda r: float(r["row"]) + float(r["col"]))
    keep = [control[int(i)] for i in np.linspace(0, len(control) - 1, n_control)]
    keep += [r for r in rows if r["role"] == "check"][:5]
    path = write_rows(folder / f"few{n_control}.csv", keep, list(rows[0]))
    return processing.run("pushbroom:importgcps", {"SCENE": sim["ONBOARD_SCENE"], "INPUT_FILE": str(path),
                                                   "Z_FIELD": "h", "Z_DATUM": "ellipsoid", "ROLE_FIELD": "role",
                                                   "CAMERA_FIELD": "camera",
                                                   "OUTPUT": str(folder / f"few{n_control}.gpkg")})["OUTPUT"]


def test_bundleadjust_from_the_command_line(qgis_process, chain, tmp_path):
    """Orientation images for position and attitude, from qgis_process, with the GCP file path."""
    sim, gcps, _, _ = chain
    results = run_json(qgis_process, "pushbroom:bundleadjust", SCENE=sim["ONBOARD_SCENE"], GCPS=gcps,
                        INTERIOR=INTERIOR, POSITION_MODEL="lagrange", POSITION_INTERVAL=2, ATTITUDE_MODEL="lagrange",
                        ATTITUDE_INTERVAL=2, ATTITUDE_SIGMA=20, OUTPUT_SCENE=tmp_path / "s.json",
                        OUTPUT_REPORT=tmp_path / "r.html", OUTPUT_GCPS=tmp_path / "g.gpkg",
                        OUTPUT_RESIDUALS=tmp_path / "v.gpkg")
    report = json.loads(Path(results["OUTPUT_REPORT_JSON"]).read_text())
    assert results["OUTPUT_REPORT_JSON"] == str(tmp_path / "r.json")
    assert report["settings"]["position_model"] == "lagrange" and len(report["trajectory"]["position_knots"]) >= 4
    assert report["settings"]["attitude_sigma"] == pytest.approx(20 * np.pi / 648000)  # arcsec -> rad
    rmse = report["check_points"]["without_blunders"]["image"]["rmse"]
    print(f"qgis_process, orientation images every 2 s: check-point RMSE {rmse:.3f} px")
    assert rmse < 1.5
    assert load_scene(results["OUTPUT_SCENE"]).platform.correction.position.kind == "lagrange"
    assert read_gpkg(results["OUTPUT_GCPS"]).scene_path == str(tmp_path / "s.json")
