"""Orthorectification of an RPC-only scene against gdalwarp with the same RPC and DEM.
Prints figures (no assertions).

Run:  PYTHONPATH=. PROJ_DATA=/usr/share/proj /usr/bin/python3 tests/bench/bench_ortho_rpc_vs_gdalwarp.py
      [--repeats 2] [--out DIR] [--keep]

The scene: the Pleiades vendor RPC (tests/data/pleiades, Global_RFM), scaled to a 12246 x 11710
image (3.27 times coarser pixels, the same ground), an 8-bit tiled GeoTIFF with the RPC in its
tags; the DEM: the vendor's (ellipsoidal heights) extended by its edge values so that it covers
the whole scene. Our side reads the scene from the image itself (SCENE = the image), gdalwarp
uses ``-rpc -to RPC_DEM=dem``; same grid (the image's footprint in its UTM zone at the native GSD),
bilinear resampling, nodata 0 and output options, as in bench_ortho_vs_gdalwarp.py (the same
harness, tests/support/ortho_bench.py, runs it: timings per process, alternating, peak memory;
geometry at 200 000 output pixels against GDAL's RPC transformer; image shift by least squares on
gradients).
"""
from __future__ import annotations

import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))
import tests.support.plugin_package  # noqa: E402,F401 (registers the package pushbroom_adjust)

from pushbroom_adjust.core.dem import Dem  # noqa: E402
from pushbroom_adjust.core.products.ortho import default_grid  # noqa: E402
from pushbroom_adjust.core.formats import load_scene  # noqa: E402
from tests.support.ortho_bench import run_benchmark  # noqa: E402
from tests.support.paths import TEST_DATA  # noqa: E402
from tests.support.rpcdata import padded_dem, pleiades_rpc, scaled, write_image  # noqa: E402
from pushbroom_adjust.core.model.rpcscene import size_from_rpc  # noqa: E402

COLS = 12246


def prepare(work: Path) -> dict:
    """The RPC image, the DEM and the common grid."""
    rpc = scaled(pleiades_rpc(TEST_DATA), 40000.0 / COLS)
    raw = write_image(work / "raw.tif", *size_from_rpc(rpc), rpc)
    dem_path = padded_dem(TEST_DATA, work / "dem_ellipsoid.tif")
    grid = default_grid(load_scene(raw), 0, Dem(dem_path, datum="ellipsoid"))
    return {"scene": str(raw), "raw": str(raw), "dem": str(dem_path),
            "grid": {"crs": grid.crs.to_wkt(), "x0": grid.x0, "y0": grid.y0, "resolution": grid.resolution,
                     "cols": grid.cols, "rows": grid.rows}}


if __name__ == "__main__":
    run_benchmark(prepare, __doc__, __file__)
