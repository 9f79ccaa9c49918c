"""Digital elevation models for ray intersection.

A DEM is read once into memory as float64 ellipsoidal heights (EPSG:4979 sense). Heights
of a geoid-referenced DEM (EGM96, as SRTM and most national DEMs) are converted with the
PROJ geoid grid ``egm96_15.gtx`` at load. Sampling is bilinear in the DEM's own CRS;
queries outside the DEM, or on nodata, return NaN so callers can say what is uncovered.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from osgeo import gdal
from pyproj import CRS, Transformer
from pyproj.exceptions import CRSError

from .errors import InputError

gdal.UseExceptions()

GEOID_GRID = "egm96_15.gtx"


def geoid_undulation(lon, lat) -> np.ndarray:
    """EGM96 geoid height N (m) above WGS84 at (lon, lat) degrees: h_ellipsoid = H_geoid + N."""
    tr = Transformer.from_pipeline(f"+proj=vgridshift +grids={GEOID_GRID} +multiplier=1")
    lon = np.asarray(lon, dtype=float)
    lat = np.asarray(lat, dtype=float)
    _, _, n = tr.transform(lon, lat, np.zeros_like(lon, dtype=float))
    n = np.asarray(n, dtype=float)
    if not np.all(np.isfinite(n)) or np.all(n == 0.0) and lon.size > 0:
        raise InputError(f"geoid grid {GEOID_GRID} is not available to PROJ (install Debian's proj-data)")
    return n


def to_ellipsoidal(lon, lat, height, datum: str) -> np.ndarray:
    """Heights (m) in ``datum`` ('ellipsoid' or 'geoid' = EGM96) -> ellipsoidal heights."""
    if datum == "ellipsoid":
        return np.asarray(height, dtype=float)
    if datum == "geoid":
        return np.asarray(height, dtype=float) + geoid_undulation(lon, lat)
    raise InputError(f"height datum must be 'ellipsoid' or 'geoid' (got {datum!r})")


@dataclass
class ConstantHeight:
    """A flat surface at one ellipsoidal height (m): the DEM to use when there is none."""
    value: float

    def height(self, lon, lat) -> np.ndarray:
        return np.full(np.shape(lon), float(self.value))

    @property
    def height_range(self) -> tuple[float, float]:
        return float(self.value), float(self.value)


class Dem:
    """A raster DEM in memory, sampled bilinearly.

    path: any GDAL raster with a CRS; band 1 holds heights in metres.
    datum: 'geoid' (EGM96, converted at load) or 'ellipsoid'.
    """

    def __init__(self, path: str | Path, datum: str = "geoid"):
        self.path = str(path)
        try:
            ds = gdal.Open(self.path)
        except RuntimeError as exc:
            raise InputError(f"DEM {self.path}: cannot be opened as a raster ({exc})") from None
        wkt = ds.GetProjection()
        if not wkt:
            raise InputError(f"DEM {self.path}: has no coordinate reference system; assign one (e.g. EPSG:4326)")
        try:
            self.crs = CRS.from_wkt(wkt)
        except CRSError as exc:
            raise InputError(f"DEM {self.path}: unknown CRS ({exc})") from None
        band = ds.GetRasterBand(1)
        z = band.ReadAsArray().astype(np.float64)
        nodata = band.GetNoDataValue()
        if nodata is not None:
            z[z == nodata] = np.nan
        gt = ds.GetGeoTransform()
        if gt[2] != 0 or gt[4] != 0:
            raise InputError(f"DEM {self.path}: rotated geotransforms are not supported; warp it to north-up first")
        self.gt = gt
        self.shape = z.shape
        self._to_dem = None if self.crs.equals(CRS.from_epsg(4326), ignore_axis_order=True) else \
            Transformer.from_crs(CRS.from_epsg(4326), self.crs, always_xy=True)
        if datum != "ellipsoid":
            lon, lat = self._node_lonlat()
            z = to_ellipsoidal(lon, lat, z, datum)
        self.datum = datum
        self.z = z
        finite = z[np.isfinite(z)]
        if finite.size == 0:
            raise InputError(f"DEM {self.path}: holds no valid heights")
        self._range = (float(finite.min()), float(finite.max()))

    def _node_lonlat(self) -> tuple[np.ndarray, np.ndarray]:
        rows, cols = np.mgrid[0:self.shape[0], 0:self.shape[1]]
        x = self.gt[0] + (cols + 0.5) * self.gt[1]
        y = self.gt[3] + (rows + 0.5) * self.gt[5]
        if self._to_dem is None:
            return x, y
        back = Transformer.from_crs(self.crs, CRS.from_epsg(4326), always_xy=True)
        return back.transform(x, y)

    @property
    def height_range(self) -> tuple[float, float]:
        """(min, max) ellipsoidal height in metres."""
        return self._range

    def write_ellipsoidal(self, path: str | Path) -> Path:
        """Write the DEM's ellipsoidal heights (float32, same grid and CRS, nodata NaN) to a
        GeoTIFF: what tools that take DEM heights as ellipsoidal (GDAL's RPC_DEM) need."""
        src = gdal.Open(self.path)
        ds = gdal.GetDriverByName("GTiff").Create(str(path), self.shape[1], self.shape[0], 1, gdal.GDT_Float32,
                                                  ["COMPRESS=DEFLATE"])
        ds.SetGeoTransform(self.gt)
        ds.SetProjection(src.GetProjection())
        band = ds.GetRasterBand(1)
        band.SetNoDataValue(float("nan"))
        band.WriteArray(self.z.astype(np.float32))
        band = ds = None
        return Path(path)

    def bounds_lonlat(self) -> tuple[float, float, float, float]:
        """(lon_min, lat_min, lon_max, lat_max) of the DEM's node centres."""
        lon, lat = self._node_lonlat()
        return float(np.min(lon)), float(np.min(lat)), float(np.max(lon)), float(np.max(lat))

    def height(self, lon, lat) -> np.ndarray:
        """Bilinear ellipsoidal height (m) at (lon, lat) degrees; NaN outside or on nodata."""
        lon = np.asarray(lon, dtype=float)
        lat = np.asarray(lat, dtype=float)
        if self._to_dem is not None:
            lon, lat = self._to_dem.transform(lon, lat)
        fx = (lon - self.gt[0]) / self.gt[1] - 0.5
        fy = (lat - self.gt[3]) / self.gt[5] - 0.5
        ny, nx = self.shape
        ok = (fx >= 0) & (fy >= 0) & (fx <= nx - 1) & (fy <= ny - 1)
        fx = np.where(ok, fx, 0.0)
        fy = np.where(ok, fy, 0.0)
        i = np.minimum(fy.astype(np.int64), max(ny - 2, 0))
        j = np.minimum(fx.astype(np.int64), max(nx - 2, 0))
        wy, wx = fy - i, fx - j
        z = self.z
        i1, j1 = np.minimum(i + 1, ny - 1), np.minimum(j + 1, nx - 1)
        val = ((z[i, j] * (1 - wx) + z[i, j1] * wx) * (1 - wy) + (z[i1, j] * (1 - wx) + z[i1, j1] * wx) * wy)
        return np.where(ok, val, np.nan)
