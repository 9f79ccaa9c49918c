"""pushbroom:importlines and bundleadjust LINES on a simulated CBERS-02B HRC scene with roads
(Tommaselli & Marcato Junior 2012), through processing.run and qgis_process."""
from __future__ import annotations

from osgeo import ogr

from tests.support.control_lines import roads  # noqa: F401 (the fixture)


def _import(provider, result, out, **extra):
    import processing
    return processing.run("pushbroom:importlines", {
        "SCENE": str(result.onboard_scene), "INPUT": f"{result.lines}|layername=ground_lines",
        "IMAGE_LINES": f"{result.lines}|layername=image_lines", "HEIGHT_SOURCE": "z", "Z_DATUM": "ellipsoid",
        "OUTPUT": str(out), **extra})


def _gcps(provider, result, out):
    import processing
    return processing.run("pushbroom:importgcps", {
        "SCENE": str(result.onboard_scene), "INPUT_FILE": str(result.gcps), "ROLE_FIELD": "role",
        "Z_FIELD": "h", "HEIGHT_SOURCE": "z", "Z_DATUM": "ellipsoid", "OUTPUT": str(out)})


def test_importlines_writes_ground_and_image_lines_with_apriori_offsets(provider, roads):  # noqa: F811
    result, folder = roads
    out = folder / "control_lines.gpkg"
    _import(provider, result, out)
    ds = ogr.Open(str(out))
    ground, image = ds.GetLayer("ground_lines"), ds.GetLayer("image_lines")
    assert ground.GetFeatureCount() == 20
    assert image.GetFeatureCount() >= 20
    # the onboard model is ~400 m off: a-priori across-line offsets are tens to hundreds of metres
    rms = [f.GetField("apriori_rms_m") for f in ground if f.GetField("apriori_rms_m") is not None]
    assert len(rms) == 20 and 10.0 < sorted(rms)[10] < 2000.0


def test_bundleadjust_with_lines_names_the_wrong_ones(provider, roads):  # noqa: F811
    import processing
    result, folder = roads
    lines = folder / "control_lines_ba.gpkg"
    _import(provider, result, lines)
    gcps = folder / "gcps.gpkg"
    _gcps(provider, result, gcps)
    residuals = folder / "line_residuals.gpkg"
    res = processing.run("pushbroom:bundleadjust", {
        "SCENE": str(result.onboard_scene), "GCPS": str(gcps), "LINES": str(lines),
        "POSITION_MODEL": "polynomial", "POSITION_ORDER": 1, "ATTITUDE_MODEL": "polynomial", "ATTITUDE_ORDER": 2,
        "OUTPUT_SCENE": str(folder / "adjusted.json"), "OUTPUT_REPORT": str(folder / "report.html"),
        "OUTPUT_LINE_RESIDUALS": str(residuals)})
    import json
    rep = json.loads(open(res["OUTPUT_REPORT_JSON"]).read())
    truth = ogr.Open(str(result.lines))
    wrong = {f.GetField("line_id") for f in truth.GetLayer("ground_lines")
             if (f.GetField("kind") or "correct") != "correct"}
    assert wrong and set(rep["lines"]["flagged_line_ids"]) == wrong
    assert rep["check_points"]["ground"]["rmse"] < 5.0
    ds = ogr.Open(str(residuals))
    flagged = {f.GetField("line_id") for f in ds.GetLayer("ground_lines") if f.GetField("flagged") == 1}
    assert flagged == wrong
    assert ds.GetLayer("line_points").GetFeatureCount() == rep["lines"]["points"]


def test_importlines_runs_from_qgis_process(qgis_process, roads, tmp_path):  # noqa: F811
    result, _ = roads
    out = tmp_path / "cl.gpkg"
    done = qgis_process("run", "pushbroom:importlines", "--", f"SCENE={result.onboard_scene}",
                        f"INPUT={result.lines}|layername=ground_lines",
                        f"IMAGE_LINES={result.lines}|layername=image_lines", "HEIGHT_SOURCE=z",
                        "Z_DATUM=ellipsoid", f"OUTPUT={out}")
    assert done.returncode == 0, done.stderr + done.stdout
    ds = ogr.Open(str(out))
    assert ds.GetLayer("ground_lines").GetFeatureCount() == 20


def test_bundleadjust_with_lines_runs_from_qgis_process(provider, qgis_process, roads, tmp_path):  # noqa: F811
    import json
    result, folder = roads
    lines, gcps = tmp_path / "cl.gpkg", tmp_path / "gcps.gpkg"
    _import(provider, result, lines)
    _gcps(provider, result, gcps)
    done = qgis_process("run", "pushbroom:bundleadjust", "--", f"SCENE={result.onboard_scene}", f"GCPS={gcps}",
                        f"LINES={lines}", "POSITION_MODEL=polynomial", "POSITION_ORDER=1",
                        "ATTITUDE_MODEL=polynomial", "ATTITUDE_ORDER=2", f"OUTPUT_SCENE={tmp_path / 'a.json'}",
                        f"OUTPUT_REPORT={tmp_path / 'r.html'}", f"OUTPUT_LINE_RESIDUALS={tmp_path / 'lr.gpkg'}")
    assert done.returncode == 0, done.stderr + done.stdout
    assert "control lines:" in done.stdout and "released" in done.stdout + done.stderr
    rep = json.loads((tmp_path / "r.json").read_text())
    assert rep["lines"]["flagged_lines"] == 2 and (tmp_path / "lr.gpkg").is_file()
