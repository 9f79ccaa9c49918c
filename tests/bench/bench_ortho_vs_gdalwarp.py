"""Our orthorectification against gdalwarp with the exported RPC, on one full CBERS-02B scene.
Prints figures (no assertions).

Run:  PYTHONPATH=. PROJ_DATA=/usr/share/proj /usr/bin/python3 tests/bench/bench_ortho_vs_gdalwarp.py
      [--repeats 2] [--out DIR] [--keep]

The scene: the simulated default CBERS-02B HRC scene (seed 0), its raw 12246 x 12246 8-bit
image rendered from the known texture with the true model, and orthorectified with the
onboard model (the nominal camera, which one RPC follows to 0.03 px) onto the default grid
(the scene's UTM zone at the native GSD: about 15 000 x 15 000 px). Both tools get:
  - the same image file (tiled DEFLATE GeoTIFF) and the same DEM file, in ellipsoidal heights
    (GDAL's RPC_DEM takes heights as ellipsoidal when the DEM carries no vertical CRS),
  - the same output grid (CRS, origin, pixel size, size), bilinear resampling, nodata 0,
  - the same output options: tiled 512 x 512, DEFLATE + predictor 2, compression on all cores.
gdalwarp runs as the issue states it: ``gdalwarp -rpc -to RPC_DEM=dem -r bilinear -multi
-wo NUM_THREADS=ALL_CPUS`` with the RPC fitted to the same model (``core.products.rpcfit``, an
``_RPC.TXT`` beside the image). Ours writes overviews as part of its product; gdalwarp does not,
so its time is given alone and with ``gdaladdo`` making the same overviews.

Each run is a separate process, timed by wall clock, with its peak resident memory; runs
alternate (ours, gdalwarp, ours, ...) so machine load hits both alike.

Consistency of the two orthoimages:
  - geometry: at 200 000 random output pixels, the image position our model gives against the
    one GDAL's RPC transformer gives with the same DEM (px of the raw image);
  - image: the shift (px) between the two orthoimages by least squares on image gradients,
    overall and in 8 x 8 blocks (largest block given), and the mean absolute difference (DN).

The harness (and this scene, prepare_cbers) is in tests/support/ortho_bench.py.
"""
from __future__ import annotations

import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))
import tests.support.plugin_package  # noqa: E402,F401 (registers the package pushbroom_adjust)

from tests.support.ortho_bench import prepare_cbers, run_benchmark  # noqa: E402


if __name__ == "__main__":
    run_benchmark(prepare_cbers, __doc__, __file__)
