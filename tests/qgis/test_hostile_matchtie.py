"""Hostile inputs of pushbroom:matchtiepoints (harness: hostile.py): each bad image set, scene or
parameter is refused with a message naming it and what was expected, every given file and the
output folder unchanged; an image in another GDAL format is legitimate and matches."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from osgeo import gdal, osr

import processing
from pushbroom_adjust.core.measure.finepass import SIGMA_FLOOR
from pushbroom_adjust.core.observations import tiepoints
from tests.support.dems import read_dem, with_holes
from tests.support.matchscene import mini_tlc_scene
from tests.support.hostile import assert_refused, assert_refused_cli
from tests.support.processing import RecordingFeedback

gdal.UseExceptions()
ALG = "pushbroom:matchtiepoints"
CAMERAS = ("NAD", "FWD", "BWD")


@pytest.fixture(scope="module")
def tlc(provider, tmp_path_factory):
    return mini_tlc_scene(tmp_path_factory.mktemp("tlc_hostile"))


def _params(sim, out: Path, **kw) -> dict:
    return {"SCENE": str(sim.onboard_scene), "INPUTS": [str(sim.images[c]) for c in CAMERAS], "DEM": str(sim.dem),
            "DEM_DATUM": "geoid", "SPACING": 100, "SEARCH_RANGE": 300, "OUTPUT": str(out / "ties.gpkg"), **kw}


def _watched(sim, out: Path, overrides: dict) -> list:
    """The scene's files (but QGIS's own raster statistics caches, <raster>.aux.xml), the files a
    case adds and the output folder."""
    given = [p for p in sim.folder.iterdir() if not p.name.endswith(".aux.xml")]
    extra = [v for value in overrides.values() for v in (value if isinstance(value, list) else [value])
             if isinstance(v, str) and Path(v).is_file() and Path(v).parent != sim.folder]
    return given + extra + [out]


def _raster(path: Path, cols: int, rows: int, value: int = 0) -> str:
    ds = gdal.GetDriverByName("GTiff").Create(str(path), cols, rows, 1, gdal.GDT_Byte)
    ds.GetRasterBand(1).Fill(value)
    ds = None
    return str(path)


def _images(sim, **replaced) -> list[str]:
    """The three cameras' images in camera order, some replaced ({camera: path})."""
    return [replaced.get(c, str(sim.images[c])) for c in CAMERAS]


def _gpkg_raster(sim, path: Path) -> str:
    """The nadir image as a GeoPackage raster (a legitimate input format; GeoPackage rasters need a
    georeference, which a raw image's reader ignores)."""
    mem = gdal.GetDriverByName("MEM").CreateCopy("", gdal.Open(str(sim.images["NAD"])))
    mem.SetGeoTransform((0.0, 1.0, 0.0, 0.0, 0.0, -1.0))
    mem.SetProjection(_mercator())
    gdal.GetDriverByName("GPKG").CreateCopy(str(path), mem)
    return str(path)


def _mercator() -> str:
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(3857)
    return srs.ExportToWkt()


def _output_is_an_input(sim, tmp: Path) -> dict:
    nadir = _gpkg_raster(sim, tmp / "nadir.gpkg")
    return {"INPUTS": _images(sim, NAD=nadir), "OUTPUT": nadir}


