"""Hostile DEMs through pushbroom:footprint, imagetoground and orthorectify (harness: hostile.py).

Each bad DEM is refused with a message naming the DEM and what is wrong, the DEM and the scene's
folder unchanged; each legitimate but unusual DEM (projected CRS, NaN nodata, a huge VRT for a
coarse footprint) gives the same footprint as the simulator's own DEM.
"""
from __future__ import annotations


import numpy as np
import pytest
from osgeo import gdal, ogr, osr

import processing
from tests.support.hostile import assert_refused, assert_refused_cli, assert_unchanged, huge_vrt, snapshot

gdal.UseExceptions()
ALGORITHMS = ("footprint", "imagetoground", "orthorectify")


def _wgs84() -> str:
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(4326)
    return srs.ExportToWkt()


def _write(path, z, gt, wkt=None, nodata=None, dtype=gdal.GDT_Float32):
    ds = gdal.GetDriverByName("GTiff").Create(str(path), z.shape[1], z.shape[0], 1, dtype)
    ds.SetGeoTransform(gt)
    if wkt:
        ds.SetProjection(wkt)
    band = ds.GetRasterBand(1)
    if nodata is not None:
        band.SetNoDataValue(nodata)
    band.WriteArray(z)
    band = ds = None
    return str(path)


@pytest.fixture(scope="module")
def sim_dem(simulated):
    ds = gdal.Open(simulated["DEM"])
    return ds.GetGeoTransform(), ds.ReadAsArray().astype(np.float32), ds.RasterXSize, ds.RasterYSize


@pytest.fixture(scope="module")
def raw_image(simulated, tmp_path_factory):
    """A raw image of the scene camera's size (sparse, a few KB): what orthorectify needs as INPUT."""
    from pushbroom_adjust.core.formats import load_scene
    cam = load_scene(simulated["TRUE_SCENE"]).cameras[0]
    path = tmp_path_factory.mktemp("raw") / "raw.tif"
    gdal.GetDriverByName("GTiff").Create(str(path), cam.cols, cam.rows, 1, gdal.GDT_Byte, ["SPARSE_OK=TRUE"])
    return str(path)


def _params(alg, simulated, dem, raw_image, out_dir):
    base = {"SCENE": simulated["TRUE_SCENE"], "DEM": dem, "DEM_DATUM": "geoid"}
    if alg == "footprint":
        return {**base, "OUTPUT": "memory:"}
    if alg == "imagetoground":
        return {**base, "INPUT": str(out_dir / "points.csv"), "OUTPUT": "memory:"}
    return {**base, "INPUT": raw_image, "OUTPUT": str(out_dir / "ortho.tif")}


def _raw_image_with_rpc(path, z):
    """A raw image (no geotransform) whose RPC tags put it on the ground: an image, not a DEM."""
    ds = gdal.GetDriverByName("GTiff").Create(str(path), z.shape[1], z.shape[0], 1, gdal.GDT_Float32)
    coefficients = " ".join(["1"] + ["0"] * 19)
    ds.SetMetadata({"LINE_OFF": "100", "SAMP_OFF": "100", "LAT_OFF": "30", "LONG_OFF": "110", "HEIGHT_OFF": "500",
                    "LINE_SCALE": "100", "SAMP_SCALE": "100", "LAT_SCALE": "0.1", "LONG_SCALE": "0.1",
                    "HEIGHT_SCALE": "500", "LINE_NUM_COEFF": coefficients, "LINE_DEN_COEFF": coefficients,
                    "SAMP_NUM_COEFF": coefficients, "SAMP_DEN_COEFF": coefficients}, "RPC")
    ds.GetRasterBand(1).WriteArray(z)
    ds = None
    return str(path)


def _points(folder):
    (folder / "points.csv").write_text("col,row\n100.5,200.5\n6000,6000\n12000,12000\n")


def _bad_dems(folder, sim_dem):
    gt, z, nx, ny = sim_dem
    wkt = _wgs84()
    far = (gt[0] + 40.0, gt[1], 0.0, gt[3] - 30.0, 0.0, gt[5])
    return {
        "no CRS": (_write(folder / "nocrs.tif", z, gt), "no coordinate reference system"),
        "all nodata": (_write(folder / "nodata.tif", np.full_like(z, -32768), gt, wkt, -32768), "no valid heights"),
        "constant 1e30": (_write(folder / "huge.tif", np.full_like(z, 1e30), gt, wkt), "not all terrain heights"),
        "outside the scene": (_write(folder / "far.tif", z, far, wkt), "cover"),
        "one pixel": (_write(folder / "one.tif", z[:1, :1], gt, wkt), "at least 2 x 2"),
        "complex band": (_write(folder / "complex.tif", z.astype(np.complex64), gt, wkt, dtype=gdal.GDT_CFloat32),
                         "real numbers"),
        "rotated": (_write(folder / "rotated.tif", z, (gt[0], gt[1], 1e-5, gt[3], 1e-5, gt[5]), wkt), "rotated"),
        "raw image with an RPC": (_raw_image_with_rpc(folder / "raw_rpc.tif", z), "a raw image with an RPC"),
    }


BAD = ("no CRS", "all nodata", "constant 1e30", "outside the scene", "one pixel", "complex band", "rotated",
       "raw image with an RPC")


