"""Real crops whose RPCs keep the full product's offsets: two crops of a Pleiades 1B stereo pair of one pass
over Mont Ventoux (2013-08-05, 500 x 500 and 498 x 495 px; tests/data/pleiades_ventoux, source and licence in
tests/data/README.md), each with the vendor RPC of its full product written for the crop with the full
product's LINE_OFF/SAMP_OFF and the crop's origin folded into the numerators, and a window of an SRTM DEM
with NaN holes (everything above 1000 m).

Measured: through GDAL's RPC transformer the crops' _RPC.TXT map ground points to the crops' pixels as the
vendor .geom maps them to the full products' pixels less the crop's origin, to 1e-11 px; the plugin reads
them as they are.
"""
from __future__ import annotations

import numpy as np
import pytest
from osgeo import gdal

from pushbroom_adjust.core.formats import load_scene
from tests.support.ossim_geom import coefficients, gdal_rpc_metadata, geom_rpc, read_geom

gdal.UseExceptions()

NAMES = ("left_image", "right_image")
ORIGINS = {"left_image": (5000.0, 5000.0), "right_image": (4915.0, 5162.0)}  # the crops' first pixel in the products
SIZES = {"left_image": (500, 500), "right_image": (498, 495)}


@pytest.fixture(scope="module")
def ventoux(shared_data):
    return shared_data / "pleiades_ventoux"


def rpc_transformer(ds) -> gdal.Transformer:
    return gdal.Transformer(ds, None, ["METHOD=RPC"])


def ground_points(transformer, x0: float, y0: float, n: int = 13) -> np.ndarray:
    """(n * n * 3, 3) ground points (lon, lat, h) that ``transformer`` (of the full product) sees at full-product
    pixels from 50 px before the crop at (x0, y0) to 50 px past it, at the bottom, middle and top of the
    RPC's height range."""
    col, row = np.meshgrid(np.linspace(-50, 550, n), np.linspace(-50, 550, n))
    points = []
    for h in (190.0, 1075.0, 1960.0):
        ground, ok = transformer.TransformPoints(0, [(c + x0, r + y0, h) for c, r in zip(col.ravel(), row.ravel())])
        assert all(ok)
        points += ground
    return np.array(points)


@pytest.mark.parametrize("name", NAMES)
def test_the_rpc_files_are_the_vendor_geom_with_the_crop_folded_into_the_numerators(ventoux, name):
    """<name>_RPC.TXT holds the unchanged .geom's offsets, scales and denominators, and its numerators less
    the crop's origin (the geotransform) over the scale times the denominator; GDAL's RPC transformer maps
    ground points to the crop's pixels as the .geom maps them to the full product's, less the origin (measured
    to 1e-11 px), and the crop's pixels to the ground as the .geom maps the product's pixels, crop + origin
    (both by GDAL's iterative inversion: measured to 1e-14 deg)."""
    geom = read_geom(ventoux / f"{name}.geom")
    crop = gdal.Open(str(ventoux / f"{name}.tif"))
    x0, _, _, y0, _, _ = crop.GetGeoTransform()
    assert (x0, y0) == ORIGINS[name] and (crop.RasterXSize, crop.RasterYSize) == SIZES[name]
    assert crop.GetRasterBand(1).DataType == gdal.GDT_UInt16 and crop.RasterCount == 1
    rpc = load_scene(ventoux / f"{name}_RPC.TXT").rpc
    vendor = geom_rpc(geom)
    for fld in ("line_off", "samp_off", "lat_off", "lon_off", "height_off", "line_scale", "samp_scale", "lat_scale",
                "lon_scale", "height_scale"):
        assert getattr(rpc, fld) == getattr(vendor, fld), fld
    np.testing.assert_array_equal(rpc.line_den, coefficients(geom, "line_den"))
    np.testing.assert_array_equal(rpc.samp_den, coefficients(geom, "samp_den"))
    np.testing.assert_allclose(rpc.line_num, vendor.line_num - y0 / vendor.line_scale * vendor.line_den, rtol=0,
                               atol=1e-16)
    np.testing.assert_allclose(rpc.samp_num, vendor.samp_num - x0 / vendor.samp_scale * vendor.samp_den, rtol=0,
                               atol=1e-16)

    product = gdal.GetDriverByName("MEM").Create("", 1, 1, 1)
    product.SetMetadata(gdal_rpc_metadata(geom), "RPC")
    full = rpc_transformer(product)
    assert crop.GetMetadata("RPC")["LINE_OFF"].split()[0] == geom["line_off"]  # GDAL pairs the _RPC.TXT
    cropped = rpc_transformer(crop)
    ground = ground_points(full, x0, y0)
    in_product, ok_product = full.TransformPoints(1, ground.tolist())
    in_crop, ok_crop = cropped.TransformPoints(1, ground.tolist())
    assert all(ok_product) and all(ok_crop)
    off_px = np.abs(np.array(in_crop)[:, :2] + (x0, y0) - np.array(in_product)[:, :2]).max()
    assert off_px < 1e-6                                                   # measured 1.1e-11 px
    pixels = [(c, r, h) for (c, r, _), h in zip(in_crop, ground[:, 2])]
    seen_in_crop, ok_crop = cropped.TransformPoints(0, pixels)
    seen_in_product, ok_product = full.TransformPoints(0, [(c + x0, r + y0, h) for c, r, h in pixels])
    assert all(ok_crop) and all(ok_product)
    assert np.abs(np.array(seen_in_crop) - np.array(seen_in_product)).max() < 1e-12  # deg; measured 7e-15


def test_the_srtm_window_has_nan_holes_and_covers_the_crops(ventoux):
    """srtm_big_hole.tif: 256 x 256 Float32 cells of 3" (EPSG:4326, EGM96 heights), NaN over the Ventoux
    massif (every height above 1000 m removed in the source: 10421 cells, 16 %), 164 to 1000 m elsewhere; it
    covers both crops' ground with heights (450 to 600 m)."""
    ds = gdal.Open(str(ventoux / "srtm_big_hole.tif"))
    band = ds.GetRasterBand(1)
    heights = band.ReadAsArray()
    assert heights.shape == (256, 256) and band.DataType == gdal.GDT_Float32 and np.isnan(band.GetNoDataValue())
    holes = np.isnan(heights)
    assert holes.sum() == 10421
    assert np.nanmin(heights) == 164.0 and np.nanmax(heights) == 1000.0
    lon0, dlon, _, lat0, _, dlat = ds.GetGeoTransform()
    for name in NAMES:
        scene = load_scene(ventoux / f"{name}.tif")
        cols, rows = SIZES[name]
        lon, lat = scene.rpc.image_to_ground(np.array([0, cols, 0, cols]), np.array([0, 0, rows, rows]), 500.0)
        i, j = ((lat - lat0) / dlat).astype(int), ((lon - lon0) / dlon).astype(int)
        under = heights[i.min() - 1:i.max() + 2, j.min() - 1:j.max() + 2]
        assert np.all(np.isfinite(under)) and 400 < under.min() and under.max() < 650, (name, under)
