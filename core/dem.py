"""Digital elevation models for ray intersection, read only where and as finely as needed.

A :class:`Dem` opens its raster lazily: it keeps the geometry (CRS, geotransform, size) and reads
heights by window when asked for them. Callers say what they need: :meth:`Dem.height` reads the
window around the queried points (with a margin, kept for the next queries), at the DEM's own
resolution or at the coarser spacing a caller chose with :meth:`Dem.with_spacing` (a footprint
needs the terrain every ~100 m, not every metre). Coarse windows are block averages read with
GDAL's decimated RasterIO (which uses the raster's overviews when it has them), in strips, so
neither the heights nor GDAL's block cache ever hold more than the window.

Heights are returned as ellipsoidal metres (EPSG:4979 sense). A geoid-referenced DEM (EGM96, as
SRTM and most national DEMs) is converted at the queried points only: the undulation is taken by
PROJ (grid ``egm96_15.gtx``) on a fixed lattice of 1/16 degree nodes (it divides the grid's 15'
cells, so the bilinear lattice reproduces PROJ's own bilinear interpolation) and interpolated.
Sampling is bilinear between pixel centres in the DEM's own CRS; queries outside the DEM, or
on nodata, return NaN so callers can say what is uncovered: :meth:`Dem.no_height` tells the two
apart (points off the DEM, points on its nodata holes), and :func:`missing_heights` words them.
"""
from __future__ import annotations

import copy
import math
import threading
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from osgeo import gdal
from pyproj import CRS, Transformer
from pyproj.exceptions import CRSError

from .errors import InputError
from .files import check_closed, closing_errors
from .rasters import open_input_raster
from .validation import check_surface_heights

gdal.UseExceptions()

GEOID_GRID = "egm96_15.gtx"
GEOID_LATTICE_DEG = 1.0 / 16.0  # divides the 15' EGM96 grid cells
MAX_LATTICE_NODES = 1_000_000   # beyond this the undulation is evaluated at the points themselves
OVERVIEW_CELLS = 1024 * 1024    # the whole-DEM overview behind height_range
MAX_WINDOW_BYTES = 2 ** 30      # the largest window of heights held in memory
_STRIP_NODES = 128              # output rows per read; GDAL's block cache is released after each
_STRIP_BYTES = 32 * 2 ** 20     # at most this many bytes of DEM pixels per read averaged in numpy
_WINDOW_MARGIN = 0.25           # share of a window's size added on each side for the next queries


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


def geoid_undulation_lattice(lon, lat) -> np.ndarray:
    """:func:`geoid_undulation` (m) at (lon, lat) degrees, bilinear between the nodes of a fixed
    1/16 degree lattice covering the points: PROJ is asked at the lattice nodes only. The value at
    a place does not depend on the other points queried with it."""
    lon = np.asarray(lon, dtype=float)
    lat = np.asarray(lat, dtype=float)
    ok = np.isfinite(lon) & np.isfinite(lat)
    out = np.full(lon.shape, np.nan)
    if not ok.any():
        return out
    step = GEOID_LATTICE_DEG
    lon_ok, lat_ok = lon[ok], lat[ok]
    i0, j0 = math.floor(np.min(lat_ok) / step), math.floor(np.min(lon_ok) / step)
    i1, j1 = math.floor(np.max(lat_ok) / step) + 1, math.floor(np.max(lon_ok) / step) + 1
    if (i1 - i0 + 1) * (j1 - j0 + 1) > MAX_LATTICE_NODES:
        out[ok] = geoid_undulation(lon_ok, lat_ok)
        return out
    node_lat, node_lon = np.arange(i0, i1 + 1) * step, np.arange(j0, j1 + 1) * step
    n = geoid_undulation(*np.meshgrid(node_lon, node_lat))  # (lat, lon) nodes
    fy, fx = lat_ok / step - i0, lon_ok / step - j0
    out[ok] = _bilinear(n, fy, fx)
    return out


def to_ellipsoidal(lon, lat, height, datum: str) -> np.ndarray:
    """Heights (m) in ``datum`` ('ellipsoid' or 'geoid' = EGM96) -> ellipsoidal heights."""
    if datum == "ellipsoid":
        return np.asarray(height, dtype=float)
    if datum == "geoid":
        return np.asarray(height, dtype=float) + geoid_undulation(lon, lat)
    raise InputError(f"height datum must be 'ellipsoid' or 'geoid' (got {datum!r})")