@pytest.mark.parametrize("alg", ALGORITHMS)
@pytest.mark.parametrize("case", BAD)
def test_bad_dem_is_refused_naming_it(simulated, sim_dem, raw_image, tmp_path, alg, case):
    dems = tmp_path / "dems"
    dems.mkdir()
    path, expected = _bad_dems(dems, sim_dem)[case]
    out = tmp_path / "out"
    out.mkdir()
    _points(out)
    # the DEM named by its file, or (imagetoground, a DEM off the scene) by its parameter
    name = "DEM" if case == "outside the scene" else path.rsplit("/", 1)[-1]
    assert_refused(f"pushbroom:{alg}", _params(alg, simulated, path, raw_image, out), name, expected,
                   watch=[dems, out, simulated["OUTPUT_FOLDER"]])


def _area(simulated, dem) -> float:
    layer = processing.run("pushbroom:footprint", {"SCENE": simulated["TRUE_SCENE"], "DEM": dem, "DEM_DATUM": "geoid",
                                                   "OUTPUT": "memory:"})["OUTPUT"]
    (feature,) = list(layer.getFeatures())
    return float(feature["area_km2"])


@pytest.fixture(scope="module")
def true_area(simulated):
    return _area(simulated, simulated["DEM"])


def test_dem_in_a_projected_crs_gives_the_same_footprint(simulated, tmp_path, true_area):
    utm = tmp_path / "utm.tif"
    gdal.Warp(str(utm), simulated["DEM"], dstSRS="EPSG:32649", xRes=30.0, yRes=30.0, resampleAlg="bilinear")
    before = snapshot(utm)
    assert _area(simulated, str(utm)) == pytest.approx(true_area, rel=1e-4)
    assert_unchanged(before, [utm])


def test_dem_with_nan_nodata_gives_the_same_footprint(simulated, sim_dem, tmp_path, true_area):
    gt, z, nx, ny = sim_dem
    z = z.copy()
    z[:5, :5] = np.nan  # a corner outside the image's footprint
    path = _write(tmp_path / "nan.tif", z, gt, _wgs84(), float("nan"))
    assert _area(simulated, path) == pytest.approx(true_area, rel=1e-9)


def test_huge_vrt_dem_footprint_reads_it_coarsely(simulated, tmp_path, true_area):
    """A DEM of ~2 million pixels square (~16 TB of heights) traces the footprint from a coarse
    read: same area as on the simulator's DEM (the VRT is that DEM, resampled)."""
    assert _area(simulated, huge_vrt(simulated["DEM"], tmp_path / "huge.vrt")) == pytest.approx(true_area, rel=1e-3)


@pytest.mark.parametrize("alg", ("imagetoground", "orthorectify"))
def test_huge_vrt_dem_at_full_resolution_is_refused(simulated, raw_image, tmp_path, alg):
    """Where the full resolution is needed, the window over the scene is beyond memory: a clean
    error naming the DEM and suggesting a coarser DEM, nothing written."""
    out = tmp_path / "out"
    out.mkdir()
    _points(out)
    vrt = huge_vrt(simulated["DEM"], tmp_path / "huge.vrt")
    assert_refused(f"pushbroom:{alg}", _params(alg, simulated, vrt, raw_image, out), "huge.vrt", "coarser DEM",
                   watch=[vrt, out])


def _not_rasters(folder) -> dict:
    """Files given as DEM that are no raster, and what the refusal says about each."""
    (folder / "text.tif").write_text("not a raster\n")
    ds = ogr.GetDriverByName("GPKG").CreateDataSource(str(folder / "points.gpkg"))
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(4326)
    layer = ds.CreateLayer("points", srs, ogr.wkbPoint)
    feature = ogr.Feature(layer.GetLayerDefn())
    feature.SetGeometry(ogr.CreateGeometryFromWkt("POINT (113.9 34.5)"))
    layer.CreateFeature(feature)
    feature = layer = ds = None
    (folder / "dem_folder").mkdir()
    return {"text file": (folder / "text.tif", "is not a raster GDAL can read"),
            "vector file": (folder / "points.gpkg", "is a vector file (GPKG: points, lines or polygons), not a raster"),
            "missing file": (folder / "missing.tif", "does not exist"),
            "folder": (folder / "dem_folder", "is a folder, not a raster file")}


NOT_RASTERS = ("text file", "vector file", "missing file", "folder")


@pytest.mark.parametrize("alg", ALGORITHMS)
@pytest.mark.parametrize("case", NOT_RASTERS)
def test_a_dem_that_is_not_a_raster(simulated, raw_image, tmp_path, alg, case):
    """Not QGIS's 'Could not load source layer for DEM: ... not found': the DEM, its file, what the
    file is and what DEM takes."""
    inputs = tmp_path / "inputs"
    inputs.mkdir()
    path, expected = _not_rasters(inputs)[case]
    out = tmp_path / "out"
    out.mkdir()
    _points(out)
    assert_refused(f"pushbroom:{alg}", _params(alg, simulated, str(path), raw_image, out), f"DEM: {path} {expected}",
                   "give a DEM: heights in metres on a map grid with a CRS", watch=[inputs, out])


def test_a_dem_that_is_not_a_raster_on_the_command_line(simulated, qgis_process, tmp_path):
    """What the issue met: qgis_process said only 'An error was encountered while checking parameter values'."""
    path, expected = _not_rasters(tmp_path)["vector file"]
    assert_refused_cli(qgis_process, "pushbroom:footprint", {"SCENE": simulated["TRUE_SCENE"], "DEM": path,
                                                             "OUTPUT": tmp_path / "fp.gpkg"},
                       f"DEM: {path} {expected}", "give a DEM", watch=[tmp_path])
