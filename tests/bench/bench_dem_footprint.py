"""Cost of a footprint on a large DEM, printed (no assertions).

Run:  PYTHONPATH=. /usr/bin/python3 tests/bench/bench_dem_footprint.py [--size 8000]

Simulates the default CBERS-02B HRC scene (12246 x 12246 px), writes a SIZE x SIZE geoid DEM
(EPSG:4326, Float32, tiled, deflate, the simulator's synthetic terrain) covering the simulator's
DEM area around the scene, then traces the scene's footprint on it (core.products.footprints,
what pushbroom:footprint runs) in a fresh Python process, and prints that process's peak
resident memory (before and after the footprint) and the footprint's time (wall clock and CPU:
on a shared machine the CPU time is the steadier figure). A second run on
the simulator's own DEM checks the footprint: the vertices of both agree to the printed distance.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from osgeo import gdal, osr

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))
import tests.support.plugin_package  # noqa: E402,F401 (registers the package pushbroom_adjust)

from pushbroom_adjust.simulation.presets import PRESETS  # noqa: E402
from pushbroom_adjust.simulation.terrain import terrain_heights  # noqa: E402
from pushbroom_adjust.simulation.simulator import simulate  # noqa: E402

CHILD = """
import json, re, sys, time
sys.path.insert(0, {repo!r})
from pushbroom_adjust.core.dem import Dem
from pushbroom_adjust.core.products.footprint import footprints
from pushbroom_adjust.core.formats import load_scene
def peak_mib():  # this process's own high-water mark (ru_maxrss would include the parent's before exec)
    return int(re.search(r"VmHWM:\\s+(\\d+) kB", open("/proc/self/status").read()).group(1)) / 1024
scene = load_scene({scene!r})
before = peak_mib()
t0, c0 = time.perf_counter(), time.process_time()
(fp,) = footprints(scene, Dem({dem!r}, datum="geoid"))
seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
print(json.dumps(dict(before=before, peak=peak_mib(),
                      seconds=seconds, cpu=cpu, area=fp.area_km2, lon=fp.lon.tolist(), lat=fp.lat.tolist())))
"""


def write_geoid_dem(path: Path, like: Path, size: int, centre, relief: float, seed: int) -> None:
    """A size x size Float32 geoid DEM over the area of the DEM ``like``, written by strips."""
    src = gdal.Open(str(like))
    gt = src.GetGeoTransform()
    lon0, lat0 = gt[0], gt[3]
    width, height = gt[1] * src.RasterXSize, -gt[5] * src.RasterYSize
    dx, dy = width / size, height / size
    ds = gdal.GetDriverByName("GTiff").Create(str(path), size, size, 1, gdal.GDT_Float32,
                                              ["COMPRESS=DEFLATE", "PREDICTOR=3", "TILED=YES", "BIGTIFF=YES"])
    ds.SetGeoTransform((lon0, dx, 0.0, lat0, 0.0, -dy))
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(4326)
    ds.SetProjection(srs.ExportToWkt())
    band = ds.GetRasterBand(1)
    band.SetNoDataValue(-32768.0)
    lon = lon0 + (np.arange(size) + 0.5) * dx
    for r0 in range(0, size, 512):
        lat = lat0 - (np.arange(r0, min(r0 + 512, size)) + 0.5) * dy
        band.WriteArray(terrain_heights(lon[None, :], lat[:, None], centre, relief, seed).astype(np.float32), 0, r0)
    band = ds = None


def run_footprint(scene: Path, dem: Path) -> dict:
    code = CHILD.format(repo=str(REPO), scene=str(scene), dem=str(dem))
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--size", type=int, default=8000, help="DEM width and height in pixels")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        result = simulate("cbers02b_hrc", tmp / "sim", seed=0, n_gcps=10)
        preset = PRESETS["cbers02b_hrc"]
        big = tmp / "dem_big.tif"
        write_geoid_dem(big, Path(result.dem), args.size, preset.centre, preset.relief, 0)
        print(f"DEM {args.size} x {args.size} px ({big.stat().st_size / 2 ** 20:.0f} MB on disk, "
              f"{args.size ** 2 * 4 / 2 ** 20:.0f} MB of Float32 heights)")
        small = run_footprint(Path(result.true_scene), Path(result.dem))
        large = run_footprint(Path(result.true_scene), big)
        for name, r in (("simulator's DEM", small), (f"{args.size}^2 DEM", large)):
            print(f"footprint on the {name}: {r['seconds']:.2f} s ({r['cpu']:.2f} s CPU), peak RSS {r['peak']:.0f} MiB "
                  f"({r['before']:.0f} MiB before the footprint), area {r['area']:.2f} km²")
        geod_dx = (np.array(large["lon"]) - small["lon"]) * 111_320 * np.cos(np.radians(np.array(small["lat"])))
        geod_dy = (np.array(large["lat"]) - small["lat"]) * 110_574
        print(f"footprint vertices of the two DEMs (same terrain) agree within {np.hypot(geod_dx, geod_dy).max():.3f} m")


if __name__ == "__main__":
    main()
