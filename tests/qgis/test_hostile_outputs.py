"""Hostile and careless outputs: every output path given over an input, over another output
(derived files included), into a missing or read-only folder, onto a full disk, over a user's
files, through symlinks and other spellings — refused before any work with a message naming
both parameters and every watched file unchanged; or, where the request is legitimate, done
right (a symlinked destination written through, a user's file at an old temporary name kept,
optional outputs left out).

Each case gets its own folder ``d`` with copies of the inputs (d/scene.json, d/dem.tif,
d/gcps.gpkg, d/gcps.csv, d/pixels.csv, d/cut.json + d/raw.tif for orthorectify) and watches it
whole: nothing there may change, appear or disappear.
"""
import json
import os
import shutil
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest
from osgeo import gdal
from qgis.core import QgsProcessingException, QgsProcessingFeedback, QgsProject, QgsRasterLayer, QgsVectorLayer

import processing
from pushbroom_adjust.core.formats.scene_json import save_scene
from tests.support.mounts import read_only_folder, tiny_disk
from tests.support.ortho_compare import rendered_cut

from tests.support.hostile import assert_clean_stderr, assert_refused, assert_refused_cli, no_unraisable, snapshot


@pytest.fixture(scope="module")
def sources(simulated, tmp_path_factory) -> Path:
    """The inputs every case copies: the simulated scene, DEM, GCPs (CSV and imported), image
    points, and a rendered 200-row cut with its raw image."""
    folder = tmp_path_factory.mktemp("sources")
    shutil.copy(simulated["ONBOARD_SCENE"], folder / "scene.json")
    shutil.copy(simulated["DEM"], folder / "dem.tif")
    shutil.copy(simulated["GCPS"], folder / "gcps.csv")
    processing.run("pushbroom:importgcps", {"SCENE": str(folder / "scene.json"), "INPUT_FILE": str(folder / "gcps.csv"),
                                            "Z_FIELD": "h", "Z_DATUM": "ellipsoid", "OUTPUT": str(folder / "gcps.gpkg")})
    (folder / "pixels.csv").write_text("id,col,row\n" + "".join(f"{i},{100 + 50 * i},{200 + 40 * i}\n"
                                                               for i in range(20)))
    cut = tmp_path_factory.mktemp("cut")
    scene, _, _, _ = rendered_cut(cut, seed=4, rows=200)
    save_scene(scene, folder / "cut.json")
    shutil.copy(cut / "raw.tif", folder / "raw.tif")
    return folder


@pytest.fixture
def d(sources, tmp_path) -> Path:
    """This case's folder: a fresh copy of the sources (and d/out); layers the case loaded into
    the project are removed after it."""
    folder = tmp_path / "d"
    shutil.copytree(sources, folder)
    (folder / "out").mkdir()
    yield folder
    QgsProject.instance().removeAllMapLayers()


def _loaded(layer):
    """``layer`` loaded into the project (which owns it), as a user's open layer."""
    assert layer.isValid()
    return QgsProject.instance().addMapLayer(layer)


def _ortho(d, **kw) -> dict:
    return {"INPUT": str(d / "raw.tif"), "SCENE": str(d / "cut.json"), "DEM": str(d / "dem.tif"), "RESOLUTION": 20.0,
            "OUTPUT": str(d / "out" / "ortho.tif"), **kw}


def _adjust(d, **kw) -> dict:
    return {"SCENE": str(d / "scene.json"), "GCPS": str(d / "gcps.gpkg"), "POSITION_ORDER": 0,
            "OUTPUT_SCENE": str(d / "out" / "adjusted.json"), **kw}


def _import(d, **kw) -> dict:
    return {"SCENE": str(d / "scene.json"), "INPUT_FILE": str(d / "gcps.csv"), "Z_FIELD": "h", "Z_DATUM": "ellipsoid",
            "OUTPUT": str(d / "out" / "gcps.gpkg"), **kw}


def _rpc(d, **kw) -> dict:
    return {"SCENE": str(d / "scene.json"), "GRID": 11, "HEIGHT_LEVELS": 4, "OUTPUT": str(d / "out" / "image_RPC.TXT"),
            **kw}


def _link(d, name: str, target: str) -> str:
    (d / name).symlink_to(d / target)
    return str(d / name)


