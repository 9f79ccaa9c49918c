"""Hostile inputs of pushbroom:matchgcps (harness: hostile.py): each bad raster or parameter is
refused with a message naming it and what to change, every given file and the output folder
unchanged; a reference in a geographic CRS is legitimate and matches."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from osgeo import gdal, osr

import processing
from pushbroom_adjust.core.observations import gcps
from tests.support.matchscene import SEARCH, mini_scene, true_errors
from tests.support.dems import read_dem, with_holes
from tests.support.hostile import assert_refused, assert_refused_cli
from tests.support.processing import RecordingFeedback

gdal.UseExceptions()
ALG = "pushbroom:matchgcps"


@pytest.fixture(scope="module")
def mini(provider, tmp_path_factory):
    return mini_scene(tmp_path_factory.mktemp("mini_hostile"))


def _params(mini, out, **kw) -> dict:
    return {"INPUT": str(mini.images["HRC"]), "SCENE": str(mini.onboard_scene), "REFERENCE": str(mini.reference),
            "DEM": str(mini.dem), "DEM_DATUM": "geoid", "SPACING": 80, "SEARCH_RANGE": SEARCH,
            "OUTPUT": str(out / "gcps.gpkg"), **kw}


def _watched(mini, out, overrides: dict) -> list:
    """The files a case gives (the scene's and its own) and the output folder. QGIS itself may add
    its raster statistics cache (<raster>.aux.xml) beside a raster it opens: not the plugin's doing,
    so folders holding given rasters are watched file by file."""
    given = [p for p in mini.folder.iterdir() if not p.name.endswith(".aux.xml")]
    return given + [v for v in overrides.values() if isinstance(v, str) and Path(v).is_file()] + [out]


def _copy_reference(mini, path, geotransform=None, wkt=None, values=None, nodata=None) -> str:
    """A copy of the mini scene's reference with another geotransform, CRS, pixels or nodata."""
    src = gdal.Open(str(mini.reference))
    ds = gdal.GetDriverByName("GTiff").CreateCopy(str(path), src)
    if geotransform is not None:
        ds.SetGeoTransform(geotransform)
    if wkt is not None:
        ds.SetProjection(wkt)
    if values is not None:
        ds.GetRasterBand(1).WriteArray(np.full((ds.RasterYSize, ds.RasterXSize), values, np.uint8))
    if nodata is not None:
        ds.GetRasterBand(1).SetNoDataValue(nodata)
    ds = None
    return str(path)


def _raster(path, cols, rows, value=0, wkt=None) -> str:
    ds = gdal.GetDriverByName("GTiff").Create(str(path), cols, rows, 1, gdal.GDT_Byte)
    ds.GetRasterBand(1).Fill(value)
    if wkt:
        ds.SetProjection(wkt)
        ds.SetGeoTransform((500000, 5, 0, 3800000, 0, -5))
    ds = None
    return str(path)


def _no_crs(mini, path) -> str:
    src = gdal.Open(str(mini.reference))
    ds = gdal.GetDriverByName("GTiff").Create(str(path), src.RasterXSize, src.RasterYSize, 1, gdal.GDT_Byte)
    ds.SetGeoTransform(src.GetGeoTransform())
    ds.GetRasterBand(1).WriteArray(src.ReadAsArray())
    ds = None
    return str(path)


def _local_crs() -> str:
    srs = osr.SpatialReference()
    srs.SetLocalCS("site grid")
    return srs.ExportToWkt()


def _shifted(mini) -> tuple:
    gt = list(gdal.Open(str(mini.reference)).GetGeoTransform())
    gt[0] += 200_000.0
    return tuple(gt)


def _rotated(mini) -> tuple:
    gt = list(gdal.Open(str(mini.reference)).GetGeoTransform())
    gt[2], gt[4] = 0.5, 0.5
    return tuple(gt)


CASES = {
    # name: (build(mini, tmp) -> parameter overrides, texts the message must hold)
    "reference_far_away": (lambda m, t: {"REFERENCE": _copy_reference(m, t / "far.tif", geotransform=_shifted(m))},
                           ("does not overlap the scene",)),
    "reference_constant": (lambda m, t: {"REFERENCE": _copy_reference(m, t / "flat.tif", values=128)},
                           ("reference", "blank or constant")),
    "reference_all_nodata": (lambda m, t: {"REFERENCE": _copy_reference(m, t / "nod.tif", values=0, nodata=0)},
                             ("reference", "blank or constant")),
    "reference_without_crs": (lambda m, t: {"REFERENCE": _no_crs(m, t / "nocrs.tif")},
                              ("reference", "coordinate reference system")),
    "reference_in_a_local_crs": (lambda m, t: {"REFERENCE": _copy_reference(m, t / "local.tif", wkt=_local_crs())},
                                 ("reference", "place on the Earth is unknown")),
    "reference_rotated": (lambda m, t: {"REFERENCE": _copy_reference(m, t / "rot.tif", geotransform=_rotated(m))},
                          ("reference", "rotated")),
    "reference_not_a_raster": (lambda m, t: {"REFERENCE": str((t / "text.tif").write_text("no image") and
                                                              t / "text.tif")},
                               ("REFERENCE",)),
    "image_blank": (lambda m, t: {"INPUT": _raster(t / "blank.tif", 2027, 1200, 0)}, ("image", "blank or constant")),
    "image_wrong_size": (lambda m, t: {"INPUT": _raster(t / "small.tif", 1000, 1000, 7)},
                         ("1000 x 1000", "is it the scene's image")),
    "onboard_error_beyond_search_range": (lambda m, t: {"SEARCH_RANGE": 60},
                                          ("within the search range", "increase the search range")),
    "fine_radius_above_its_range": (lambda m, t: {"FINE_RADIUS": 65}, ("FINE_RADIUS",)),
    "window_even": (lambda m, t: {"WINDOW": 30}, ("window",)),
    "spacing_larger_than_the_image": (lambda m, t: {"SPACING": 50_000}, ("no grid point fits",)),
    "output_not_geopackage": (lambda m, t: {"OUTPUT": str(t / "gcps.csv")}, ("OUTPUT", "GeoPackage")),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_refused(mini, tmp_path, case):
    build, texts = CASES[case]
    out = tmp_path / "out"
    out.mkdir()
    overrides = build(mini, tmp_path)
    assert_refused(ALG, _params(mini, out, **overrides), *texts, watch=_watched(mini, out, overrides))


def test_refused_through_qgis_process(mini, tmp_path, qgis_process):
    far = _copy_reference(mini, tmp_path / "far.tif", geotransform=_shifted(mini))
    out = tmp_path / "out"
    out.mkdir()
    assert_refused_cli(qgis_process, ALG, _params(mini, out, REFERENCE=far), "does not overlap the scene",
                       watch=_watched(mini, out, {"REFERENCE": far}))


def test_reference_in_geographic_coordinates_matches(mini, tmp_path):
    """A legitimate reference in EPSG:4326 (degrees) is used as it is."""
    path = tmp_path / "ref4326.tif"
    gdal.Warp(str(path), str(mini.reference), dstSRS="EPSG:4326", resampleAlg="cubic")
    before = path.read_bytes()
    out = processing.run(ALG, _params(mini, tmp_path, REFERENCE=str(path), SPACING=60))
    e = true_errors(mini.folder, gcps.read_gpkg(out["OUTPUT"]))
    assert len(e) >= 400 and np.median(e) <= 0.2 and np.mean(e > 1) <= 0.03
    assert path.read_bytes() == before


def test_a_search_range_beyond_the_image_is_clipped_to_it(mini, tmp_path):
    """SEARCH_RANGE 5 km over an image of 4.8 km (2027 px of 2.358 m): clipped to the image, said in the
    log, and matched (before: refused, 'search range 5000 m needs ... px chips, more than the image')."""
    log = RecordingFeedback()
    out = processing.run(ALG, _params(mini, tmp_path, SEARCH_RANGE=5000), feedback=log)
    assert any(line.startswith("search range 5000 m clipped to 4779 m: 2027 px") for line in log.lines), log.lines
    e = true_errors(mini.folder, gcps.read_gpkg(out["OUTPUT"]))
    assert len(e) >= 250 and np.median(e) <= 0.1 and np.mean(e > 1) <= 0.03


def _holed_dem(mini, path, nodata) -> str:
    """The mini scene's DEM with holes over a band of its columns (a DSM's hole): NaN, or ``nodata``
    in an Int16 DEM as SRTM writes its voids (tests/support/dems.py)."""
    z, _, _ = read_dem(mini.dem)
    mask = np.zeros(z.shape, bool)
    mask[:, z.shape[1] // 3:z.shape[1] // 2] = True
    return with_holes(mini.dem, path, mask, nodata)


@pytest.mark.parametrize("nodata", [None, -32768], ids=["NaN", "nodata -32768"])
def test_a_dem_with_holes_rejects_the_gcps_it_has_no_height_for(mini, tmp_path, nodata):
    """A DEM with holes over a band of the scene: no traceback (before: 'ValueError: cannot convert
    float NaN to integer' in the coarse pass); the grid points whose ground lies in the hole are matched
    at the estimated height and rejected as 'no DEM height' (a GCP's height would be a guess), counted
    in the log with the DEM named; the others are GCPs as accurate as on the whole DEM (measured, NaN and
    -32768 alike: no height for 106 of 336 grid points, 97 matches among them rejected, 206 GCPs)."""
    dem = _holed_dem(mini, tmp_path / "holed_dem.tif", nodata)
    log = RecordingFeedback()
    out = processing.run(ALG, _params(mini, tmp_path, DEM=dem), feedback=log)
    rejected = next(line for line in log.lines if line.startswith("rejected: "))
    holes = int(rejected.split(" no DEM height")[0].rsplit(" ", 1)[-1])
    assert holes >= 20, rejected
    counted = re.search(r"DEM \S+holed_dem.tif gives no height for (\d+) of (\d+) grid points \((\d+) on its nodata "
                        r"holes\): the reference was rectified there at the estimated height [\d.]+ m, and the (\d+) "
                        r"matches among them rejected as 'no DEM height'", "\n".join(log.lines))
    assert counted and int(counted.group(1)) == int(counted.group(3)) >= int(counted.group(4)) == holes, log.lines
    table = gcps.read_gpkg(out["OUTPUT"])
    e = true_errors(mini.folder, table)
    assert len(e) >= 150 and np.median(e) <= 0.1 and np.mean(e > 1) <= 0.03
