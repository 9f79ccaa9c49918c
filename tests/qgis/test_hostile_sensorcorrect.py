"""Hostile input to pushbroom:sensorcorrect: each case a bad input refused with a message naming
what is wrong, its inputs and output folder unchanged (no partial image, RPC, VRT or scene)."""
import shutil
from pathlib import Path

import pytest
from osgeo import gdal

from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.formats.scene_json import save_scene
from tests.support.paths import TEST_DATA
from tests.support.ortho_compare import saved_cut
from tests.support.rpcdata import pleiades_rpc, rpc_files, scaled

from tests.support.hostile import assert_refused, assert_refused_cli

ALG = "pushbroom:sensorcorrect"


@pytest.fixture(scope="module")
def sources(tmp_path_factory) -> Path:
    """A rendered 120-row cut of a CBERS-02B true camera: cut.json, raw.tif, dem.tif."""
    folder = tmp_path_factory.mktemp("sc_sources")
    assert saved_cut(folder, seed=6, rows=120)[2] == str(folder / "dem.tif")
    return folder


@pytest.fixture
def case(sources, tmp_path) -> tuple[Path, dict]:
    """(folder with copies of the inputs, valid parameters writing into it)."""
    for name in ("cut.json", "raw.tif", "dem.tif"):
        shutil.copy(sources / name, tmp_path / name)
    return tmp_path, {"INPUT": str(tmp_path / "raw.tif"), "SCENE": str(tmp_path / "cut.json"),
                      "DEM": str(tmp_path / "dem.tif"), "DEM_DATUM": "geoid", "OUTPUT": str(tmp_path / "sc.tif"),
                      "OUTPUT_SCENE": str(tmp_path / "sc.json")}


def _wrong_size(d: Path) -> dict:
    gdal.Translate(str(d / "small.tif"), str(d / "raw.tif"), srcWin=[0, 0, 1000, 120])
    return {"INPUT": str(d / "small.tif")}


def _other_scene_length(d: Path) -> dict:
    scene = load_scene(d / "cut.json")
    scene.cameras[0].rows = 500
    save_scene(scene, d / "long.json")
    return {"SCENE": str(d / "long.json")}


def _dem_not_covering(d: Path) -> dict:
    src = gdal.Open(str(d / "dem.tif"))
    gdal.Translate(str(d / "west.tif"), src, srcWin=[0, 0, src.RasterXSize // 3, src.RasterYSize])
    return {"DEM": str(d / "west.tif")}


def _rpc_scene(d: Path) -> dict:
    files = rpc_files(d, scaled(pleiades_rpc(TEST_DATA), 16.0), name="rpc")
    return {"SCENE": str(files["txt"]), "INPUT": str(files["tif"])}


CASES = {
    # an RPC-only scene: no physical camera to correct (its image already has one smooth RPC)
    "RPC scene": (_rpc_scene, ["SCENE", "RPC scene", "rigorous"]),
    # a raster of another size than the camera images: not this camera's image
    "raw image of another size": (_wrong_size, ["raster is 1000 x 120 px", "camera HRC"]),
    # a scene whose camera images more rows than the raster has
    "scene of another image length": (_other_scene_length, ["raster is 12246 x 120 px", "12246 x 500"]),
    # the output over the raw image it reads
    "output over the input": (lambda d: {"OUTPUT": str(d / "raw.tif")}, ["OUTPUT", "INPUT"]),
    # the virtual scene over the scene it reads
    "output scene over the scene": (lambda d: {"OUTPUT_SCENE": str(d / "cut.json")}, ["OUTPUT_SCENE", "SCENE"]),
    # the RPC sidecar the image would get is an input (the DEM renamed to it)
    "derived RPC over an input": (lambda d: {"DEM": str(shutil.copy(d / "dem.tif", d / "x_RPC.TXT")),
                                             "OUTPUT": str(d / "x.tif")}, ["its RPC", "DEM"]),
    # a DEM covering a third of the scene
    "DEM not covering the scene": (_dem_not_covering, ["west.tif", "does not cover"]),
    # a camera the scene does not have
    "unknown camera": (lambda d: {"CAMERA": "PAN"}, ["CAMERA", "'PAN' is not in this scene", "HRC"]),
    # an output format the writer does not make
    "output not GeoTIFF": (lambda d: {"OUTPUT": str(d / "sc.png")}, ["OUTPUT", "GeoTIFF"]),
    # a resampling by option number / unknown name
    "unknown resampling": (lambda d: {"RESAMPLING": "lanczos"}, ["RESAMPLING", "nearest", "bilinear", "cubic"]),
}


@pytest.mark.parametrize("name", list(CASES))
def test_hostile_sensorcorrect(provider, case, name):
    d, params = case
    change, texts = CASES[name]
    changed = change(d)
    assert_refused(ALG, {**params, **changed}, *texts, watch=[d])


def test_hostile_sensorcorrect_cli_output_over_input(qgis_process, case):
    """The same from qgis_process; QGIS itself may add its statistics cache (*.aux.xml) of the
    rasters it opens as layers, so the inputs are watched file by file."""
    d, params = case
    inputs = [d / name for name in ("cut.json", "raw.tif", "dem.tif")]
    assert_refused_cli(qgis_process, ALG, {**params, "OUTPUT": params["INPUT"]}, "OUTPUT", "INPUT", watch=inputs)
    assert {p.name for p in d.iterdir()} - {"raw.tif.aux.xml", "dem.tif.aux.xml"} == {p.name for p in inputs}