def _hard(d, name: str, target: str) -> str:
    os.link(d / target, d / name)
    return str(d / name)


def _renamed(d, source: str, name: str) -> str:
    shutil.copy(d / source, d / name)
    return str(d / name)


def _dir(d, name: str) -> str:
    (d / name).mkdir()
    return str(d / name)


def _busy(d, name: str) -> str:
    (d / f"{name}-wal").write_text("")
    return str(d / name)


def _vrt(d, name: str, source: str) -> str:
    """A VRT d/name showing d/source."""
    gdal.Translate(str(d / name), str(d / source), format="VRT")
    return str(d / name)


def _far_dem(d) -> str:
    """A 10 x 10 DEM far from the scene (which it does not cover)."""
    ds = gdal.GetDriverByName("GTiff").Create(str(d / "far.tif"), 10, 10, 1, gdal.GDT_Float32)
    ds.SetGeoTransform((-60.0, 0.01, 0, -30.0, 0, -0.01))
    ds.SetProjection("EPSG:4326")
    ds.GetRasterBand(1).Fill(100.0)
    ds = None
    return str(d / "far.tif")


# (id, algorithm, parameters from the case folder, texts the message must hold)
CASES = [
    # orthorectify: the example and the other spellings of the same files
    ("ortho-over-input", "orthorectify", lambda d: _ortho(d, OUTPUT=str(d / "raw.tif")), ["OUTPUT", "INPUT"]),
    ("ortho-over-dem", "orthorectify", lambda d: _ortho(d, OUTPUT=str(d / "dem.tif")), ["OUTPUT", "DEM"]),
    ("ortho-symlink-to-input", "orthorectify", lambda d: _ortho(d, OUTPUT=_link(d, "o.tif", "raw.tif")),
     ["OUTPUT", "the file of INPUT"]),
    ("ortho-hardlink-to-dem", "orthorectify", lambda d: _ortho(d, OUTPUT=_hard(d, "o.tif", "dem.tif")),
     ["OUTPUT", "the file of DEM"]),
    ("ortho-dotdot-spelling", "orthorectify", lambda d: _ortho(d, OUTPUT=os.path.join(d, "sub", "..", "raw.tif")),
     ["OUTPUT", "INPUT"]),
    ("ortho-input-as-loaded-layer", "orthorectify",
     lambda d: _ortho(d, INPUT=_loaded(QgsRasterLayer(str(d / "raw.tif"), "raw")), OUTPUT=str(d / "raw.tif")), ["INPUT"]),
    ("ortho-dem-as-loaded-layer", "orthorectify",
     lambda d: _ortho(d, DEM=_loaded(QgsRasterLayer(str(d / "dem.tif"), "dem")), OUTPUT=str(d / "dem.tif")), ["DEM"]),
    ("ortho-missing-folder", "orthorectify", lambda d: _ortho(d, OUTPUT=str(d / "nowhere" / "o.tif")),
     ["OUTPUT", "does not exist"]),
    ("ortho-output-is-a-folder", "orthorectify", lambda d: _ortho(d, OUTPUT=_dir(d, "o.tif")),
     ["OUTPUT", "it is a folder"]),
    ("ortho-output-is-a-device", "orthorectify", lambda d: _ortho(d, OUTPUT=_link(d, "null.tif", "/dev/null")),
     ["OUTPUT", "not a regular file"]),
    ("ortho-dem-not-covering", "orthorectify", lambda d: _ortho(d, DEM=_far_dem(d)), ["DEM"]),
    # bundleadjust: over its inputs, one output's derived file over another, missing folders
    ("adjust-scene-over-scene", "bundleadjust", lambda d: _adjust(d, OUTPUT_SCENE=str(d / "scene.json")),
     ["OUTPUT_SCENE", "the file of SCENE"]),
    ("adjust-gcps-over-gcps", "bundleadjust", lambda d: _adjust(d, OUTPUT_GCPS=str(d / "gcps.gpkg")),
     ["OUTPUT_GCPS", "the file of GCPS"]),
    ("adjust-gcps-over-loaded-layer", "bundleadjust",
     lambda d: _adjust(d, GCPS=_loaded(QgsVectorLayer(str(d / "gcps.gpkg"), "gcps", "ogr")), OUTPUT_GCPS=str(d / "gcps.gpkg")),
     ["OUTPUT_GCPS", "GCPS"]),
    ("adjust-residuals-over-gcps", "bundleadjust", lambda d: _adjust(d, OUTPUT_RESIDUALS=str(d / "gcps.gpkg")),
     ["OUTPUT_RESIDUALS", "GCPS"]),
    ("adjust-report-json-over-scene", "bundleadjust",
     lambda d: _adjust(d, OUTPUT_SCENE=str(d / "result.json"), OUTPUT_REPORT=str(d / "result.html")),
     ["OUTPUT_REPORT", "its JSON report", "OUTPUT_SCENE"]),
    ("adjust-report-json-over-input-scene", "bundleadjust", lambda d: _adjust(d, OUTPUT_REPORT=str(d / "scene.html")),
     ["OUTPUT_REPORT", "its JSON report", "SCENE"]),
    ("adjust-gcps-equals-residuals", "bundleadjust",
     lambda d: _adjust(d, OUTPUT_GCPS=str(d / "r.gpkg"), OUTPUT_RESIDUALS=str(d / "r.gpkg")),
     ["OUTPUT_RESIDUALS", "OUTPUT_GCPS"]),
    ("adjust-gcps-equals-residuals-other-spelling", "bundleadjust",
     lambda d: _adjust(d, OUTPUT_GCPS=str(d / "r.gpkg"), OUTPUT_RESIDUALS=os.path.join(d, ".", "out", "..", "r.gpkg")),
     ["OUTPUT_RESIDUALS", "OUTPUT_GCPS"]),
    ("adjust-scene-symlink-to-scene", "bundleadjust", lambda d: _adjust(d, OUTPUT_SCENE=_link(d, "l.json", "scene.json")),
     ["OUTPUT_SCENE", "SCENE"]),
    ("adjust-missing-folder", "bundleadjust", lambda d: _adjust(d, OUTPUT_SCENE=str(d / "nowhere" / "a.json")),
     ["OUTPUT_SCENE", "does not exist"]),
    ("adjust-report-missing-folder", "bundleadjust", lambda d: _adjust(d, OUTPUT_REPORT=str(d / "nowhere" / "r.html")),
     ["OUTPUT_REPORT", "does not exist"]),
    ("adjust-gcps-open-elsewhere", "bundleadjust", lambda d: _adjust(d, OUTPUT_GCPS=_busy(d, "busy.gpkg")),
     ["OUTPUT_GCPS", "open in another program"]),
    ("adjust-scene-is-a-folder", "bundleadjust", lambda d: _adjust(d, OUTPUT_SCENE=_dir(d, "a.json")),
     ["OUTPUT_SCENE", "it is a folder"]),
    # importgcps
    ("import-over-input-layer", "importgcps",
     lambda d: _import(d, INPUT_FILE=None, INPUT=str(d / "gcps.gpkg"), COL_FIELD="col", ROW_FIELD="row",
                       Z_FIELD="", OUTPUT=str(d / "gcps.gpkg")), ["OUTPUT", "the file of INPUT"]),
    ("import-over-loaded-input-layer", "importgcps",
     lambda d: _import(d, INPUT_FILE=None, INPUT=_loaded(QgsVectorLayer(str(d / "gcps.gpkg"), "g", "ogr")),
                       OUTPUT=str(d / "gcps.gpkg")), ["OUTPUT", "INPUT"]),
    ("import-over-symlinked-input", "importgcps",
     lambda d: _import(d, INPUT_FILE=None, INPUT=str(d / "gcps.gpkg"), OUTPUT=_link(d, "l.gpkg", "gcps.gpkg")),
     ["OUTPUT", "INPUT"]),
    ("import-over-csv-input", "importgcps", lambda d: _import(d, OUTPUT=str(d / "gcps.csv")), ["OUTPUT", ".gpkg"]),
    ("import-over-scene-named-gpkg", "importgcps",
     lambda d: _import(d, SCENE=_renamed(d, "scene.json", "scene.gpkg"), OUTPUT=str(d / "scene.gpkg")),
     ["OUTPUT", "SCENE"]),
    ("import-missing-folder", "importgcps", lambda d: _import(d, OUTPUT=str(d / "nowhere" / "g.gpkg")),
     ["OUTPUT", "does not exist"]),
    ("import-open-elsewhere", "importgcps", lambda d: _import(d, OUTPUT=_busy(d, "busy.gpkg")),
     ["OUTPUT", "open in another program"]),
    # feature sinks
    ("footprint-over-dem", "footprint", lambda d: {"SCENE": str(d / "scene.json"), "DEM": str(d / "dem.tif"),
                                                   "OUTPUT": str(d / "dem.tif")}, ["OUTPUT", "DEM"]),
    ("footprint-over-scene", "footprint", lambda d: {"SCENE": str(d / "scene.json"), "OUTPUT": str(d / "scene.json")},
     ["OUTPUT", "SCENE"]),
    ("footprint-missing-folder", "footprint",
     lambda d: {"SCENE": str(d / "scene.json"), "OUTPUT": str(d / "nowhere" / "f.gpkg")}, ["OUTPUT", "does not exist"]),
    ("footprint-error-leaves-no-geopackage", "footprint",
     lambda d: {"SCENE": str(d / "scene.json"), "DEM": _far_dem(d), "OUTPUT": str(d / "f.gpkg")}, ["DEM"]),
    ("imagetoground-over-input", "imagetoground",
     lambda d: {"SCENE": str(d / "scene.json"), "INPUT": str(d / "gcps.gpkg"), "OUTPUT": str(d / "gcps.gpkg")},
     ["OUTPUT", "INPUT"]),
    ("imagetoground-table-into-input", "imagetoground",
     lambda d: {"SCENE": str(d / "scene.json"), "INPUT": str(d / "gcps.gpkg"),
                "OUTPUT": f"ogr:dbname='{d / 'gcps.gpkg'}' table=\"ground\" (geom)"}, ["OUTPUT", "INPUT"]),
    ("imagetoground-over-csv-input", "imagetoground",
     lambda d: {"SCENE": str(d / "scene.json"), "INPUT": str(d / "pixels.csv"), "OUTPUT": str(d / "pixels.csv")},
     ["OUTPUT", "INPUT"]),
    ("imagetoground-error-leaves-nothing", "imagetoground",
     lambda d: {"SCENE": str(d / "scene.json"), "INPUT": str(d / "pixels.csv"), "DEM": _far_dem(d),
                "OUTPUT": str(d / "g.gpkg")}, ["DEM"]),
    ("groundtoimage-over-input", "groundtoimage",
     lambda d: {"SCENE": str(d / "scene.json"), "INPUT": str(d / "gcps.gpkg"), "OUTPUT": str(d / "gcps.gpkg")},
     ["OUTPUT", "INPUT"]),
    ("groundtoimage-over-loaded-input", "groundtoimage",
     lambda d: {"SCENE": str(d / "scene.json"), "INPUT": _loaded(QgsVectorLayer(str(d / "gcps.gpkg"), "g", "ogr")),
                "OUTPUT": str(d / "gcps.gpkg")}, ["OUTPUT", "INPUT"]),
    ("groundtoimage-over-dem", "groundtoimage",
     lambda d: {"SCENE": str(d / "scene.json"), "INPUT": str(d / "gcps.gpkg"), "DEM": str(d / "dem.tif"),
                "OUTPUT": str(d / "dem.tif")}, ["OUTPUT", "DEM"]),
    # exportrpc: the RPC, its report and the VRT beside it
    ("rpc-over-scene", "exportrpc", lambda d: _rpc(d, SCENE=_renamed(d, "scene.json", "s.RPB"), OUTPUT=str(d / "s.RPB")),
     ["OUTPUT", "SCENE"]),
    ("rpc-report-over-scene", "exportrpc",
     lambda d: _rpc(d, SCENE=_renamed(d, "scene.json", "x_RPC.TXT.json"), OUTPUT=str(d / "x_RPC.TXT")),
     ["OUTPUT", "its fit report", "SCENE"]),
    ("rpc-vrt-over-image", "exportrpc",
     lambda d: _rpc(d, IMAGE=_vrt(d, "img.vrt", "raw.tif"), OUTPUT=str(d / "img_RPC.TXT")), ["OUTPUT", "VRT", "IMAGE"]),
    ("rpc-vrt-over-dem", "exportrpc",
     lambda d: _rpc(d, IMAGE=str(d / "raw.tif"), DEM=_vrt(d, "raw.vrt", "dem.tif"), OUTPUT=str(d / "raw_RPC.TXT")),
     ["OUTPUT", "VRT", "DEM"]),
    ("rpc-output-symlink-to-scene", "exportrpc", lambda d: _rpc(d, OUTPUT=_link(d, "s_RPC.TXT", "scene.json")),
     ["OUTPUT", "SCENE"]),
    ("rpc-missing-folder", "exportrpc", lambda d: _rpc(d, OUTPUT=str(d / "nowhere" / "x_RPC.TXT")),
     ["OUTPUT", "does not exist"]),
    # simulatescene: a user's files in the output folder
    ("simulate-user-gcps-csv", "simulatescene",
     lambda d: {"N_GCPS": 5, "OUTPUT_FOLDER": str(d)}, ["OUTPUT_FOLDER", "gcps.csv", "dem.tif", "not replaced"]),
    ("simulate-folder-is-a-file", "simulatescene",
     lambda d: {"N_GCPS": 5, "OUTPUT_FOLDER": str(d / "scene.json")}, ["OUTPUT_FOLDER", "is a file"]),
]


