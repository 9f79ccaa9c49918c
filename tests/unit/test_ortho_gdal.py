"""Consistency with GDAL: gdalwarp with the RPC we export, on the same DEM and grid, gives the
orthoimage our rigorous orthorectification gives, to a fraction of a pixel."""
from dataclasses import replace

import numpy as np
import pytest
from osgeo import gdal

from core.dem import Dem
from core.ortho import default_grid, orthorectify
from core.render import render_image, texture_frame
from core.rpcfit import dem_height_range, fit_rpc, sidecar_path, write_rpc
from core.scene_io import load_scene
from core.simulator import simulate
from tests.ortho_compare import gdal_rpc_against_rigorous, image_difference


@pytest.fixture(scope="module")
def both(tmp_path_factory):
    """A 1500-row cut of the onboard CBERS-02B model (the nominal camera, which one RPC
    follows), its rendered image with the exported RPC beside it, the ellipsoidal DEM, the
    common grid, and the two orthoimages: ours and gdalwarp's."""
    folder = tmp_path_factory.mktemp("gdal")
    result = simulate("cbers02b_hrc", folder, seed=4, n_gcps=5)
    full = load_scene(result.onboard_scene)
    scene = replace(full, cameras=[replace(full.cameras[0], rows=1500)], _guess={})
    dem_path = Dem(result.dem, datum="geoid").write_ellipsoidal(folder / "dem_ellipsoid.tif")
    dem = Dem(dem_path, datum="ellipsoid")
    raw = folder / "raw.tif"
    render_image(scene, 0, dem, raw, texture_frame(full, dem, 4))
    rpc, report = fit_rpc(scene, 0, dem_height_range(scene, dem))
    write_rpc(rpc, sidecar_path(raw), report)
    grid = default_grid(scene, 0, dem)
    orthorectify(scene, raw, dem, folder / "ours.tif", grid=grid, resampling="bilinear")
    gdal.Warp(str(folder / "gdalwarp.tif"), str(raw), rpc=True, transformerOptions=[f"RPC_DEM={dem_path}"],
              dstSRS=grid.crs.to_wkt(), outputBounds=(grid.x0, grid.y0 - grid.rows * grid.resolution,
                                                      grid.x0 + grid.cols * grid.resolution, grid.y0),
              width=grid.cols, height=grid.rows, resampleAlg="bilinear", dstNodata=0)
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