def _bilinear(z: np.ndarray, fy: np.ndarray, fx: np.ndarray) -> np.ndarray:
    """Bilinear values of grid z (ny, nx) at fractional node indices (fy, fx) inside it."""
    ny, nx = z.shape
    i = np.clip(fy.astype(np.int64), 0, max(ny - 2, 0))
    j = np.clip(fx.astype(np.int64), 0, max(nx - 2, 0))
    wy, wx = fy - i, fx - j
    i1, j1 = np.minimum(i + 1, ny - 1), np.minimum(j + 1, nx - 1)
    z00, z01 = z[i, j].astype(float), z[i, j1].astype(float)
    z10, z11 = z[i1, j].astype(float), z[i1, j1].astype(float)
    return (z00 * (1 - wx) + z01 * wx) * (1 - wy) + (z10 * (1 - wx) + z11 * wx) * wy


def _block_sums(z: np.ndarray, step: int, h: int, w: int) -> np.ndarray:
    """Sums (float64) of the step x step blocks of z (h * step, w * step): (h, w). Along rows
    first, over contiguous memory, then along columns."""
    rows = z.reshape(h * step, w, step).sum(axis=2, dtype=np.float64)
    return rows.reshape(h, step, w).sum(axis=1)


@dataclass
class ConstantHeight:
    """A flat surface at one ellipsoidal height (m): the DEM to use when there is none."""
    value: float

    def height(self, lon, lat) -> np.ndarray:
        return np.full(np.shape(lon), float(self.value))

    @property
    def height_range(self) -> tuple[float, float]:
        return float(self.value), float(self.value)

    def no_height(self, lon, lat) -> tuple[np.ndarray, np.ndarray]:
        """(off, hole) as :meth:`Dem.no_height`: a constant height covers everything."""
        return np.zeros(np.shape(lon), bool), np.zeros(np.shape(lon), bool)


def surface_name(surface) -> str:
    """How a message names the terrain: 'DEM <path>' or 'constant ellipsoidal height <h> m'."""
    if hasattr(surface, "path"):
        return f"DEM {surface.path}"
    return f"constant ellipsoidal height {surface.value:g} m" if hasattr(surface, "value") else "the terrain surface"


def missing_heights(surface, lon, lat, what: str = "points") -> str:
    """'' when ``surface`` gives a height at every (lon, lat) degrees, else a sentence saying
    for how many of the ``what`` it gives none, and why: off the DEM's extent, on its nodata
    holes (voids)."""
    off, hole = surface.no_height(lon, lat)
    words = no_height_words(int(np.sum(off)), int(np.sum(hole)), int(np.size(off)), what)
    return f"{surface_name(surface)} {words}" if words else ""


def no_height_words(n_off: int, n_hole: int, total: int, what: str) -> str:
    """'' when nothing is missing, else 'gives no height for <n> of <total> <what> (<n_off> off its
    extent, <n_hole> on its nodata holes)', to follow the surface's name."""
    if n_off + n_hole == 0:
        return ""
    why = [f"{n_off} off its extent" if n_off else "", f"{n_hole} on its nodata holes" if n_hole else ""]
    return f"gives no height for {n_off + n_hole} of {total} {what} ({', '.join(filter(None, why))})"


