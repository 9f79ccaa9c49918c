"""Hostile input to pushbroom:preparedigitising: each case a bad input refused with a message naming
the parameter and what was expected, the raw image, the scene and the output folder unchanged
(no display copy, no layer, no temporary file)."""
import shutil
from pathlib import Path

import pytest
from osgeo import gdal

from pushbroom_adjust.core.formats import load_scene

from tests.support.digitising import blank_raw_image
from tests.support.hostile import assert_refused, assert_refused_cli

ALG = "pushbroom:preparedigitising"


@pytest.fixture
def case(simulated, tmp_path) -> tuple[Path, dict]:
    """(folder with the scene and a blank raw image of its camera's size, valid parameters)."""
    shutil.copy(simulated["ONBOARD_SCENE"], tmp_path / "scene.json")
    camera = load_scene(tmp_path / "scene.json").cameras[0]
    blank_raw_image(tmp_path / "raw.tif", camera.cols, camera.rows)
    return tmp_path, {"INPUT": str(tmp_path / "raw.tif"), "SCENE": str(tmp_path / "scene.json"), "CAMERA": "",
                      "OUTPUT": str(tmp_path / "display.vrt"), "OUTPUT_LINES": str(tmp_path / "lines.gpkg")}


def _cropped(d: Path) -> dict:
    gdal.Translate(str(d / "crop.tif"), str(d / "raw.tif"), srcWin=[0, 0, 1000, 500])
    return {"INPUT": str(d / "crop.tif")}


def _one_column_more(d: Path) -> dict:
    ds = gdal.Open(str(d / "raw.tif"))
    blank_raw_image(d / "wider.tif", ds.RasterXSize + 1, ds.RasterYSize)
    return {"INPUT": str(d / "wider.tif")}


def _not_a_raster(d: Path) -> dict:
    (d / "notes.tif").write_text("not an image\n")
    return {"INPUT": str(d / "notes.tif")}


CASES = {
    # (parameters changed, texts the message must hold)
    "raster not the camera's size": (_cropped, ("INPUT", "1000 x 500 pixels", "camera HRC")),
    "one column more than the camera": (_one_column_more, ("INPUT", "camera HRC of the scene delivers")),
    "input not a raster": (_not_a_raster, ("INPUT",)),
    "scene without the camera": (lambda d: {"CAMERA": "NAD"}, ("CAMERA", "'NAD' is not in this scene", "HRC")),
    "camera index beyond the scene": (lambda d: {"CAMERA": "3"}, ("CAMERA",)),
    "scene file missing": (lambda d: {"SCENE": str(d / "gone.json")}, ("SCENE",)),
    "scene is the raw image": (lambda d: {"SCENE": str(d / "raw.tif")}, ("SCENE",)),
    "display copy replaces the raw image": (lambda d: {"OUTPUT": str(d / "raw.tif")}, ("OUTPUT", "INPUT")),
    "display copy replaces the scene": (lambda d: {"OUTPUT": str(d / "scene.json")}, ("OUTPUT", "SCENE")),
    "line layer is the display copy": (lambda d: {"OUTPUT_LINES": str(d / "display.vrt")},
                                       ("OUTPUT_LINES", "OUTPUT")),
    "display copy not a .vrt": (lambda d: {"OUTPUT": str(d / "display.tif")}, ("use a .vrt file name",)),
    "line layer not a GeoPackage": (lambda d: {"OUTPUT_LINES": str(d / "lines.shp")}, ("GeoPackage", ".gpkg")),
    "output folder missing": (lambda d: {"OUTPUT": str(d / "nowhere" / "display.vrt")}, ("OUTPUT", "does not exist")),
}


@pytest.mark.parametrize("name", CASES)
def test_prepare_digitising_refuses(name, case):
    folder, params = case
    change, texts = CASES[name]
    params = {**params, **change(folder)}
    assert_refused(ALG, params, *texts, watch=[folder])


def test_prepare_digitising_refuses_through_the_command_line(case, qgis_process):
    folder, params = case
    # QGIS saves approximate statistics beside a raster layer it loads without any (raw.tif.aux.xml,
    # GDAL's side file, not written by the plugin): computed here first, QGIS leaves them alone
    raw = gdal.Open(params["INPUT"])  # kept open while its band is used
    raw.GetRasterBand(1).ComputeStatistics(True)
    raw = None
    assert_refused_cli(qgis_process, ALG, {**params, "CAMERA": "NAD"}, "CAMERA", "not in this scene", watch=[folder])
