"""core.rasters: input rasters opened without PAM (nothing written beside them, even after
statistics are computed and metadata set), refusals that say what a file is, and the statistics a
display VRT carries (exact on small rasters, from spread whole blocks on large tiled ones)."""
import numpy as np
import pytest
from osgeo import gdal, ogr, osr

from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.rasters import (EXACT_STATISTICS_PIXELS, check_input_raster, copy_statistics,
                                           open_input_raster, sample_band)

gdal.UseExceptions()


def geotiff(path, values: np.ndarray, nodata=None, options=()) -> str:
    ds = gdal.GetDriverByName("GTiff").Create(str(path), values.shape[1], values.shape[0], 1,
                                              gdal.GDT_Float32, list(options))
    ds.GetRasterBand(1).WriteArray(values)
    if nodata is not None:
        ds.GetRasterBand(1).SetNoDataValue(nodata)
    ds = None
    return str(path)


def test_an_input_raster_gets_nothing_written_beside_it(tmp_path):
    path = geotiff(tmp_path / "dem.tif", np.arange(12.0).reshape(3, 4))
    before = (tmp_path / "dem.tif").read_bytes()
    ds = open_input_raster(path)
    band = ds.GetRasterBand(1)
    assert band.ComputeStatistics(False)[0:2] == [0.0, 11.0]
    band.SetMetadataItem("SEEN", "yes")
    ds = band = None
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dem.tif"]
    assert (tmp_path / "dem.tif").read_bytes() == before
    # without it GDAL writes its PAM beside the raster: what the test guards against
    ds = gdal.Open(path)
    ds.GetRasterBand(1).ComputeStatistics(False)
    ds = None
    assert (tmp_path / "dem.tif.aux.xml").exists()


def test_check_input_raster_says_what_a_file_is(tmp_path):
    assert check_input_raster(geotiff(tmp_path / "ok.tif", np.zeros((2, 5)))) == (5, 2)
    (tmp_path / "folder").mkdir()
    (tmp_path / "text.tif").write_text("not a raster")
    ds = ogr.GetDriverByName("GPKG").CreateDataSource(str(tmp_path / "points.gpkg"))
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(4326)
    ds.CreateLayer("points", srs, ogr.wkbPoint)
    ds = None
    cases = {tmp_path / "missing.tif": "missing.tif does not exist",
             tmp_path / "folder": "folder is a folder, not a raster file",
             tmp_path / "text.tif": r"text.tif is not a raster GDAL can read \(",
             tmp_path / "points.gpkg": r"points.gpkg is a vector file \(GPKG: points, lines or polygons\), not a raster"}
    for path, message in cases.items():
        with pytest.raises(InputError, match=message):
            check_input_raster(path)
    with pytest.raises(InputError, match="no raster file given"):
        check_input_raster("")


def test_a_small_raster_gets_its_exact_statistics(tmp_path):
    values = np.random.default_rng(1).normal(100.0, 15.0, (60, 80)).astype(np.float32)
    values[5, 5], values[6, 6] = -9999.0, np.nan
    source = open_input_raster(geotiff(tmp_path / "src.tif", values, nodata=-9999.0))
    target = gdal.GetDriverByName("MEM").Create("", 80, 60, 1, gdal.GDT_Float32)
    copy_statistics(source, target)
    valid = values[np.isfinite(values) & (values != -9999.0)].astype(np.float64)
    got = target.GetRasterBand(1).GetStatistics(False, False)
    np.testing.assert_allclose(got, [valid.min(), valid.max(), valid.mean(), valid.std()], rtol=1e-12)
    assert target.GetRasterBand(1).GetMetadataItem("STATISTICS_APPROXIMATE") is None


def test_a_large_tiled_raster_is_sampled_in_whole_blocks(tmp_path):
    rows, cols, tile = 2048, 2048, 256
    y, x = np.mgrid[0:rows, 0:cols]
    values = (x + y).astype(np.float32)
    path = geotiff(tmp_path / "big.tif", values, options=["TILED=YES", f"BLOCKXSIZE={tile}", f"BLOCKYSIZE={tile}"])
    ds = open_input_raster(path)  # held: a band outlives no dataset
    sample, approximate = sample_band(ds.GetRasterBand(1))
    assert approximate and rows * cols > EXACT_STATISTICS_PIXELS
    # every other tile row and column: a quarter of the 64 tiles, each read whole
    assert sample.size == 16 * tile * tile
    assert sample.min() == 0.0 and sample.max() == 2 * (cols - tile - 1)  # the last tile of each axis not read