CASES = {
    # name: (build(sim, tmp) -> parameter overrides, texts the message must hold)
    "image_of_the_wrong_size": (
        lambda s, t: {"INPUTS": _images(s, BWD=_raster(t / "small.tif", 1000, 800, 9))},
        ("INPUTS", "small.tif", "1000 x 800", "camera BWD", "1500 x 986")),
    "fewer_images_than_cameras": (lambda s, t: {"INPUTS": _images(s)[:2]},
                                  ("INPUTS", "2 raw image(s) given", "3 camera(s) (NAD, FWD, BWD)")),
    "more_images_than_cameras": (lambda s, t: {"INPUTS": _images(s) + [str(s.images["NAD"])]},
                                 ("INPUTS", "4 raw image(s) given", "one image per camera")),
    "no_image": (lambda s, t: {"INPUTS": []}, ("INPUTS", "0 raw image(s) given")),
    "blank_image": (lambda s, t: {"INPUTS": _images(s, FWD=_raster(t / "blank.tif", 1500, 986, 0))},
                    ("blank.tif", "blank or constant")),
    "images_in_the_wrong_order": (  # the mini scene's FWD and BWD images have 986 rows, NAD 1200
        lambda s, t: {"INPUTS": [str(s.images[c]) for c in ("FWD", "NAD", "BWD")]},
        ("INPUTS", "image_FWD.tif", "1500 x 986 px but camera NAD", "is it the scene's image")),
    "two_cameras_swapped_of_one_size": (  # FWD and BWD have the same size: the matching finds no agreement
        lambda s, t: {"INPUTS": [str(s.images[c]) for c in ("NAD", "BWD", "FWD")]},
        ("no consistent match", "increase the search range")),
    "output_is_an_input": (_output_is_an_input, ("OUTPUT", "INPUTS")),
    "output_not_geopackage": (lambda s, t: {"OUTPUT": str(t / "ties.csv")}, ("OUTPUT", "GeoPackage")),
    "window_even": (lambda s, t: {"WINDOW": 30}, ("window",)),
    "fine_radius_below_its_range": (lambda s, t: {"FINE_RADIUS": 1}, ("FINE_RADIUS",)),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_refused(tlc, tmp_path, case):
    build, texts = CASES[case]
    out = tmp_path / "out"
    out.mkdir()
    overrides = build(tlc, tmp_path)
    assert_refused(ALG, _params(tlc, out, **overrides), *texts, watch=_watched(tlc, out, overrides))


def test_a_single_camera_scene_has_no_pairs(simulated, tmp_path):
    """A CBERS-02B HRC scene (one camera): nothing to tie; refused before any image is read."""
    out = tmp_path / "out"
    out.mkdir()
    image = _raster(tmp_path / "hrc.tif", 100, 100, 5)
    assert_refused(ALG, {"SCENE": simulated["ONBOARD_SCENE"], "INPUTS": [image], "OUTPUT": str(out / "t.gpkg")},
                   "SCENE", "has one camera (HRC)", "two or more", watch=[simulated["ONBOARD_SCENE"], image, out])


def test_refused_through_qgis_process(tlc, tmp_path, qgis_process):
    out = tmp_path / "out"
    out.mkdir()
    params = _params(tlc, out)
    images = params.pop("INPUTS")[:2]
    before = {"INPUTS": images}
    text = assert_refused_cli(qgis_process, ALG, params | {"INPUTS": images[0]}, "1 raw image(s) given",
                              watch=_watched(tlc, out, before))
    assert "3 camera(s)" in text


def test_an_image_in_another_format_is_legitimate(tlc, tmp_path):
    """The nadir image as a GeoPackage raster (any GDAL format will do) matches as the GeoTIFF does."""
    nadir = _gpkg_raster(tlc, tmp_path / "nadir.gpkg")
    out = processing.run(ALG, _params(tlc, tmp_path, INPUTS=_images(tlc, NAD=nadir)))
    table = tiepoints.read_gpkg(out["OUTPUT"])
    pairs = tiepoints.summary(table)["pairs"]
    assert pairs["NAD-FWD"] >= 100 and pairs["NAD-BWD"] >= 100, pairs  # 15 x 12 grid points
    assert np.all(table.sigma_px >= SIGMA_FLOOR)


def test_a_search_range_beyond_the_image_is_clipped_to_it(tlc, tmp_path):
    """SEARCH_RANGE 20 km over an image of 7.5 km (1500 px of 5 m): clipped to the image, said in the
    log, and matched as with 300 m (before: refused, 'search range 20000 m needs ... px chips, more than
    the image')."""
    log = RecordingFeedback()
    out = processing.run(ALG, _params(tlc, tmp_path, SEARCH_RANGE=20_000), feedback=log)
    assert any(line.startswith("search range 20000 m clipped to 7500 m: 1500 px, the image's larger side")
               for line in log.lines), log.lines
    pairs = tiepoints.summary(tiepoints.read_gpkg(out["OUTPUT"]))["pairs"]
    assert pairs["NAD-FWD"] >= 100 and pairs["NAD-BWD"] >= 100, pairs  # 15 x 12 grid points


@pytest.fixture(scope="module")
def pair(provider, tmp_path_factory) -> dict:
    """A small rendered tri-stereo (pushbroom:simulateblock): scenes nad, fwd, bwd."""
    return processing.run("pushbroom:simulateblock", {
        "PRESET": "th1_tlc", "LAYOUT": "tristereo", "IMAGE_SIZE": 500, "RENDER": True, "SEED": 3, "N_GCPS": 5,
        "N_TIE_POINTS": 10, "OUTPUT_FOLDER": str(tmp_path_factory.mktemp("pair"))})


def test_one_image_given_for_two_scenes_is_refused(pair, tmp_path):
    """SCENES nad, fwd with INPUTS image_NAD.tif and a copy of it for fwd (issue 28): the copy correlates
    with itself through two different models, and the ties it gave (305 of them) sat a median 13.5 px, at
    most 24 px, from where the fwd model puts them, with exit code 0. Refused, naming both images."""
    copy = tmp_path / "copy_of_nad.tif"
    copy.write_bytes(Path(pair["IMAGES"][0]).read_bytes())
    out = tmp_path / "out"
    out.mkdir()
    params = {"SCENES": pair["SCENES"][:2], "INPUTS": [pair["IMAGES"][0], str(copy)], "SPACING": 30,
              "SEARCH_RANGE": 400, "OUTPUT": str(out / "ties.gpkg")}
    assert_refused(ALG, params, "INPUTS", "the images of nad/NAD", "and fwd/NAD", "copy_of_nad.tif",
                   "show the same pixels", "each needs its own image",
                   watch=[Path(p) for p in pair["SCENES"][:2]] + [Path(pair["IMAGES"][0]), copy, out])


@pytest.mark.parametrize("nodata", [None, -32768], ids=["NaN", "nodata -32768"])
def test_a_dem_with_holes_is_matched_on_and_its_holes_counted(tlc, tmp_path, nodata):
    """The scene's DEM with holes over a band of its columns (NaN, or -32768 in an Int16 DEM as SRTM
    writes its voids): no traceback (before: 'ValueError: cannot convert float NaN to integer' in the
    coarse pass); per camera the log counts the grid points the DEM gives no height for, matched at the
    estimated height (the DEM's median under the image), and many of them tie (measured: 58 of 180 grid
    points in the hole, 25 tied in FWD and 30 in BWD; 107 and 102 ties in all)."""
    z, _, _ = read_dem(tlc.dem)
    mask = np.zeros(z.shape, bool)
    mask[:, z.shape[1] // 3:z.shape[1] // 2] = True
    dem = with_holes(tlc.dem, tmp_path / "holed_dem.tif", mask, nodata)
    log = RecordingFeedback()
    out = processing.run(ALG, _params(tlc, tmp_path, DEM=dem), feedback=log)
    text = "\n".join(log.lines)
    for camera in ("FWD", "BWD"):
        counted = re.search(rf"NAD-{camera}: DEM \S+holed_dem.tif gives no height for (\d+) of (\d+) grid points "
                            rf"\((\d+) on its nodata holes\): those were matched at the estimated height [\d.]+ m "
                            rf"\((\d+) matched", text)
        assert counted and int(counted.group(1)) == int(counted.group(3)) >= 10, text
        assert int(counted.group(4)) >= 15, text      # measured 25 and 30 of 58 (many fall outside the other image)
    assert "Traceback" not in text
    summary = tiepoints.summary(tiepoints.read_gpkg(out["OUTPUT"]))
    assert summary["pairs"]["NAD-FWD"] >= 50 and summary["pairs"]["NAD-BWD"] >= 50, summary