@pytest.mark.parametrize("alg, make, texts", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_refused_before_any_work(provider, d, alg, make, texts):
    params = {k: v for k, v in make(d).items() if v is not None}
    assert_refused(f"pushbroom:{alg}", params, *texts, watch=[d])


# --- read-only folders and full disks ----------------------------------------------------------
READ_ONLY = [
    ("bundleadjust", lambda d, ro: _adjust(d, OUTPUT_SCENE=str(ro / "a.json")), "OUTPUT_SCENE"),
    ("bundleadjust", lambda d, ro: _adjust(d, OUTPUT_RESIDUALS=str(ro / "r.gpkg")), "OUTPUT_RESIDUALS"),
    ("orthorectify", lambda d, ro: _ortho(d, OUTPUT=str(ro / "o.tif")), "OUTPUT"),
    ("footprint", lambda d, ro: {"SCENE": str(d / "scene.json"), "OUTPUT": str(ro / "f.gpkg")}, "OUTPUT"),
    ("exportrpc", lambda d, ro: _rpc(d, OUTPUT=str(ro / "x_RPC.TXT")), "OUTPUT"),
    ("simulatescene", lambda d, ro: {"N_GCPS": 5, "OUTPUT_FOLDER": str(ro / "sim")}, "OUTPUT_FOLDER"),
]


@pytest.mark.parametrize("alg, make, name", READ_ONLY, ids=[f"{c[0]}-{c[2]}" for c in READ_ONLY])
def test_a_read_only_destination_is_refused_at_once(provider, d, alg, make, name):
    with read_only_folder(d / "ro") as ro:
        assert_refused(f"pushbroom:{alg}", make(d, ro), name, "not writable", watch=[d])


MANY = 10000  # image points: more than a 256 KiB disk holds as a layer


FULL_DISK = [
    ("footprint", lambda d, disk: {"SCENE": str(d / "scene.json"), "SAMPLES": 50000, "OUTPUT": str(disk / "f.gpkg")},
     "OUTPUT"),
    ("imagetoground", lambda d, disk: {"SCENE": str(d / "scene.json"), "INPUT": str(d / "many.csv"),
                                       "OUTPUT": str(disk / "g.gpkg")}, "OUTPUT"),
    ("groundtoimage", lambda d, disk: {"SCENE": str(d / "scene.json"), "OUTPUT": str(disk / "i.shp"), "INPUT":
                                       _loaded(QgsVectorLayer(f"file://{d / 'many.csv'}?type=csv&xField=lon&"
                                                              "yField=lat&crs=EPSG:4326", "many", "delimitedtext"))},
     "OUTPUT"),
    ("orthorectify", lambda d, disk: _ortho(d, OUTPUT=str(disk / "o.tif"), RESOLUTION=2.0), "o.tif"),
    ("bundleadjust", lambda d, disk: _adjust(d, OUTPUT_REPORT=str(disk / "r.html"), OUTPUT_GCPS=str(disk / "g.gpkg")),
     "OUTPUT_"),
    ("simulatescene", lambda d, disk: {"N_GCPS": 5, "OUTPUT_FOLDER": str(disk / "sim")}, "sim"),
    ("sensorcorrect", lambda d, disk: _sensorcorrect(d, OUTPUT=str(disk / "sc.tif"), OUTPUT_SCENE=str(disk / "s.json")),
     "sc.tif"),
    ("orthorectify-all-cameras", lambda d, disk: _all_cameras(d, disk / "orthos"), "ortho_HRC.tif"),
]


def _sensorcorrect(d, **kw) -> dict:
    return {"INPUT": str(d / "raw.tif"), "SCENE": str(d / "cut.json"), "DEM": str(d / "dem.tif"),
            "DEM_DATUM": "geoid", "OUTPUT": str(d / "out" / "sc.tif"), "OUTPUT_SCENE": str(d / "out" / "sc.json"), **kw}


def _all_cameras(d, folder) -> dict:
    return {"SCENE": str(d / "cut.json"), "DEM": str(d / "dem.tif"), "RESOLUTION": 2.0, "ALL_CAMERAS": True,
            "INPUTS": [str(d / "raw.tif")], "ORTHO_FOLDER": str(folder)}


def _full_disk_message(message: str) -> None:
    message = message.lower()
    assert "no space left on the device" in message or "disk is full" in message, message


@pytest.mark.parametrize("alg, make, text", FULL_DISK, ids=[c[0] for c in FULL_DISK])
def test_a_full_disk_is_an_error_and_leaves_nothing(provider, d, tmp_path, capfd, alg, make, text):
    """A 256 KiB disk holding a user's file: the run fails naming the output and the full disk (where the
    plugin writes the file), the disk keeps only that file, and GDAL's errors on closing the file are
    caught: none reaches Python's 'Exception ignored' hook, nothing like a traceback on stderr."""
    (d / "many.csv").write_text("id,col,row,lon,lat\n" + "".join(
        f"{i},{i % 12000 + 0.5},{i % 9000 + 0.5},114.0,34.5\n" for i in range(MANY)))
    with tiny_disk(tmp_path / "disk") as disk:
        (disk / "mine.txt").write_text("a user's file")
        _full_disk_message(assert_refused(f"pushbroom:{alg.split('-')[0]}", make(d, disk), text, watch=[d, disk],
                                          capfd=capfd))


CLI_FULL_DISK = [c for c in FULL_DISK if c[0] in ("orthorectify", "simulatescene", "sensorcorrect",
                                                   "orthorectify-all-cameras", "footprint")]


@pytest.mark.parametrize("alg, make, text", CLI_FULL_DISK, ids=[c[0] for c in CLI_FULL_DISK])
def test_a_full_disk_from_the_command_line(qgis_process, d, tmp_path, alg, make, text):
    """The same through qgis_process: the full disk named, no traceback nor 'Exception ignored' on
    either stream (GDAL's errors on closing files were printed there once), the inputs' folder as it was
    (no statistics of QGIS beside the rasters: they are not loaded as layers)."""
    with tiny_disk(tmp_path / "disk") as disk:
        (disk / "mine.txt").write_text("a user's file")
        params = {k: ",".join(v) if isinstance(v, list) else v for k, v in make(d, disk).items()}
        _full_disk_message(assert_refused_cli(qgis_process, f"pushbroom:{alg.split('-')[0]}", params, text,
                                              watch=[d, disk]))


# sensorcorrect's files on disks from a quarter of what they need to a little more: the disk fills while
# the image is written, while it is closed (its last directories: GDAL's error then came from a
# destructor, 'Exception ignored'), or while its RPC, VRT and scene are written after it.
DISK_SHARES = (0.25, 0.6, 0.85, 0.95, 1.05, 1.3)


@pytest.fixture(scope="module")
def sensorcorrect_bytes(provider, sources, tmp_path_factory) -> int:
    """What sensorcorrect writes (bytes): its files on an ample disk."""
    folder = tmp_path_factory.mktemp("sc_ample")
    processing.run("pushbroom:sensorcorrect", _sensorcorrect(sources, OUTPUT=str(folder / "sc.tif"),
                                                             OUTPUT_SCENE=str(folder / "sc.json")))
    return sum(f.stat().st_size for f in folder.iterdir())


@pytest.mark.parametrize("share", DISK_SHARES)
def test_sensorcorrect_on_disks_filling_at_every_step(provider, d, tmp_path, capfd, sensorcorrect_bytes, share):
    """Whatever step the disk fills at, the run either writes every file or fails naming the full disk and
    leaves nothing; never a traceback or 'Exception ignored' on stderr."""
    size = f"{int(share * sensorcorrect_bytes) // 4096 * 4 + 8}k"
    with tiny_disk(tmp_path / "disk", size) as disk:
        params = _sensorcorrect(d, OUTPUT=str(disk / "sc.tif"), OUTPUT_SCENE=str(disk / "sc.json"))
        with no_unraisable():
            try:
                processing.run("pushbroom:sensorcorrect", params)
            except QgsProcessingException as exc:
                _full_disk_message(str(exc))
                assert os.listdir(disk) == []
            else:
                assert sorted(os.listdir(disk)) == ["sc.json", "sc.tif", "sc.vrt", "sc_RPC.TXT", "sc_RPC.TXT.json"]
    assert_clean_stderr(capfd.readouterr().err)


# --- legitimate requests, done right ------------------------------------------------------------
def test_bundleadjust_needs_only_the_scene_output(provider, d):
    before = set(os.listdir(d))
    out = processing.run("pushbroom:bundleadjust", _adjust(d, OUTPUT_SCENE=str(d / "adjusted.json")))
    assert out["OUTPUT_SCENE"] == str(d / "adjusted.json") and json.loads((d / "adjusted.json").read_text())
    assert out["OUTPUT_REPORT"] is None and out["OUTPUT_GCPS"] is None and out["OUTPUT_REPORT_JSON"] is None
    assert set(os.listdir(d)) - before == {"adjusted.json"}


def test_a_cancelled_run_leaves_nothing(provider, d):
    class Cancelling(QgsProcessingFeedback):
        def setProgress(self, progress):  # noqa: N802 (QGIS API name)
            super().setProgress(progress)
            if progress > 10:
                self.cancel()

    before = snapshot(d)
    with pytest.raises(Exception, match="cancel"):
        processing.run("pushbroom:orthorectify", _ortho(d, OUTPUT=str(d / "o.tif"), RESOLUTION=2.0),
                       feedback=Cancelling())
    assert snapshot(d) == before


@pytest.mark.parametrize("alg, make, output, written", [
    ("importgcps", lambda d: _import(d, OUTPUT=str(d / "g.gpkg")), "g.part.gpkg", "g.gpkg"),
    ("footprint", lambda d: {"SCENE": str(d / "scene.json"), "OUTPUT": str(d / "f.gpkg")}, "f.part.gpkg", "f.gpkg"),
    ("bundleadjust", lambda d: _adjust(d, OUTPUT_SCENE=str(d / "a.json")), "a.json.part", "a.json"),
    ("orthorectify", lambda d: _ortho(d, OUTPUT=str(d / "o.tif")), "o.part.tif", "o.tif"),
    ("exportrpc", lambda d: _rpc(d, OUTPUT=str(d / "x_RPC.TXT"), IMAGE=str(d / "raw.tif"), SCENE=str(d / "cut.json")),
     "x.vrt.part.vrt", "x.vrt"),
], ids=["importgcps", "footprint", "bundleadjust", "orthorectify", "exportrpc"])
def test_a_users_file_at_an_old_temporary_name_is_kept_and_modes_follow_the_umask(provider, d, alg, make, output,
                                                                                 written):
    (d / output).write_text("a user's file")
    previous = os.umask(0o027)
    try:
        processing.run(f"pushbroom:{alg}", make(d))
    finally:
        os.umask(previous)
    assert (d / output).read_text() == "a user's file"
    assert oct((d / written).stat().st_mode & 0o777) == oct(0o640)
    assert not [p for p in d.iterdir() if p.name.startswith(".")]  # no temporary folder left


def test_a_symlinked_destination_is_written_through(provider, d):
    (d / "real").mkdir()
    (d / "real" / "g.gpkg").write_text("an old file")
    (d / "link.gpkg").symlink_to(d / "real" / "g.gpkg")
    processing.run("pushbroom:importgcps", _import(d, OUTPUT=str(d / "link.gpkg")))
    assert (d / "link.gpkg").is_symlink()
    assert QgsVectorLayer(str(d / "real" / "g.gpkg"), "g", "ogr").featureCount() == 12


def test_a_simulation_replaces_its_own_earlier_files_only(provider, d):
    folder = d / "sim"
    processing.run("pushbroom:simulatescene", {"N_GCPS": 5, "SEED": 1, "OUTPUT_FOLDER": str(folder)})
    processing.run("pushbroom:simulatescene", {"N_GCPS": 7, "SEED": 2, "OUTPUT_FOLDER": str(folder)})
    assert json.loads((folder / "simulation.json").read_text())["seed"] == 2
    (folder / "gcps.csv").write_text("my edits")  # changed after the simulation: a user's file now
    assert_refused("pushbroom:simulatescene", {"N_GCPS": 5, "OUTPUT_FOLDER": str(folder)}, "OUTPUT_FOLDER",
                   "gcps.csv", "changed since", watch=[d])


def _ring_points(path) -> int:
    layer = QgsVectorLayer(str(path), "fp", "ogr")
    assert layer.featureCount() == 1
    return len(next(layer.getFeatures()).geometry().asPolygon()[0])


def test_concurrent_runs_to_the_same_output_leave_one_whole_file(qgis_process, d):
    """Three footprint runs from qgis_process at once (different SAMPLES) to one GeoPackage: all
    succeed and the file is one run's whole result."""
    samples = (8, 64, 2048)
    alone = {_ring_points(processing.run("pushbroom:footprint", {"SCENE": str(d / "scene.json"), "SAMPLES": n,
                                                                 "OUTPUT": str(d / f"alone{n}.gpkg")})["OUTPUT"])
             for n in samples}
    with ThreadPoolExecutor(len(samples)) as pool:
        runs = list(pool.map(lambda n: qgis_process("run", "pushbroom:footprint", "--", f"SCENE={d / 'scene.json'}",
                                                    f"SAMPLES={n}", f"OUTPUT={d / 'fp.gpkg'}"), samples))
    assert all(r.returncode == 0 for r in runs), [r.stderr for r in runs]
    assert len(alone) == 3 and _ring_points(d / "fp.gpkg") in alone
    assert not [p for p in d.iterdir() if p.name.startswith(".")]


# --- through qgis_process ---------------------------------------------------------------------------
CLI = [
    ("exportrpc", lambda d: _rpc(d, OUTPUT=_link(d, "s_RPC.TXT", "scene.json")), ["OUTPUT", "SCENE"]),
    ("bundleadjust", lambda d: _adjust(d, OUTPUT_SCENE=str(d / "scene.json")), ["OUTPUT_SCENE", "SCENE"]),
    ("bundleadjust", lambda d: _adjust(d, OUTPUT_GCPS=str(d / "gcps.gpkg")), ["OUTPUT_GCPS", "GCPS"]),
    ("importgcps", lambda d: _import(d, INPUT_FILE="", INPUT=str(d / "gcps.gpkg"), OUTPUT=str(d / "gcps.gpkg")),
     ["OUTPUT", "INPUT"]),
    ("simulatescene", lambda d: {"OUTPUT_FOLDER": str(d)}, ["OUTPUT_FOLDER", "gcps.csv"]),
]


@pytest.mark.parametrize("alg, make, texts", CLI, ids=[f"{c[0]}-{c[2][0]}" for c in CLI])
def test_refused_from_the_command_line(qgis_process, d, alg, make, texts):
    assert_refused_cli(qgis_process, f"pushbroom:{alg}", make(d), *texts, watch=[d])


def test_bundleadjust_from_the_command_line_with_only_the_scene_output(qgis_process, d):
    done = qgis_process("run", "pushbroom:bundleadjust", "--", f"SCENE={d / 'scene.json'}", f"GCPS={d / 'gcps.gpkg'}",
                        "POSITION_ORDER=0", f"OUTPUT_SCENE={d / 'out' / 'adjusted.json'}")
    assert done.returncode == 0, done.stdout + done.stderr
    assert os.listdir(d / "out") == ["adjusted.json"] and json.loads((d / "out" / "adjusted.json").read_text())
