"""pushbroom:sensorcorrect in QGIS and from qgis_process, on a rendered cut of the simulated
CBERS-02B true (misaligned) camera: the seamless image, its RPC (sidecar and VRT) exact to
hundredths of a pixel, and its virtual scene readable as SCENE by the other algorithms."""
import json
from pathlib import Path

import numpy as np
import pytest
from osgeo import gdal

import processing
from pushbroom_adjust.core.formats import load_scene

from tests.support.ortho_compare import saved_cut

from tests.support.processing import RecordingFeedback
from tests.support.qgis_process import run_json


@pytest.fixture(scope="module")
def raw(tmp_path_factory):
    """(scene JSON, raw image, DEM) of a 300-row cut of a CBERS-02B scene's true camera, rendered."""
    return saved_cut(tmp_path_factory.mktemp("raw"), seed=5, rows=300)


def test_sensorcorrect_with_processing_run(provider, raw, tmp_path):
    scene, image, dem = raw
    feedback = RecordingFeedback()
    out = processing.run("pushbroom:sensorcorrect", {"INPUT": image, "SCENE": scene, "DEM": dem, "DEM_DATUM": "geoid",
                                                     "RESAMPLING": "cubic", "OUTPUT": str(tmp_path / "sc.tif"),
                                                     "OUTPUT_SCENE": str(tmp_path / "sc.json")}, feedback=feedback)
    assert out["OUTPUT"] == str(tmp_path / "sc.tif") and out["OUTPUT_SCENE"] == str(tmp_path / "sc.json")
    assert out["RPC"] == str(tmp_path / "sc_RPC.TXT") and out["IMAGE_WITH_RPC"] == str(tmp_path / "sc.vrt")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sc.json", "sc.tif", "sc.vrt", "sc_RPC.TXT",
                                                          "sc_RPC.TXT.json"]
    assert out["MAX_PX"] < 0.01 and json.loads(Path(out["REPORT"]).read_text())["check"]["max_px"] == out["MAX_PX"]
    ds = gdal.Open(out["OUTPUT"])
    assert (ds.RasterXSize, ds.RasterYSize) == (12246, 300) and "LINE_NUM_COEFF" in ds.GetMetadata("RPC")
    vrt = gdal.Open(out["IMAGE_WITH_RPC"])
    line_off = [float(m.GetMetadata("RPC")["LINE_OFF"].split()[0]) for m in (vrt, ds)]  # the TXT says 'pixels'
    assert line_off[0] == line_off[1] == 150.0
    data = vrt.GetRasterBand(1).ReadAsArray()
    assert np.mean(data[5:-5, 5:-5] > 0) > 0.999  # seamless: every inner pixel sees the ground
    virtual = load_scene(out["OUTPUT_SCENE"])
    assert len(virtual.cameras[0].chips) == 1 and virtual.info["sensor_corrected"]["source_scene"] == scene
    assert any("independent check RMS" in m for m in feedback.infos), feedback.infos


def test_virtual_scene_serves_as_scene_for_the_other_algorithms(provider, raw, tmp_path):
    """Orthorectifying the sensor-corrected image with its virtual scene."""
    scene, image, dem = raw
    sc = processing.run("pushbroom:sensorcorrect", {"INPUT": image, "SCENE": scene, "HEIGHT": 800.0,
                                                    "OUTPUT": str(tmp_path / "sc.tif"),
                                                    "OUTPUT_SCENE": str(tmp_path / "sc.json")})
    assert load_scene(sc["OUTPUT_SCENE"]).info["sensor_corrected"]["surface"] == "constant ellipsoidal height 800 m"
    ortho = processing.run("pushbroom:orthorectify", {"INPUT": sc["OUTPUT"], "SCENE": sc["OUTPUT_SCENE"],
                                                      "DEM": dem, "RESOLUTION": 10,
                                                      "OUTPUT": str(tmp_path / "o.tif")})["OUTPUT"]
    ds = gdal.Open(ortho)
    assert 0.05 < np.mean(ds.GetRasterBand(1).ReadAsArray() > 0) < 0.5


def test_sensorcorrect_from_the_command_line(qgis_process, raw, tmp_path):
    scene, image, dem = raw
    results = run_json(qgis_process, "pushbroom:sensorcorrect", INPUT=image, SCENE=scene, DEM=dem,
                        DEM_DATUM="geoid", RESAMPLING="bilinear", OUTPUT=tmp_path / "c.tif",
                        OUTPUT_SCENE=tmp_path / "c.json")
    ds = gdal.Open(results["OUTPUT"])
    assert ds.RasterCount == 1 and "SAMP_NUM_COEFF" in ds.GetMetadata("RPC")
    assert results["MAX_PX"] < 0.01 and Path(results["OUTPUT_SCENE"]).is_file()
