"""Cost of the tie points' height constraint (DEM with TIE_HEIGHT_SIGMA, :mod:`core.adjust.tieheights`, issue
31): one evaluation at the current ground (the DEM sampled, EGM96 added, the rank-1 weights and misfits) for
10 000 to 1 000 000 tie points. The adjustment evaluates it once per linearisation and once per cost (each
Levenberg-Marquardt trial). Prints CPU seconds per evaluation (no assertions).

Run:  PYTHONPATH=. PROJ_DATA=/usr/share/proj /usr/bin/python3 tests/bench/bench_tieheights.py

The DEM: 3600 x 3600 cells of 1" (a 1 x 1 degree tile like Copernicus GLO-30, random heights 0-1000 m,
EGM96), written to a temporary GeoTIFF; the points uniform over it at 500 m ellipsoidal height. The first
evaluation (which reads the DEM window) is not timed.
"""
from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from osgeo import gdal, osr

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from tests.support import plugin_package  # noqa: F401 (registers the package pushbroom_adjust)

from pushbroom_adjust.core.adjust.tieheights import TieHeights
from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.geodesy import geodetic_to_ecef

CELLS = 3600
STEP = 1.0 / 3600.0
ORIGIN = (113.0, 35.0)  # lon, lat of the tile's north-west corner


def write_tile(path: Path) -> None:
    ds = gdal.GetDriverByName("GTiff").Create(str(path), CELLS, CELLS, 1, gdal.GDT_Float32, ["TILED=YES"])
    ds.SetGeoTransform((ORIGIN[0], STEP, 0.0, ORIGIN[1], 0.0, -STEP))
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(4326)
    ds.SetProjection(srs.ExportToWkt())
    ds.GetRasterBand(1).WriteArray(np.random.default_rng(0).uniform(0.0, 1000.0, (CELLS, CELLS)).astype(np.float32))
    ds = None


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "tile.tif"
        write_tile(path)
        reference = TieHeights(Dem(path, "geoid"), 5.0)
        rng = np.random.default_rng(1)
        for n in (10_000, 100_000, 1_000_000):
            lon = ORIGIN[0] + rng.uniform(0.01, 0.99, n)
            lat = ORIGIN[1] - rng.uniform(0.01, 0.99, n)
            ground = geodetic_to_ecef(lon, lat, np.full(n, 500.0))
            reference.at(ground)
            start = time.process_time()
            c = reference.at(ground)
            c.weight, c.misfit, c.cost  # what the adjustment asks of it
            print(f"{n:>9,d} tie points: {time.process_time() - start:.3f} s CPU per evaluation, "
                  f"{int(c.on.sum()):,d} constrained")


if __name__ == "__main__":
    main()
