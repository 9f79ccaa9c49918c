"""Consistency with GDAL: gdalwarp with the RPC we export, on the same DEM and grid, gives the
orthoimage our rigorous orthorectification gives, to a fraction of a pixel."""

import numpy as np
import pytest
from osgeo import gdal

from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.products.ortho import default_grid, orthorectify
from pushbroom_adjust.core.formats.rpcfiles import sidecar_path, write_rpc
from pushbroom_adjust.core.products.rpcfit import dem_height_range, fit_rpc
from tests.support.ortho_compare import gdal_rpc_against_rigorous, gdalwarp_rpc, image_difference, rendered_cut


@pytest.fixture(scope="module")
def both(tmp_path_factory):
    """A 1500-row cut of the onboard CBERS-02B model (the nominal camera, which one RPC
    follows), its rendered image with the exported RPC beside it, the ellipsoidal DEM, the
    common grid, and the two orthoimages: ours and gdalwarp's."""
    folder = tmp_path_factory.mktemp("gdal")
    scene, result, geoid_dem, _ = rendered_cut(folder, seed=4, rows=1500, model="onboard_scene")
    dem_path = geoid_dem.write_ellipsoidal(folder / "dem_ellipsoid.tif")
    dem = Dem(dem_path, datum="ellipsoid")
    raw = folder / "raw.tif"
    rpc, report = fit_rpc(scene, 0, dem_height_range(scene, dem))
    write_rpc(rpc, sidecar_path(raw), report)
    grid = default_grid(scene, 0, dem)
    orthorectify(scene, raw, dem, folder / "ours.tif", grid=grid, resampling="bilinear")
    gdalwarp_rpc(raw, dem_path, grid, folder / "gdalwarp.tif")
    return scene, dem_path, raw, grid, folder, report


def test_gdal_rpc_transformer_maps_output_pixels_where_we_do(both):
    scene, dem_path, raw, grid, folder, report = both
    err = gdal_rpc_against_rigorous(scene, dem_path, raw, grid, n=50_000)
    assert err.size > 10_000
    # what is left is the RPC's own fit error (report), nothing from DEM sampling or conventions
    assert np.sqrt(np.mean(err ** 2)) < 0.05 and err.max() < 0.1, (np.sqrt(np.mean(err ** 2)), err.max())
    assert err.max() <= report["check"]["max_px"] + 0.01


def test_gdalwarp_orthoimage_matches_ours_within_a_tenth_of_a_pixel(both):
    scene, dem_path, raw, grid, folder, report = both
    ds = gdal.Open(str(folder / "gdalwarp.tif"))
    assert (ds.RasterXSize, ds.RasterYSize) == (grid.cols, grid.rows)
    assert ds.GetGeoTransform() == pytest.approx(grid.geotransform())
    diff = image_difference(str(folder / "ours.tif"), str(folder / "gdalwarp.tif"), blocks=4)
    assert diff["pixels"] > 500_000
    assert np.hypot(*diff["shift_px"]) < 0.02 and diff["worst_block_shift_px"] < 0.1, diff
    assert diff["mean_abs_difference_dn"] < 1.0, diff
