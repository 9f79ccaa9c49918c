"""Hostile input to pushbroom:orthorectify over every camera (ALL_CAMERAS, INPUTS, ORTHO_FOLDER)
and to its SCHEDULER: refused before any work with a message naming the parameter, every
watched file and folder unchanged; or, where the request is legitimate, done right.

The scene is a 96-row cut of a simulated TH-1 three-line scene (cameras NAD, FWD, BWD of
12000 x 96 px); refusals come before any pixel is read, so the raw images are blank rasters
of the cameras' size.
"""
import shutil
import socket
from dataclasses import replace
from pathlib import Path

import pytest
from osgeo import gdal

from pushbroom_adjust.core.formats import load_scene
from pushbroom_adjust.core.formats.scene_json import save_scene
from pushbroom_adjust.simulation.simulator import simulate

from tests.support.hostile import assert_refused, assert_refused_cli, snapshot

ALG = "pushbroom:orthorectify"
CAMERAS = ("NAD", "FWD", "BWD")


def _blank(path: Path, cols: int, rows: int) -> str:
    gdal.GetDriverByName("GTiff").Create(str(path), cols, rows, 1, gdal.GDT_Byte, ["COMPRESS=DEFLATE"]).FlushCache()
    return str(path)


@pytest.fixture(scope="module")
def sources(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("tlc")
    result = simulate("th1_tlc", folder / "sim", seed=6, n_gcps=5)
    full = load_scene(result.true_scene)
    save_scene(replace(full, cameras=[replace(c, rows=96) for c in full.cameras], _guess={}), folder / "cut.json")
    shutil.copy(result.dem, folder / "dem.tif")
    for name in CAMERAS:
        _blank(folder / f"raw_{name}.tif", 12000, 96)
    return folder


@pytest.fixture
def d(sources, tmp_path) -> Path:
    """A private copy of the sources for one case."""
    folder = tmp_path / "d"
    shutil.copytree(sources, folder, ignore=shutil.ignore_patterns("sim"))
    return folder


def _params(d: Path, **kw) -> dict:
    return {"SCENE": str(d / "cut.json"), "DEM": str(d / "dem.tif"), "RESOLUTION": 200.0, "ALL_CAMERAS": True,
            "INPUTS": [str(d / f"raw_{c}.tif") for c in CAMERAS], "ORTHO_FOLDER": str(d / "out"), **kw}


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_fewer_images_than_cameras(provider, d):
    assert_refused(ALG, _params(d, INPUTS=[str(d / "raw_NAD.tif"), str(d / "raw_FWD.tif")]),
                   "INPUTS: 2 raw image(s) given", "3 camera(s) (NAD, FWD, BWD)", watch=[d])


def test_all_cameras_without_images(provider, d):
    params = _params(d)
    del params["INPUTS"]
    assert_refused(ALG, params, "INPUTS: 0 raw image(s) given", watch=[d])


def test_an_image_of_the_wrong_size_for_its_camera(provider, d):
    _blank(d / "small.tif", 4096, 96)
    assert_refused(ALG, _params(d, INPUTS=[str(d / "raw_NAD.tif"), str(d / "small.tif"), str(d / "raw_BWD.tif")]),
                   "INPUTS:", "small.tif: the raster is 4096 x 96 px but camera FWD", watch=[d])


def test_the_output_folder_is_the_inputs_folder_with_a_clashing_name(provider, d):
    """An input called ortho_FWD.tif in ORTHO_FOLDER: the FWD orthoimage would replace it."""
    shutil.move(d / "raw_FWD.tif", d / "ortho_FWD.tif")
    assert_refused(ALG, _params(d, INPUTS=[str(d / "raw_NAD.tif"), str(d / "ortho_FWD.tif"), str(d / "raw_BWD.tif")],
                                ORTHO_FOLDER=str(d)), "ORTHO_FOLDER", "INPUTS", "ortho_FWD.tif", watch=[d])


def test_an_output_folder_whose_parent_is_missing(provider, d):
    assert_refused(ALG, _params(d, ORTHO_FOLDER=str(d / "no" / "such")), "does not exist", watch=[d])


def test_an_output_folder_that_is_a_file(provider, d):
    """Not 'folder ... does not exist': ORTHO_FOLDER names a file."""
    (d / "notes.txt").write_text("a file\n")
    assert_refused(ALG, _params(d, ORTHO_FOLDER=str(d / "notes.txt")), f"ORTHO_FOLDER: {d / 'notes.txt'} is a file, "
                   "not a folder", watch=[d])


def test_no_image_without_all_cameras(provider, d):
    params = _params(d, ALL_CAMERAS=False, OUTPUT=str(d / "o.tif"))
    assert_refused(ALG, params, "INPUT: no raw image given", "ALL_CAMERAS", watch=[d])


def test_an_unreachable_scheduler(provider, d):
    port = _free_port()
    assert_refused(ALG, _params(d, SCHEDULER=f"tcp://127.0.0.1:{port}"), "SCHEDULER", f"tcp://127.0.0.1:{port}",
                   watch=[d])
    assert not (d / "out").exists()  # the folder the run would have created is gone again


def test_an_unreachable_scheduler_from_the_command_line(qgis_process, d):
    params = _params(d, SCHEDULER=f"tcp://127.0.0.1:{_free_port()}")
    images = params.pop("INPUTS")
    before = snapshot(d)
    done = qgis_process("run", ALG, "--", *(f"{k}={v}" for k, v in params.items()), *(f"INPUTS={i}" for i in images))
    text = done.stdout + done.stderr
    assert done.returncode != 0 and "Traceback" not in text and "SCHEDULER" in text, text
    # only QGIS's own statistics caches (*.aux.xml, written when it opens a raster layer) may appear
    assert {k: v for k, v in snapshot(d).items() if not k.endswith(".aux.xml")} == before


def test_a_single_camera_run_with_a_bad_scheduler_from_the_command_line(qgis_process, d):
    assert_refused_cli(qgis_process, ALG, {"SCENE": d / "cut.json", "INPUT": d / "raw_FWD.tif", "CAMERA": "FWD",
                                           "HEIGHT": 100, "OUTPUT": d / "o.tif", "SCHEDULER": "not an address"},
                       "SCHEDULER", watch=[d / "cut.json", d / "raw_FWD.tif", d / "o.tif"])
