"""pushbroom:exportrpc in real QGIS (processing.run) and on the command line (qgis_process), on the
small simulated CBERS-02B scene (three staggered CCDs): files GDAL reads, per-CCD figures, bad input."""
import json
from pathlib import Path

import numpy as np
import pytest
from osgeo import gdal
from qgis.core import QgsProcessingException

import processing
from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.products.rpcfit import dem_height_range, fit_rpc
from pushbroom_adjust.core.formats import load_scene

from tests.support.qgis_process import run_json
from tests.support.processing import RecordingFeedback

gdal.UseExceptions()


def _image(path, cols, rows) -> Path:
    ds = gdal.GetDriverByName("GTiff").Create(str(path), cols, rows, 1, gdal.GDT_Byte, ["SPARSE_OK=YES"])
    del ds  # closes the file
    return path


def test_export_with_a_dem_reports_every_ccd(simulated, tmp_path):
    out = tmp_path / "hrc_RPC.TXT"
    feedback = RecordingFeedback()
    res = processing.run("pushbroom:exportrpc", {"SCENE": simulated["TRUE_SCENE"], "DEM": simulated["DEM"],
                                                 "DEM_DATUM": "geoid", "OUTPUT": str(out)}, feedback=feedback)
    assert Path(res["OUTPUT"]) == out and out.is_file() and res["IMAGE_WITH_RPC"] in (None, "")
    report = json.loads(Path(res["REPORT"]).read_text())
    assert [c["chip"] for c in report["check"]["chips"]] == [0, 1, 2]
    assert res["RMS_PX"] == pytest.approx(report["check"]["rms_px"])
    assert any("cannot model the steps" in w for w in feedback.warnings)
    # the seams are missed by far more than 0.1 px: the log points to the sensor-corrected product
    seams = report["check"]["seams"]
    assert seams["max_px"] > 0.5
    (hint,) = [w for w in feedback.warnings if "pushbroom:sensorcorrect" in w]
    assert f"up to {seams['max_px']:.2f} px at the CCD seams" in hint
    assert sum("CCD" in i for i in feedback.infos) == 3
    # the same as the core with the DEM's height range
    scene = load_scene(simulated["TRUE_SCENE"])
    heights = dem_height_range(scene, Dem(simulated["DEM"], "geoid"), 0)
    assert report["height_range"] == pytest.approx(list(heights))
    rpc, core_report = fit_rpc(scene, 0, heights)
    assert report["check"]["rms_px"] == pytest.approx(core_report["check"]["rms_px"], rel=1e-9)
    # GDAL reads the file for an image of that name
    md = gdal.Open(str(_image(tmp_path / "hrc.tif", 16, 16))).GetMetadata("RPC")
    assert float(md["LINE_OFF"].split()[0]) == rpc.line_off
    assert md["SAMP_NUM_COEFF"].split() == [repr(float(v)) for v in rpc.samp_num]


def test_export_without_a_dem_writes_an_rpb_and_a_vrt_of_the_image(simulated, tmp_path):
    scene = load_scene(simulated["TRUE_SCENE"])
    cam = scene.cameras[0]
    image = _image(tmp_path / "raw.tif", cam.cols, cam.rows)
    before = image.stat().st_mtime_ns, image.stat().st_size
    out = tmp_path / "products" / "scene.RPB"
    out.parent.mkdir()
    res = processing.run("pushbroom:exportrpc", {"SCENE": simulated["TRUE_SCENE"], "CAMERA": "HRC", "HEIGHT": 600.0,
                                                 "HEIGHT_SPAN": 300.0, "IMAGE": str(image), "OUTPUT": str(out)})
    report = json.loads(Path(res["REPORT"]).read_text())
    assert report["height_range"] == [300.0, 900.0]
    assert 'SpecId = "RPC00B";' in out.read_text()
    vrt = Path(res["IMAGE_WITH_RPC"])
    assert vrt == out.with_name("scene.vrt")
    ds = gdal.Open(str(vrt))
    assert (ds.RasterXSize, ds.RasterYSize) == (cam.cols, cam.rows) and "LINE_NUM_COEFF" in ds.GetMetadata("RPC")
    assert (image.stat().st_mtime_ns, image.stat().st_size) == before
    # only QGIS's own statistics cache (raw.tif.aux.xml, written when it opens any raster layer) may appear
    assert {p.name for p in tmp_path.iterdir()} - {"raw.tif.aux.xml"} == {"products", "raw.tif"}
    assert sorted(p.name for p in out.parent.iterdir()) == ["scene.RPB", "scene.RPB.json", "scene.vrt"]


def test_bad_input_is_named(simulated, tmp_path):
    base = {"SCENE": simulated["TRUE_SCENE"], "OUTPUT": str(tmp_path / "x_RPC.TXT")}
    with pytest.raises(QgsProcessingException, match=r"CAMERA: camera 'PAN' is not in this scene"):
        processing.run("pushbroom:exportrpc", {**base, "CAMERA": "PAN"})
    small = tmp_path / "small.tif"
    _image(small, 10, 10)
    with pytest.raises(QgsProcessingException, match=r"IMAGE: .*not this camera's image"):
        processing.run("pushbroom:exportrpc", {**base, "IMAGE": str(small)})
    with pytest.raises(QgsProcessingException, match=r"OUTPUT: .* must end in _RPC.TXT"):
        processing.run("pushbroom:exportrpc", {**base, "OUTPUT": str(tmp_path / "x.json")})
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    with pytest.raises(QgsProcessingException, match=r"OUTPUT: cannot write"):
        processing.run("pushbroom:exportrpc", {**base, "OUTPUT": str(blocker / "x_RPC.TXT")})
    assert {p.name for p in tmp_path.iterdir()} - {"small.tif.aux.xml"} == {"a_file", "small.tif"}


def test_a_dem_that_does_not_cover_the_scene(simulated, tmp_path):
    dem = tmp_path / "far.tif"
    src = gdal.Open(simulated["DEM"])
    ds = gdal.GetDriverByName("GTiff").CreateCopy(str(dem), src)
    gt = list(src.GetGeoTransform())
    gt[0] += 20.0  # 20 degrees east of the scene
    ds.SetGeoTransform(gt)
    ds = None
    out = tmp_path / "x_RPC.TXT"
    with pytest.raises(QgsProcessingException, match=r"DEM: DEM .*far\.tif does not cover camera 'HRC'"):
        processing.run("pushbroom:exportrpc", {"SCENE": simulated["TRUE_SCENE"], "DEM": str(dem), "OUTPUT": str(out)})
    assert not out.exists()


def test_run_exportrpc_from_the_command_line(qgis_process, simulated, tmp_path):
    out = tmp_path / "scene_RPC.TXT"
    results = run_json(qgis_process, "pushbroom:exportrpc", SCENE=simulated["TRUE_SCENE"], HEIGHT=700,
                        HEIGHT_SPAN=600, GRID=21, OUTPUT=out)
    assert Path(results["OUTPUT"]) == out
    report = json.loads(Path(results["REPORT"]).read_text())
    assert report["grid"] == [21, 21, 7] and report["height_range"] == [100.0, 1300.0]
    assert len(report["check"]["chips"]) == 3 and np.isfinite(results["MAX_PX"])
    help_text = qgis_process("help", "pushbroom:exportrpc").stdout
    assert "HEIGHT_SPAN" in help_text and "_RPC.TXT" in help_text
