"""Orthorectification with a real vendor model: the Pleiades 1B scene's rigorous model (DIMAP v2)
against gdalwarp with the vendor's own Global_RFM, on the same DEM and grid.

The scene's image is not shipped, so the raw image is a sparse 40000 x 38248 GeoTIFF holding a
random texture in a 1536 x 1536 window near the centre; the orthoimage covers that window. The
40000-column image is read window by window (memory_budget=0), as full scenes are."""
import numpy as np
import pytest
from osgeo import gdal
from pyproj import CRS, Transformer
from scipy import ndimage

from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.geodesy import ecef_to_geodetic
from pushbroom_adjust.core.products.mapping import utm_crs
from pushbroom_adjust.core.products.ortho import default_grid, orthorectify
from pushbroom_adjust.core.formats.dimaprfm import read_dimap_rfm
from pushbroom_adjust.core.formats.rpcfiles import sidecar_path, write_rpc
from pushbroom_adjust.core.formats import load_scene
from tests.support.ortho_compare import gdalwarp_rpc, image_difference

XML = "pleiades/PHRDIMAP_P1BP--2018122638935449CP.XML"
MNT = "pleiades/MNT_P1BP--2018122638935449CP.tif"  # ellipsoidal heights (tests/unit/formats/test_dimap.py)
WINDOW = (19000, 18000, 1536)  # first column, first row, size (px) of the textured window


@pytest.fixture(scope="module")
def pleiades_orthos(shared_data, tmp_path_factory):
    folder = tmp_path_factory.mktemp("pleiades_ortho")
    scene = load_scene(shared_data / XML)
    cam = scene.cameras[0]
    c0, r0, n = WINDOW
    raw = folder / "raw.tif"
    ds = gdal.GetDriverByName("GTiff").Create(str(raw), cam.cols, cam.rows, 1, gdal.GDT_UInt16,
                                              ["TILED=YES", "SPARSE_OK=TRUE", "COMPRESS=DEFLATE"])
    noise = ndimage.gaussian_filter(np.random.default_rng(0).normal(size=(n, n)), 1.5)
    ds.GetRasterBand(1).WriteArray((2000 + 8000 * noise / noise.std()).clip(1, 65535).astype(np.uint16), c0, r0)
    ds = None
    vendor, _ = read_dimap_rfm(shared_data / XML)
    write_rpc(vendor, sidecar_path(raw))
    dem_path = shared_data / MNT
    dem = Dem(dem_path, datum="ellipsoid")
    # the grid: the ground under the window's inner part, in the scene's UTM zone
    col = np.array([c0 + 100, c0 + n - 100, c0 + 100, c0 + n - 100], dtype=float)
    row = np.array([r0 + 100, r0 + 100, r0 + n - 100, r0 + n - 100], dtype=float)
    lon, lat, _ = ecef_to_geodetic(scene.image_to_ground_dem(col, row, dem))
    crs = utm_crs(float(lon.mean()), float(lat.mean()))
    x, y = Transformer.from_crs(CRS.from_epsg(4326), crs, always_xy=True).transform(lon, lat)
    grid = default_grid(scene, 0, dem, crs=crs, extent=(x.min(), y.min(), x.max(), y.max()))
    figures = orthorectify(scene, raw, dem, folder / "ours.tif", grid=grid, memory_budget=0)
    gdalwarp_rpc(raw, dem_path, grid, folder / "gdalwarp.tif")
    return folder, grid, figures


def test_our_pleiades_orthoimage_matches_gdalwarp_with_the_vendor_rfm(pleiades_orthos):
    folder, grid, figures = pleiades_orthos
    assert grid.cols * grid.rows > 1e6 and 0.4 < grid.resolution < 0.7
    assert figures["densification_error_px"] < 0.01 and figures["dem_gap_share"] == 0
    diff = image_difference(str(folder / "ours.tif"), str(folder / "gdalwarp.tif"), blocks=4)
    assert diff["pixels"] > 500_000
    # our rigorous model and the vendor RFM agree to 0.001 px; resampling adds nothing systematic
    assert np.hypot(*diff["shift_px"]) < 0.02 and diff["worst_block_shift_px"] < 0.05, diff
