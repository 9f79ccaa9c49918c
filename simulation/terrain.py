"""The simulated ground's heights: a synthetic terrain, deterministic by seed, and its DEM file."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from osgeo import gdal, osr

from ..core.files import check_closed, closing_errors
from .texture import texture_plane

gdal.UseExceptions()


def terrain_heights(lon, lat, centre: tuple[float, float], relief: float, seed: int) -> np.ndarray:
    """Synthetic terrain (m above the geoid) at (lon, lat) degrees: a sum of random plane
    waves with wavelengths 1.5-40 km and amplitudes growing with wavelength, spanning about
    ``relief`` metres above a 200 m plain. Smooth at the DEM spacing, deterministic by seed."""
    rng = np.random.default_rng([seed, 7])
    n = 24
    wavelength = np.exp(rng.uniform(np.log(1.5e3), np.log(40e3), n))
    direction = rng.uniform(0.0, 2 * math.pi, n)
    phase = rng.uniform(0.0, 2 * math.pi, n)
    amp = wavelength / wavelength.sum()
    x, y = texture_plane(lon, lat, centre)
    k = 2 * math.pi / wavelength
    h = np.zeros(np.broadcast(x, y).shape)
    for i in range(n):  # a few waves over the whole grid: numpy does the work per wave
        h += amp[i] * np.cos(k[i] * (x * np.cos(direction[i]) + y * np.sin(direction[i])) + phase[i])
    # The sum is near-Gaussian with this standard deviation: +-3 sigma spans the relief.
    sigma = math.sqrt(float(np.sum(amp ** 2)) / 2.0)
    return 200.0 + relief * (0.5 + h / (6.0 * sigma)).clip(0.0, 1.0)


def write_dem(path: Path, bounds: tuple[float, float, float, float], centre, relief: float, seed: int,
              max_cells: int = 4_000_000) -> None:
    """A GeoTIFF DEM in EPSG:4326 (EGM96 geoid heights, Float32) covering ``bounds``
    (lon_min, lat_min, lon_max, lat_max) at 1 arc-second, coarser if it would exceed max_cells."""
    lon_min, lat_min, lon_max, lat_max = bounds
    step = max(1.0 / 3600.0, math.sqrt((lon_max - lon_min) * (lat_max - lat_min) / max_cells))
    nx = int(math.ceil((lon_max - lon_min) / step)) + 1
    ny = int(math.ceil((lat_max - lat_min) / step)) + 1
    lon = lon_min + (np.arange(nx) + 0.5) * step
    lat = lat_max - (np.arange(ny) + 0.5) * step
    z = terrain_heights(lon[None, :], lat[:, None], centre, relief, seed).astype(np.float32)
    ds = gdal.GetDriverByName("GTiff").Create(str(path), nx, ny, 1, gdal.GDT_Float32,
                                              ["COMPRESS=DEFLATE", "PREDICTOR=3", "TILED=YES"])
    ds.SetGeoTransform((lon_min, step, 0.0, lat_max, 0.0, -step))
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(4326)
    ds.SetProjection(srs.ExportToWkt())
    band = ds.GetRasterBand(1)
    band.WriteArray(z)
    band.SetNoDataValue(-32768.0)
    band.SetDescription("height above the EGM96 geoid (m)")
    with closing_errors() as closing:
        band = ds = None  # closes the file
    check_closed(path, closing)


def set_height_range(scenes, dem, margin: float = 50.0) -> None:
    """Set each scene model's ``info['height_range']`` to the DEM's (ellipsoidal m) widened by
    ``margin`` m and rounded outward to whole metres: the heights its products and RPCs span."""
    lo, hi = dem.height_range
    for scene in scenes:
        scene.info["height_range"] = [math.floor(lo - margin), math.ceil(hi + margin)]