@dataclass
class HeightGrid:
    """Heights in the DEM's datum (NaN = nodata) on a window of the DEM at decimation ``step``:
    node (i, j) is the centre of the step x step block of DEM pixels whose upper-left pixel is
    (row0 + i * step, col0 + j * step). z: (rows, cols) float32 or float64."""
    z: np.ndarray
    row0: int
    col0: int
    step: int

    def node_indices(self, px: np.ndarray, py: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Fractional node indices (fx, fy) of DEM pixel coordinates (px, py; GDAL, 0 = edge)."""
        return (px - self.col0) / self.step - 0.5, (py - self.row0) / self.step - 0.5

    def inside(self, px: np.ndarray, py: np.ndarray) -> np.ndarray:
        fx, fy = self.node_indices(px, py)
        ny, nx = self.z.shape
        return (fx >= 0) & (fy >= 0) & (fx <= nx - 1) & (fy <= ny - 1)

    def sample(self, px: np.ndarray, py: np.ndarray) -> np.ndarray:
        """Bilinear heights at DEM pixel coordinates; NaN outside the window or on nodata."""
        fx, fy = self.node_indices(px, py)
        ok = self.inside(px, py)
        val = _bilinear(self.z, np.where(ok, fy, 0.0), np.where(ok, fx, 0.0))
        return np.where(ok, val, np.nan)


class Dem:
    """A raster DEM read by window, sampled bilinearly.

    path: any GDAL raster with a north-up geotransform and a CRS; band 1 holds heights in metres.
    datum: 'geoid' (EGM96, converted at the sampled points) or 'ellipsoid'.
    max_bytes: the largest window of heights held in memory; a larger need is an InputError
    naming the DEM.
    """

    def __init__(self, path: str | Path, datum: str = "geoid", max_bytes: int = MAX_WINDOW_BYTES):
        self.path = str(path)
        if datum not in ("geoid", "ellipsoid"):
            raise InputError(f"height datum must be 'ellipsoid' or 'geoid' (got {datum!r})")
        self.datum = datum
        self.max_bytes = int(max_bytes)
        ds = self._open()
        if ds.GetMetadata("RPC") and ds.GetGeoTransform(can_return_null=True) is None:
            raise InputError(f"DEM {self.path}: a raw image with an RPC (no map georeferencing), not a DEM; give a "
                             "DEM (heights on a map grid with a CRS)")
        wkt = ds.GetProjection()
        if not wkt:
            raise InputError(f"DEM {self.path}: has no coordinate reference system; assign one (e.g. EPSG:4326)")
        try:
            self.crs = CRS.from_wkt(wkt)
        except CRSError as exc:
            raise InputError(f"DEM {self.path}: unknown CRS ({exc})") from None
        gt = ds.GetGeoTransform()
        if gt[2] != 0 or gt[4] != 0:
            raise InputError(f"DEM {self.path}: rotated geotransforms are not supported; warp it to north-up first")
        if gt[1] == 0 or gt[5] == 0:
            raise InputError(f"DEM {self.path}: its geotransform has a zero pixel size")
        self.gt = gt
        self.shape = (ds.RasterYSize, ds.RasterXSize)
        if min(self.shape) < 2:
            raise InputError(f"DEM {self.path}: {self.shape[1]} x {self.shape[0]} pixels; at least 2 x 2 are "
                             "needed to interpolate heights")
        band = ds.GetRasterBand(1)
        if gdal.DataTypeIsComplex(band.DataType) or band.DataType == gdal.GDT_Unknown:
            raise InputError(f"DEM {self.path}: band 1 is of type {gdal.GetDataTypeName(band.DataType)}; "
                             "heights must be real numbers (integer or floating point)")
        self._buf_type = gdal.GDT_Float64 if band.DataType == gdal.GDT_Float64 else gdal.GDT_Float32
        self._nodata = band.GetNoDataValue()
        self._to_dem = None if self.crs.equals(CRS.from_epsg(4326), ignore_axis_order=True) else \
            Transformer.from_crs(CRS.from_epsg(4326), self.crs, always_xy=True)
        self._step = 1
        self._grid: HeightGrid | None = None
        self._overview_grid: HeightGrid | None = None
        self._range: tuple[float, float] | None = None
        self._lock = threading.Lock()

    # --- what callers ask for ----------------------------------------------------------------
    @property
    def height_range(self) -> tuple[float, float]:
        """(min, max) ellipsoidal height (m) over the whole DEM: exact when the DEM has at most
        OVERVIEW_CELLS pixels, else from block averages widened by 10 % of the span (>= 20 m)."""
        if self._range is None:
            grid = self._overview()
            lo, hi = self._grid_range(grid)
            if grid.step > 1:
                pad = max(0.1 * (hi - lo), 20.0)
                lo, hi = lo - pad, hi + pad
            self._range = (lo, hi)
        return self._range

    def with_spacing(self, metres: float) -> "Dem":
        """This DEM sampled no finer than ``metres`` (block averages of whole DEM pixels): what a
        caller needing only the coarse terrain asks for. The DEM's own resolution if finer."""
        step = max(1, int(metres // self.pixel_size_m())) if np.isfinite(metres) else 1
        self.height_range
        coarse = copy.copy(self)
        coarse._step, coarse._grid, coarse._lock = step, None, threading.Lock()
        return coarse

    def pixel_size_m(self) -> float:
        """Approximate ground size (m) of a DEM pixel (geometric mean of its sides, at the DEM's
        centre for a geographic CRS)."""
        dx, dy = abs(self.gt[1]), abs(self.gt[5])
        if self.crs.is_geographic:
            lat = self.gt[3] + 0.5 * self.shape[0] * self.gt[5]
            return math.sqrt(dx * 111_320.0 * max(math.cos(math.radians(lat)), 1e-3) * dy * 110_574.0)
        unit = self.crs.axis_info[0].unit_conversion_factor if self.crs.axis_info else 1.0
        return math.sqrt(dx * dy) * unit

    def height(self, lon, lat) -> np.ndarray:
        """Bilinear ellipsoidal height (m) at (lon, lat) degrees; NaN outside or on nodata."""
        lon = np.asarray(lon, dtype=float)
        lat = np.asarray(lat, dtype=float)
        return self.values_at(*self.pixel_coordinates(lon, lat)) + self.datum_offset(lon, lat)

    def datum_offset(self, lon, lat) -> np.ndarray:
        """Ellipsoidal height minus DEM value (m) at (lon, lat) degrees: the geoid undulation of a
        geoid DEM, 0 for an ellipsoidal one (smooth either way)."""
        if self.datum == "geoid":
            return geoid_undulation_lattice(lon, lat)
        return np.zeros(np.shape(lon))

    def pixel_coordinates(self, lon, lat) -> tuple[np.ndarray, np.ndarray]:
        """DEM pixel coordinates (px = column, py = row; GDAL's, 0 at the raster's edge, pixel
        centres at +0.5) of (lon, lat) degrees."""
        lon = np.asarray(lon, dtype=float)
        lat = np.asarray(lat, dtype=float)
        x, y = (lon, lat) if self._to_dem is None else self._to_dem.transform(lon, lat)
        x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
        return (x - self.gt[0]) / self.gt[1], (y - self.gt[3]) / self.gt[5]

    def values_at(self, px: np.ndarray, py: np.ndarray) -> np.ndarray:
        """Bilinear DEM values (m, in the DEM's own datum) at DEM pixel coordinates (any equal
        shapes); NaN off the DEM or on nodata. Ellipsoidal heights differ from them by a smooth
        offset (the geoid undulation of a geoid DEM, else 0)."""
        grid = self.grid_at(px, py)
        return np.full(np.shape(px), np.nan) if grid is None else grid.sample(px, py)

    def grid_at(self, px: np.ndarray, py: np.ndarray) -> HeightGrid | None:
        """The window of DEM values (read when needed) that covers every one of the DEM pixel
        coordinates (px, py) lying on the DEM; None when none ever did."""
        return self._grid_for(np.asarray(px, dtype=float), np.asarray(py, dtype=float))

    def no_height(self, lon, lat) -> tuple[np.ndarray, np.ndarray]:
        """Where (lon, lat) degrees get no height: (off, hole) boolean masks, ``off`` outside
        the DEM (beyond its outer pixel centres), ``hole`` on it but on nodata (a void)."""
        px, py = self.pixel_coordinates(lon, lat)
        rows, cols = self.shape
        with np.errstate(invalid="ignore"):
            on_dem = (px >= 0.5) & (py >= 0.5) & (px <= cols - 0.5) & (py <= rows - 0.5)
        return ~on_dem, on_dem & ~np.isfinite(self.values_at(px, py))

    def write_ellipsoidal(self, path: str | Path) -> Path:
        """Write the DEM's ellipsoidal heights (float32, same grid and CRS, nodata NaN) to a
        GeoTIFF: what tools that take DEM heights as ellipsoidal (GDAL's RPC_DEM) need."""
        rows, cols = self.shape
        src = self._open()
        ds = gdal.GetDriverByName("GTiff").Create(str(path), cols, rows, 1, gdal.GDT_Float32,
                                                  ["COMPRESS=DEFLATE", "TILED=YES"])
        ds.SetGeoTransform(self.gt)
        ds.SetProjection(src.GetProjection())
        band = ds.GetRasterBand(1)
        band.SetNoDataValue(float("nan"))
        for r0 in range(0, rows, _STRIP_NODES):
            grid = HeightGrid(self._read(src, r0, 0, min(_STRIP_NODES, rows - r0), cols, 1), r0, 0, 1)
            pj, pi = np.meshgrid(np.arange(cols) + 0.5, np.arange(grid.z.shape[0]) + r0 + 0.5)
            band.WriteArray(self._ellipsoidal(grid.z, pj, pi).astype(np.float32), 0, r0)
        with closing_errors() as closing:
            band = ds = None  # closes the file: GDAL's error then (a full disk) is kept, not printed
        check_closed(path, closing)
        return Path(path)

    # --- windows ---------------------------------------------------------------------------------
    def _grid_for(self, px: np.ndarray, py: np.ndarray) -> HeightGrid | None:
        """A loaded grid covering every queried point that lies on the DEM (px, py: DEM pixel
        coordinates); reads a new window around them when the current one does not. None when
        no point has ever been on the DEM."""
        overview = self._overview()
        if overview.step <= self._step:
            return overview
        rows, cols = self.shape
        on_dem = (px >= 0.5) & (py >= 0.5) & (px <= cols - 0.5) & (py <= rows - 0.5)
        with self._lock:
            grid = self._grid
            need = on_dem if grid is None else on_dem & ~grid.inside(px, py)
            if need.any():
                grid = self._grid = self._load_around(px[need], py[need], grid)
        return grid

    def _load_around(self, px: np.ndarray, py: np.ndarray, current: HeightGrid | None) -> HeightGrid:
        """Read the window (aligned to the decimation step) covering the points with a margin,
        united with the current window."""
        step, (rows, cols) = self._step, self.shape
        c0, c1, r0, r1 = float(np.min(px)), float(np.max(px)), float(np.min(py)), float(np.max(py))
        pad_c = max(_WINDOW_MARGIN * (c1 - c0), 16.0 * step)
        pad_r = max(_WINDOW_MARGIN * (r1 - r0), 16.0 * step)
        c0, c1, r0, r1 = c0 - pad_c, c1 + pad_c, r0 - pad_r, r1 + pad_r
        if current is not None:
            h, w = current.z.shape
            c0, r0 = min(c0, current.col0), min(r0, current.row0)
            c1, r1 = max(c1, current.col0 + w * step), max(r1, current.row0 + h * step)
        col0 = max(0, int(c0 // step) * step)
        row0 = max(0, int(r0 // step) * step)
        ncols = (min(cols, int(math.ceil(c1))) - col0) // step
        nrows = (min(rows, int(math.ceil(r1))) - row0) // step
        return HeightGrid(self._read(self._open(), row0, col0, max(nrows, 1), max(ncols, 1), step), row0, col0, step)

    def _overview(self) -> HeightGrid:
        """The whole DEM at the decimation that keeps it within OVERVIEW_CELLS nodes (the DEM
        itself when it is that small), read once."""
        if self._overview_grid is None:
            rows, cols = self.shape
            step = max(1, math.ceil(math.sqrt(rows * cols / OVERVIEW_CELLS)))
            z = self._read(self._open(), 0, 0, max(rows // step, 1), max(cols // step, 1), step)
            grid = HeightGrid(z, 0, 0, step)
            self._overview_grid = grid
            self._check_plausible(grid)
        return self._overview_grid

    def _read(self, ds, row0: int, col0: int, nrows: int, ncols: int, step: int) -> np.ndarray:
        """Heights (DEM datum, nodata -> NaN) of nrows x ncols nodes, each the average of a
        step x step block of pixels from (row0, col0); read in strips, releasing GDAL's cache."""
        dtype = np.float64 if self._buf_type == gdal.GDT_Float64 else np.float32
        need = nrows * ncols * np.dtype(dtype).itemsize
        if need > self.max_bytes:
            raise InputError(f"DEM {self.path}: the area needed is {ncols} x {nrows} DEM pixels"
                             f"{f' (every {step}th)' if step > 1 else ''}, {need / 2 ** 20:.0f} MB, over the "
                             f"{self.max_bytes / 2 ** 20:.0f} MB a DEM may take in memory; use a coarser DEM, "
                             "or one cut to the area of the scene (or a smaller extent)")
        try:
            z = np.empty((nrows, ncols), dtype=dtype)
        except MemoryError:
            raise InputError(f"DEM {self.path}: not enough memory for {ncols} x {nrows} DEM pixels; use a "
                             "coarser DEM, or one cut to the area of the scene") from None
        band = ds.GetRasterBand(1)
        # Whole strips of pixels averaged here cost a plain read; GDAL's averaging RasterIO is
        # slower, but it uses the raster's overviews and reads huge blocks piecewise.
        by_numpy = step > 1 and band.GetOverviewCount() == 0 and step * step * ncols * z.itemsize <= _STRIP_BYTES
        strip = max(1, min(_STRIP_NODES, _STRIP_BYTES // max(step * step * ncols * z.itemsize, 1))) if by_numpy \
            else _STRIP_NODES
        try:
            for i in range(0, nrows, strip):
                n = min(strip, nrows - i)
                if by_numpy:
                    z[i:i + n] = self._block_means(band.ReadAsArray(col0, row0 + i * step, ncols * step, n * step,
                                                                    buf_type=self._buf_type), step)
                else:
                    z[i:i + n] = self._masked(band.ReadAsArray(
                        col0, row0 + i * step, ncols * step, n * step, buf_xsize=ncols, buf_ysize=n,
                        buf_type=self._buf_type, resample_alg=gdal.GRIORA_Average))
                band.FlushCache()
        except RuntimeError as exc:
            raise InputError(f"DEM {self.path}: cannot read its heights ({exc})") from None
        return z

    def _masked(self, z: np.ndarray) -> np.ndarray:
        """z with the nodata value made NaN (in place)."""
        if self._nodata is not None and not math.isnan(self._nodata):
            z[z == z.dtype.type(self._nodata)] = np.nan
        return z

    def _block_means(self, z: np.ndarray, step: int) -> np.ndarray:
        """Means of the valid pixels (not nodata) of each step x step block of z; NaN where none."""
        z = self._masked(z)
        h, w = z.shape[0] // step, z.shape[1] // step
        z = z[:h * step, :w * step]
        valid = np.isfinite(z)
        if valid.all():
            return _block_sums(z, step, h, w) / (step * step)
        count = _block_sums(valid.astype(np.float32), step, h, w)
        total = _block_sums(np.where(valid, z, z.dtype.type(0)), step, h, w)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(count > 0, total / count, np.nan)

    def _open(self):
        try:
            ds = open_input_raster(self.path)
        except RuntimeError as exc:
            raise InputError(f"DEM {self.path}: cannot be opened as a raster ({exc})") from None
        if ds is None or ds.RasterCount < 1:
            raise InputError(f"DEM {self.path}: cannot be opened as a raster with a band of heights")
        return ds

    # --- heights of a whole grid ------------------------------------------------------------------
    def _grid_range(self, grid: HeightGrid) -> tuple[float, float]:
        """(min, max) ellipsoidal height (m) of a grid's nodes."""
        lo, hi = np.inf, -np.inf
        ny, nx = grid.z.shape
        pj = grid.col0 + (np.arange(nx) + 0.5) * grid.step
        for i in range(0, ny, _STRIP_NODES):
            pi = grid.row0 + (np.arange(i, min(i + _STRIP_NODES, ny)) + 0.5) * grid.step
            h = self._ellipsoidal(grid.z[i:i + _STRIP_NODES], *np.meshgrid(pj, pi))
            if np.isfinite(h).any():
                lo, hi = min(lo, float(np.nanmin(h))), max(hi, float(np.nanmax(h)))
        if not np.isfinite(lo):
            raise InputError(f"DEM {self.path}: holds no valid heights (every pixel is nodata)")
        return lo, hi

    def _ellipsoidal(self, z: np.ndarray, px: np.ndarray, py: np.ndarray) -> np.ndarray:
        """Ellipsoidal heights (m) of DEM values z at DEM pixel coordinates (px, py), same shapes."""
        if self.datum == "ellipsoid":
            return z.astype(float)
        x, y = self.gt[0] + px * self.gt[1], self.gt[3] + py * self.gt[5]
        if self._to_dem is not None:
            x, y = Transformer.from_crs(self.crs, CRS.from_epsg(4326), always_xy=True).transform(x, y)
        return z + geoid_undulation_lattice(x, y)

    def _check_plausible(self, grid: HeightGrid) -> None:
        """Refuse heights no terrain has (a nodata value without its nodata tag, or not metres)."""
        finite = grid.z[np.isfinite(grid.z)]
        if finite.size == 0:
            raise InputError(f"DEM {self.path}: holds no valid heights (every pixel is nodata)")
        check_surface_heights((float(finite.min()), float(finite.max())), f"DEM {self.path}")
