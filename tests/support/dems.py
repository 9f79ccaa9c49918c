"""DEMs made in the tests from another DEM: with nodata holes (NaN, or a nodata value), cut to a part,
or with steps (a DSM's buildings)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from osgeo import gdal

gdal.UseExceptions()


def write_dem(path, z: np.ndarray, gt, wkt: str, nodata: float | None = None, dtype=gdal.GDT_Float32) -> str:
    """A GeoTIFF DEM of heights z (rows, cols) on geotransform ``gt`` in CRS ``wkt``."""
    ds = gdal.GetDriverByName("GTiff").Create(str(path), z.shape[1], z.shape[0], 1, dtype)
    ds.SetGeoTransform(tuple(gt))
    ds.SetProjection(wkt)
    band = ds.GetRasterBand(1)
    if nodata is not None:
        band.SetNoDataValue(float(nodata))
    band.WriteArray(z)
    band = ds = None
    return str(path)


def read_dem(path) -> tuple[np.ndarray, tuple, str]:
    """(heights as float64, NaN on nodata; geotransform; CRS WKT) of a DEM file."""
    ds = gdal.Open(str(path))
    band = ds.GetRasterBand(1)
    z = band.ReadAsArray().astype(float)
    if band.GetNoDataValue() is not None:
        z[z == band.GetNoDataValue()] = np.nan
    return z, ds.GetGeoTransform(), ds.GetProjection()


def blob_holes(shape: tuple[int, int], share: float, seed: int = 0, size: int = 6) -> np.ndarray:
    """A mask (rows, cols) of square holes of ``size`` pixels at random places covering about
    ``share`` of it (a DSM's voids: shadows, water)."""
    rng = np.random.default_rng(seed)
    mask = np.zeros(shape, bool)
    for _ in range(max(1, int(share * mask.size / size ** 2))):
        a, b = rng.integers(0, shape[0] - size), rng.integers(0, shape[1] - size)
        mask[a:a + size, b:b + size] = True
    return mask


def with_holes(src, out, mask: np.ndarray, nodata: float | None = None) -> str:
    """The DEM ``src`` with the pixels of ``mask`` made nodata: NaN (nodata NaN) or, with ``nodata``,
    that value in an Int16 raster (the heights rounded), as SRTM delivers its voids."""
    z, gt, wkt = read_dem(src)
    if nodata is None:
        return write_dem(out, np.where(mask, np.nan, z).astype(np.float32), gt, wkt, float("nan"))
    return write_dem(out, np.where(mask | ~np.isfinite(z), nodata, np.rint(z)).astype(np.int16), gt, wkt, nodata,
                     gdal.GDT_Int16)


def western_part(src, out, share: float = 0.5) -> str:
    """The DEM ``src`` cut to its western ``share`` of columns."""
    z, gt, wkt = read_dem(src)
    return write_dem(out, z[:, :int(share * z.shape[1])].astype(np.float32), gt, wkt, float("nan"))


def stepped(src, out, spacing_deg: float, lon: tuple[float, float], lat: tuple[float, float], n_blocks: int,
            heights=(10.0, 20.0, 30.0), seed: int = 0, block_px: tuple[int, int] = (5, 30)) -> Path:
    """A DSM (EPSG:4326, ``spacing_deg`` pixels over lon x lat degrees; ellipsoidal heights) of
    ``src``'s terrain (any object with ``height(lon, lat)``: a core.dem.Dem, a ConstantHeight) with
    ``n_blocks`` buildings: rectangles of ``block_px`` pixels raised by one of ``heights`` m, their
    walls a step from one pixel to the next."""
    nx = int((lon[1] - lon[0]) / spacing_deg)
    ny = int((lat[1] - lat[0]) / spacing_deg)
    glon, glat = np.meshgrid(lon[0] + (np.arange(nx) + 0.5) * spacing_deg, lat[1] - (np.arange(ny) + 0.5) * spacing_deg)
    z = src.height(glon, glat)
    rng = np.random.default_rng(seed)
    for _ in range(n_blocks):
        a, b = rng.integers(0, ny - block_px[0]), rng.integers(0, nx - block_px[0])
        h, w = rng.integers(*block_px, 2)
        z[a:a + h, b:b + w] += rng.choice(heights)
    wkt = 'GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563]],PRIMEM["Greenwich",0],' \
          'UNIT["degree",0.0174532925199433],AXIS["Latitude",NORTH],AXIS["Longitude",EAST],AUTHORITY["EPSG","4326"]]'
    return Path(write_dem(out, z.astype(np.float32), (lon[0], spacing_deg, 0.0, lat[1], 0.0, -spacing_deg), wkt))
