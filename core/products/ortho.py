"""Orthorectification of a raw pushbroom image with its rigorous scene model.

For every output pixel (a north-up grid in a projected CRS) the terrain height comes from the
DEM (bilinear) and the image position from the scene's ground -> image. That exact mapping is
evaluated on a coarse node grid per tile (every ``step`` output pixels) and densified by
bilinear interpolation, which is checked at the cell centres against the exact mapping: a
tile whose check exceeds ``max_error`` px is redone with half the step. Cells whose corners
fall on different CCD chips straddle a seam of a staggered array, where the mapping jumps:
their pixels are mapped exactly, one by one, so no seam is smeared. The raw image is then
resampled (nearest, bilinear or cubic) at the image positions.

Tiles are processed on a thread per core and written to a tiled, compressed GeoTIFF with
overviews, completely or not at all (:class:`core.files.OutputSet`).
Coordinates: image positions in the GDAL convention (pixel centres at +0.5); output pixel
centres at the geotransform's +0.5.
"""
from __future__ import annotations

import json
import logging
import math
import os
import shutil
import tempfile
import threading
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from functools import lru_cache, partial
from pathlib import Path
from typing import Callable

import numpy as np
from osgeo import gdal, gdal_array
from pyproj import CRS, Transformer
from scipy import ndimage

from ..dem import ConstantHeight
from ..errors import Cancelled, InputError
from ..files import OutputSet, atomic_outputs, check_destination
from ..geodesy import ecef_to_geodetic, geodetic_to_ecef
from ..formats.scene_json import scene_to_dict
from ..model.sensor import SceneModel
from ..validation import check_nodata

gdal.UseExceptions()
log = logging.getLogger(__name__)

RESAMPLING = {"nearest": 0, "bilinear": 1, "cubic": 3}  # spline orders of scipy.ndimage
OVERVIEW_FACTORS = (2, 4, 8, 16, 32, 64)
MAX_OUTPUT_PIXELS = 2e9  # per band: ~2 GB at 8 bits, more than any scene needs at its own GSD
SEAM_MARGIN = 8.0  # px from a chip boundary within which cells are mapped pixel by pixel
SCHEDULER_TIMEOUT = 10  # s to reach a Dask scheduler


@dataclass
class OrthoGrid:
    """The output grid: CRS (pyproj), origin (x0, y0) of the upper-left corner, pixel size
    (m) and size (cols, rows)."""
    crs: CRS
    x0: float
    y0: float
    resolution: float
    cols: int
    rows: int

    def geotransform(self) -> tuple:
        return (self.x0, self.resolution, 0.0, self.y0, 0.0, -self.resolution)


def utm_crs(lon: float, lat: float) -> CRS:
    """The WGS84 UTM zone CRS of a point."""
    zone = int((lon + 180.0) // 6.0) % 60 + 1
    return CRS.from_epsg((32600 if lat >= 0 else 32700) + zone)


def scene_utm_crs(scene: SceneModel, camera: int, surface) -> CRS:
    """The WGS84 UTM zone CRS of the image centre on the surface (the default output CRS)."""
    lon, lat, _ = ecef_to_geodetic(_image_on_surface(scene, camera, surface, footprint=False))
    return utm_crs(float(lon[-1]), float(lat[-1]))


def _image_on_surface(scene: SceneModel, camera: int, surface, footprint: bool,
                      rows: tuple[int, int] | None = None) -> np.ndarray:
    """ECEF points (n, 3) where the image (its ``rows`` = (first, end), default all) meets the
    surface: with ``footprint`` 33 points along each side of the border, then (always) the
    centre pixel and its right neighbour (without ``footprint``, at the surface's mean height
    where the surface misses them). InputError naming the DEM where they do not meet it."""
    cam = scene.cameras[camera]
    top, bottom = rows or (0, cam.rows)
    s = np.linspace(0.0, 1.0, 33)
    centre_col, centre_row = np.array([cam.cols / 2, cam.cols / 2 + 1]), np.array([(top + bottom) / 2] * 2)
    if footprint:
        side = top + s * (bottom - top)
        col = np.concatenate([s * cam.cols, np.full_like(s, cam.cols), s * cam.cols, np.zeros_like(s), centre_col])
        row = np.concatenate([np.full_like(s, top), side, np.full_like(s, bottom), side, centre_row])
    else:
        col, row = centre_col, centre_row
    ground = scene.image_to_ground_dem(col, row, surface, camera)
    if not footprint and not np.all(np.isfinite(ground)):
        # the centre only sets the default CRS and pixel size: the DEM's mean height serves there
        ground = scene.image_to_ground_dem(col, row, ConstantHeight(float(np.mean(surface.height_range))), camera)
    if not np.all(np.isfinite(ground)):
        name = getattr(surface, "path", "the terrain surface")
        where = "the image's centre" if not np.all(np.isfinite(ground[-2:])) else "the image's border"
        raise InputError(f"DEM {name} does not cover the scene: {where} does not meet it. Use a DEM covering the "
                         f"footprint, a constant height, or an extent inside the DEM")
    return ground


def default_grid(scene: SceneModel, camera: int, surface, crs: CRS | None = None,
                 resolution: float | None = None, extent: tuple | None = None,
                 rows: tuple[int, int] | None = None) -> OrthoGrid:
    """The grid covering the image's footprint on the surface (or ``extent`` = (xmin, ymin,
    xmax, ymax) in ``crs``), in ``crs`` (default: the UTM zone of the scene centre), at
    ``resolution`` m (default: the ground sample distance at the image centre). ``rows``:
    (first, end) image rows of one scene of a strip (default: the whole image)."""
    ground = _image_on_surface(scene, camera, surface, footprint=extent is None, rows=rows)
    lon, lat, _ = ecef_to_geodetic(ground)
    crs = crs or utm_crs(float(lon[-1]), float(lat[-1]))
    x, y = Transformer.from_crs(CRS.from_epsg(4326), crs, always_xy=True).transform(lon, lat)
    if resolution is None:
        resolution = float(np.hypot(x[-1] - x[-2], y[-1] - y[-2]))
    if not resolution > 0:
        raise InputError(f"the output resolution must be positive (got {resolution})")
    xmin, ymin, xmax, ymax = extent or (np.min(x[:-2]), np.min(y[:-2]), np.max(x[:-2]), np.max(y[:-2]))
    if not (xmax > xmin and ymax > ymin):
        raise InputError(f"the extent {extent} is empty: it needs xmin < xmax and ymin < ymax")
    width, height = float(xmax - xmin) / resolution, float(ymax - ymin) / resolution
    if not width * height <= MAX_OUTPUT_PIXELS:  # also inf: never round sizes that no file can hold
        raise InputError(f"resolution {resolution:g} m: the output would have {width:.4g} x {height:.4g} pixels "
                         f"(more than {MAX_OUTPUT_PIXELS:.0e}); choose a coarser resolution or a smaller extent")
    x0 = math.floor(xmin / resolution) * resolution
    y0 = math.ceil(ymax / resolution) * resolution
    cols, rows = int(math.ceil((xmax - x0) / resolution)), int(math.ceil((y0 - ymin) / resolution))
    return OrthoGrid(crs, x0, y0, resolution, cols, rows)


def overview_levels(cols: int, rows: int) -> list[int]:
    """Overview decimation factors of an output: halvings down to about 256 px on the long side."""
    return [f for f in OVERVIEW_FACTORS if max(cols, rows) / f >= 256]


def _open_raw(image_path, cam):
    """The raw image as a GDAL dataset (decoded on all cores), checked against the camera's size."""
    try:
        src = gdal.OpenEx(str(image_path), gdal.OF_RASTER, open_options=["NUM_THREADS=ALL_CPUS"])
    except RuntimeError as exc:
        raise InputError(f"{image_path}: cannot be opened as a raster ({exc})") from None
    if (src.RasterXSize, src.RasterYSize) != (cam.cols, cam.rows):
        raise InputError(f"{image_path}: the raster is {src.RasterXSize} x {src.RasterYSize} px but camera {cam.name} "
                         f"of the scene images {cam.cols} x {cam.rows} px: is it the scene's image?")
    return src


class _RawImage:
    """The raw image's bands (count, rows, cols), read by window: from memory when the whole
    image fits in ``budget`` bytes (decoded once, on all cores), else from the file through a
    GDAL dataset per thread (GDAL datasets are not shared between threads), so memory stays
    bounded for images of any size."""

    def __init__(self, path, src, budget: float):
        self.path, self.count = str(path), src.RasterCount
        self.rows, self.cols = src.RasterYSize, src.RasterXSize
        self.data_type = src.GetRasterBand(1).DataType
        self.dtype = np.dtype(gdal_array.GDALTypeCodeToNumericTypeCode(self.data_type))
        size = self.rows * self.cols * self.count * self.dtype.itemsize
        self.data = src.ReadAsArray().reshape(self.count, self.rows, self.cols) if size <= budget else None
        self._local = threading.local()

    def window(self, i0: int, i1: int, j0: int, j1: int) -> np.ndarray:
        """Bands (count, i1-i0, j1-j0) of rows i0..i1 and columns j0..j1."""
        if self.data is not None:
            return self.data[:, i0:i1, j0:j1]
        ds = getattr(self._local, "ds", None)
        if ds is None:
            ds = self._local.ds = gdal.Open(self.path)
        return ds.ReadAsArray(j0, i0, j1 - j0, i1 - i0).reshape(self.count, i1 - i0, j1 - j0)

    def close(self) -> None:
        """Drop the decoded image and every thread's dataset."""
        self.data, self._local = None, threading.local()


def _resample(raw: _RawImage, col: np.ndarray, row: np.ndarray, order: int, fill,
              rows: tuple[int, int] | None = None) -> list[np.ndarray]:
    """Values of every band of the raw image at image positions (col, row) (GDAL convention,
    arrays of the tile's shape); ``fill`` outside the image (or outside its ``rows`` = (first,
    end), one scene of a strip). Integer types rounded and clipped to their range."""
    top, bottom = rows or (0, raw.rows)
    outside = ~np.isfinite(col) | (col < 0) | (col > raw.cols) | (row < top) | (row > bottom)
    any_outside = outside.any()
    if any_outside and outside.all():
        return [np.full(col.shape, fill, dtype=raw.dtype) for _ in range(raw.count)]
    # image positions (centres at +0.5) -> array indices (centres at 0), in the raw window the
    # tile needs (a cubic spline is prefiltered on that window only)
    i, j = row - 0.5, col - 0.5
    if any_outside:
        i, j = np.where(outside, np.nan, i), np.where(outside, np.nan, j)
    i0, j0 = max(int(np.nanmin(i)) - 4, 0), max(int(np.nanmin(j)) - 4, 0)
    i1, j1 = min(int(np.nanmax(i)) + 5, raw.rows), min(int(np.nanmax(j)) + 5, raw.cols)
    coords = np.stack([i - i0, j - j0])
    if any_outside:
        coords[:, outside] = 0.0
    blocks = []
    for window in raw.window(i0, i1, j0, j1):
        if order <= 1:  # an integer band's output is rounded by ndimage; no overshoot to clip
            block = ndimage.map_coordinates(window, coords, order=order, mode="nearest", prefilter=False)
        else:
            values = ndimage.map_coordinates(window.astype(np.float32), coords, order=order, mode="nearest")
            if np.issubdtype(raw.dtype, np.integer):
                info = np.iinfo(raw.dtype)
                values = np.clip(np.rint(values), info.min, info.max)
            block = values.astype(raw.dtype)
        if any_outside:
            block[outside] = fill
        blocks.append(block)
    return blocks


def _overview_blocks(block: np.ndarray, levels: list[int], nodata, nearest: bool) -> list[np.ndarray]:
    """A tile's part of each overview level (factor f: ceil(shape / f) px): the mean of the valid
    (not nodata) pixels of each f x f cell, or with ``nearest`` the pixel nearest its centre.
    Cells without valid pixels are nodata."""
    if nearest:
        def pick(n, f):
            return np.minimum(np.arange(-(-n // f)) * f + f // 2, n - 1)
        return [block[np.ix_(pick(block.shape[0], f), pick(block.shape[1], f))] for f in levels]
    valid = np.ones(block.shape, bool) if nodata is None else block != nodata
    if not valid.any():
        return [np.full((-(-block.shape[0] // f), -(-block.shape[1] // f)), nodata, block.dtype) for f in levels]
    total = block.astype(np.float32)  # float32 sums: 1e-7 relative, far below one grey level
    total[~valid] = 0.0
    count = valid.astype(np.float32)
    out, reached = [], 1
    for f in levels:
        while reached < f:  # halve the sums and counts: level 2f from level f
            total, count = _sum_pairs(total), _sum_pairs(count)
            reached *= 2
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = total / count
        if np.issubdtype(block.dtype, np.integer):
            mean = np.rint(mean)
        out.append(np.where(count > 0, mean, nodata if nodata is not None else 0).astype(block.dtype))
    return out


def _sum_pairs(a: np.ndarray) -> np.ndarray:
    """Sums of 2 x 2 cells (a ragged last row / column summed alone)."""
    h, w = a.shape
    if h % 2 or w % 2:
        padded = np.zeros((h + h % 2, w + w % 2), a.dtype)
        padded[:h, :w] = a
        a = padded
    return a[0::2, 0::2] + a[1::2, 0::2] + a[0::2, 1::2] + a[1::2, 1::2]


@dataclass
class _Nodes:
    """Exact image positions (col, row) at output nodes (i, j) = (r0 + a*step, c0 + b*step)
    (ncol, nrow: (na, nb)) and at the cell centres between them (ecol, erow: (na-1, nb-1))."""
    r0: int
    c0: int
    step: int
    ncol: np.ndarray
    nrow: np.ndarray
    ecol: np.ndarray
    erow: np.ndarray

    def window(self, r0: int, r1: int, c0: int, c1: int) -> "_Nodes":
        """The nodes of a tile whose corners (r0, c0) lie on the node grid, to at least (r1, c1)."""
        a, b = (r0 - self.r0) // self.step, (c0 - self.c0) // self.step
        na, nb = -(-(r1 - r0) // self.step) + 1, -(-(c1 - c0) // self.step) + 1
        return _Nodes(r0, c0, self.step, self.ncol[a:a + na, b:b + nb], self.nrow[a:a + na, b:b + nb],
                      self.ecol[a:a + na - 1, b:b + nb - 1], self.erow[a:a + na - 1, b:b + nb - 1])


class _Mapper:
    """Output pixel centres of a tile -> image positions (col, row) of the raw image; ``rows``:
    (first, end) image rows of one scene of a strip, outside which the tile is nodata."""

    rows: tuple[int, int] | None = None  # subclasses that map onto the whole raw image keep it

    def __init__(self, scene: SceneModel, camera: int, surface, grid: OrthoGrid,
                 rows: tuple[int, int] | None = None):
        self.scene, self.camera, self.surface, self.grid, self.rows = scene, camera, surface, grid, rows
        self.to_lonlat = Transformer.from_crs(grid.crs, CRS.from_epsg(4326), always_xy=True)
        self.cam = scene.cameras[camera]

    def exact(self, i: np.ndarray, j: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Image (col, row) of output positions (i = row, j = col, float, pixel-centre units)."""
        g = self.grid
        x = g.x0 + (j + 0.5) * g.resolution
        y = g.y0 - (i + 0.5) * g.resolution
        lon, lat = self.to_lonlat.transform(x, y)
        h = self.surface.height(lon, lat)
        col = np.full(np.shape(lon), np.nan)
        row = np.full(np.shape(lon), np.nan)
        ok = np.isfinite(h)
        if ok.any():
            col[ok], row[ok] = self.scene.ground_to_image(geodetic_to_ecef(lon[ok], lat[ok], h[ok]), self.camera)
        return col, row

    def exact_many(self, i: np.ndarray, j: np.ndarray, chunk: int = 250_000,
                   is_cancelled: Callable[[], bool] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`exact` for many positions (any equal shapes), in chunks of bounded memory."""
        col, row = np.empty(i.size), np.empty(i.size)
        fi, fj = i.ravel(), j.ravel()
        for k in range(0, i.size, chunk):
            if is_cancelled and is_cancelled():
                raise Cancelled("orthorectification cancelled by the user")
            col[k:k + chunk], row[k:k + chunk] = self.exact(fi[k:k + chunk], fj[k:k + chunk])
        return col.reshape(i.shape), row.reshape(i.shape)

    def nodes(self, r0: int, r1: int, c0: int, c1: int, step: int,
              is_cancelled: Callable[[], bool] | None = None) -> "_Nodes":
        """Exact image positions at the nodes (every ``step`` output pixels, from (r0, c0) to at
        least (r1, c1)) and at the centres of the cells between them."""
        ni = np.arange(r0, r1 + step, step, dtype=float)
        nj = np.arange(c0, c1 + step, step, dtype=float)
        ncol, nrow = self.exact_many(*np.meshgrid(ni, nj, indexing="ij"), is_cancelled=is_cancelled)
        ecol, erow = self.exact_many(*np.meshgrid(ni[:-1] + step / 2, nj[:-1] + step / 2, indexing="ij"),
                                     is_cancelled=is_cancelled)
        return _Nodes(r0, c0, step, ncol, nrow, ecol, erow)

    def dem_gap_share(self, planned: "_Nodes") -> float:
        """Share of the image's nodes in the output that the surface gives no height (they stay
        nodata): nodes without a height that fall in the image at the surface's mean height."""
        nodes = np.argwhere(np.isnan(planned.ncol)).astype(float)
        if nodes.size == 0:
            return 0.0
        i, j = nodes[:, 0] * planned.step + planned.r0, nodes[:, 1] * planned.step + planned.c0
        lon, lat = self.to_lonlat.transform(self.grid.x0 + (j + 0.5) * self.grid.resolution,
                                            self.grid.y0 - (i + 0.5) * self.grid.resolution)
        no_height = ~np.isfinite(self.surface.height(lon, lat))
        if not no_height.any():
            return 0.0
        h = float(np.mean(self.surface.height_range))
        col, row = self.scene.ground_to_image(geodetic_to_ecef(lon[no_height], lat[no_height], np.full(no_height.sum(), h)),
                                              self.camera)
        missing = int(np.sum((col >= 0) & (col <= self.cam.cols) & (row >= 0) & (row <= self.cam.rows)))
        covered = int(np.sum((planned.ncol >= 0) & (planned.ncol <= self.cam.cols) & (planned.nrow >= 0)
                             & (planned.nrow <= self.cam.rows)))
        return missing / max(missing + covered, 1)

    def tile(self, r0: int, r1: int, c0: int, c1: int, step: int, max_error: float,
             planned: "_Nodes | None" = None) -> tuple[np.ndarray, np.ndarray, float]:
        """(col, row) arrays (r1-r0, c1-c0) of a tile, and the densification error measured (px).
        planned: nodes of the whole grid at ``step`` (:meth:`nodes`), sliced instead of computed."""
        nodes = planned.window(r0, r1, c0, c1) if planned is not None and planned.step == step else None
        while True:
            nodes = nodes or self.nodes(r0, r1, c0, c1, step)
            ncol, nrow, ecol, erow = nodes.ncol, nodes.nrow, nodes.ecol, nodes.erow
            # check at the cell centres where the four corners lie on one chip
            icol = 0.25 * (ncol[:-1, :-1] + ncol[1:, :-1] + ncol[:-1, 1:] + ncol[1:, 1:])
            irow = 0.25 * (nrow[:-1, :-1] + nrow[1:, :-1] + nrow[:-1, 1:] + nrow[1:, 1:])
            # Seam cells: corners on different chips, or a centre the exact mapping puts on
            # another chip (a seam duplicate: both pixels see the point).
            centre_chip = self.cam.chip_index(np.nan_to_num(ecol, nan=-1.0))
            seam = self._seam_cells(ncol) | (centre_chip != self.cam.chip_index(np.nan_to_num(
                ncol[:-1, :-1], nan=-1.0)))
            err = np.hypot(icol - ecol, irow - erow)[~seam]
            worst = float(np.nanmax(err, initial=0.0))
            if worst <= max_error or step <= 2:
                break
            step //= 2
            nodes = None
        col, row = self._densify(ncol, nrow, r1 - r0, c1 - c0, step)
        if seam.any():
            self._exact_in_cells(col, row, seam, r0, c0, step)
        return col, row, worst

    def _seam_cells(self, ncol: np.ndarray) -> np.ndarray:
        """Cells (nodes - 1 each way) whose corners are on different chips, off the image, or
        within SEAM_MARGIN px of a chip boundary (misaligned chips leave gaps and duplicates
        a few pixels wide there, where the mapping has no single smooth answer)."""
        finite = np.isfinite(ncol)
        safe = np.nan_to_num(ncol, nan=-1.0)
        chip = np.where(finite, self.cam.chip_index(safe), -1)
        bounds = np.array([c.col_offset for c in self.cam.chips[1:]] or [np.inf])
        near = (np.abs(safe[..., None] - bounds).min(axis=-1) < SEAM_MARGIN) & finite
        chip = np.where(near, -2, chip)  # a mark that never matches a neighbour
        corners = np.stack([chip[:-1, :-1], chip[1:, :-1], chip[:-1, 1:], chip[1:, 1:]])
        return (corners.min(axis=0) != corners.max(axis=0)) | (corners.min(axis=0) < 0)

    @staticmethod
    def _densify(ncol, nrow, h: int, w: int, step: int):
        """Bilinear interpolation of node values to every pixel of the tile: two small matrix
        products (separable weights), so it costs little per pixel."""
        def weights(n_pix, n_nodes):
            f = np.arange(n_pix) / step
            k = np.minimum(f.astype(int), n_nodes - 2)
            t = f - k
            m = np.zeros((n_pix, n_nodes))
            m[np.arange(n_pix), k] = 1 - t
            m[np.arange(n_pix), k + 1] = t
            return m
        wi, wj = weights(h, ncol.shape[0]), weights(w, ncol.shape[1])
        fill = lambda a: np.where(np.isfinite(a), a, 0.0)  # noqa: E731  (NaN nodes: handled as seam cells)
        return wi @ fill(ncol) @ wj.T, wi @ fill(nrow) @ wj.T

    def _exact_in_cells(self, col, row, seam, r0, c0, step) -> None:
        """Exact mapping for the pixels of the flagged cells (seams, image or DEM borders)."""
        h, w = col.shape
        ci, cj = np.nonzero(seam)
        ii = (ci[:, None, None] * step + np.arange(step)[None, :, None]).repeat(step, 2)
        jj = (cj[:, None, None] * step + np.arange(step)[None, None, :]).repeat(step, 1)
        keep = (ii < h) & (jj < w)
        ii, jj = ii[keep], jj[keep]
        ecol, erow = self.exact(ii + r0, jj + c0)
        col[ii, jj], row[ii, jj] = ecol, erow


def _tile_blocks(mapper: _Mapper, raw: _RawImage, window: tuple[int, int, int, int], step: int, max_error: float,
                 planned: "_Nodes | None", order: int, fill, levels: list[int], nodata):
    """One tile: the bands (resampled), their parts of each overview level and the densification
    error (px). The same computation for the threads of one process and for a distributed job."""
    r0, r1, c0, c1 = window
    col, row, err = mapper.tile(r0, r1, c0, c1, step, max_error, planned)
    blocks = _resample(raw, col, row, order, fill, mapper.rows)
    return blocks, [_overview_blocks(b, levels, nodata, order == 0) for b in blocks], err


def _write_tile(out_bands, levels: list[int], window: tuple, blocks, overviews) -> None:
    """A tile's bands and overview parts into the output's bands (in tile order: the file's
    layout depends on the order blocks are written)."""
    r0, _, c0, _ = window
    for band, b, ovr in zip(out_bands, blocks, overviews):
        band.WriteArray(b, c0, r0)
        for k, (f, o) in enumerate(zip(levels, ovr)):
            band.GetOverview(k).WriteArray(o, c0 // f, r0 // f)


def _create_geotiff(path, cols: int, rows: int, count: int, data_type: int, levels: list[int], nodata,
                    options: list[str]):
    """A new GeoTIFF with empty overviews at ``levels`` (each tile writes its part of them)."""
    out = gdal.GetDriverByName("GTiff").Create(str(path), cols, rows, count, data_type, options)
    for k in range(count):
        if nodata is not None:
            out.GetRasterBand(k + 1).SetNoDataValue(nodata)
    if levels:
        out.BuildOverviews("NONE", levels)
    return out


# --- distributed work: one picklable job per tile -------------------------------------------------
def surface_description(surface) -> dict:
    """The terrain as plain data a job carries: {"height": m} or {"dem": path, "datum": ...}."""
    if isinstance(surface, ConstantHeight):
        return {"height": float(surface.value)}
    return {"dem": str(surface.path), "datum": surface.datum}


@dataclass(frozen=True)
class OrthoJob:
    """One tile of one orthoimage, as plain picklable data: a worker of a distributed engine
    (another process or machine, with this package importable and the files reachable at the
    same paths) runs it with :func:`run_job` and writes the tile to ``output`` (a GeoTIFF of
    the window's size, holding the tile's part of each overview level as its own overviews).

    scene: the scene model as scene JSON text; camera: its index; image: the raw image's path;
    grid: (CRS WKT, x0, y0, resolution m, cols, rows) of the whole output; window: (r0, r1, c0,
    c1) output rows and columns of the tile; surface: :func:`surface_description`; rows: (first,
    end) image rows of one scene of a strip or None; nodes: the planned exact image positions of
    the window (a ``_Nodes``), so the tile is the threaded run's to the bit."""
    scene: str
    camera: int
    image: str
    grid: tuple
    window: tuple[int, int, int, int]
    surface: dict
    resampling: str
    nodata: float | None
    output: str
    rows: tuple[int, int] | None = None
    step: int = 32
    max_error: float = 0.01
    levels: tuple[int, ...] = ()
    nodes: _Nodes | None = None


@lru_cache(maxsize=4)
def _job_mapper(scene_text: str, camera: int, grid: tuple, surface: str, rows: tuple | None) -> _Mapper:
    """The mapper a worker builds once per orthoimage (scene JSON parsed, DEM opened)."""
    from ..dem import Dem
    from ..formats.scene_json import scene_from_dict
    description = json.loads(surface)
    terrain = (ConstantHeight(description["height"]) if "height" in description
               else Dem(description["dem"], datum=description["datum"]))
    wkt, x0, y0, resolution, cols, n_rows = grid
    return _Mapper(scene_from_dict(json.loads(scene_text)), camera, terrain,
                   OrthoGrid(CRS.from_wkt(wkt), x0, y0, resolution, cols, n_rows), rows)


def run_job(job: OrthoJob) -> float:
    """Compute one tile (:class:`OrthoJob`) and write it to ``job.output``; returns its
    densification error (px)."""
    mapper = _job_mapper(job.scene, job.camera, job.grid, json.dumps(job.surface, sort_keys=True), job.rows)
    src = gdal.Open(job.image)
    raw = _RawImage(job.image, src, budget=0)  # read by window: a worker holds only its tiles' pixels
    levels = list(job.levels)
    fill = job.nodata if job.nodata is not None else 0.0
    blocks, overviews, err = _tile_blocks(mapper, raw, job.window, job.step, job.max_error, job.nodes,
                                          RESAMPLING[job.resampling], fill, levels, job.nodata)
    r0, r1, c0, c1 = job.window
    out = _create_geotiff(job.output, c1 - c0, r1 - r0, raw.count, raw.data_type, levels, job.nodata, [])
    wkt, x0, y0, resolution, _, _ = job.grid
    out.SetGeoTransform((x0 + c0 * resolution, resolution, 0.0, y0 - r0 * resolution, 0.0, -resolution))
    out.SetProjection(wkt)
    _write_tile([out.GetRasterBand(k + 1) for k in range(raw.count)], levels, (0, 0, 0, 0), blocks, overviews)
    out = None
    raw.close()
    return err


def _connect(scheduler: str):
    """A Dask distributed client of the scheduler at ``scheduler``; InputError naming SCHEDULER
    when Dask is missing or the scheduler does not answer."""
    try:
        from distributed import Client
    except ImportError:
        raise InputError(f"SCHEDULER: {scheduler} needs Dask distributed, which is not installed (Debian: "
                         "python3-distributed); leave SCHEDULER empty to use this machine's cores") from None
    try:
        return Client(scheduler, timeout=SCHEDULER_TIMEOUT, set_as_default=False)
    except (OSError, TimeoutError, ValueError, TypeError) as exc:
        raise InputError(f"SCHEDULER: cannot reach the Dask scheduler at {scheduler!r} within "
                         f"{SCHEDULER_TIMEOUT} s ({exc}); give its address, e.g. tcp://host:8786") from None


def _run_jobs(scheduler: str, jobs: list[OrthoJob], report, cancelled) -> float:
    """Run ``jobs`` on the Dask scheduler (``report`` gets the share done); returns the worst
    densification error (px)."""
    from distributed import as_completed
    client = _connect(scheduler)
    try:
        futures = client.map(run_job, jobs, pure=False)
        worst = 0.0
        for n, future in enumerate(as_completed(futures, loop=client.loop)):
            if cancelled():
                client.cancel(futures)
                raise Cancelled("orthorectification cancelled by the user")
            worst = max(worst, future.result())
            report((n + 1) / len(jobs))
        return worst
    finally:
        client.close()


def _assemble(jobs: list[OrthoJob], out_bands, levels: list[int], folder: Path, report, cancelled) -> None:
    """Write the tiles of ``jobs`` into the output in tile order: bands through a VRT mosaic of
    the tile files (GDAL), overview parts from each tile's overviews."""
    mosaic = gdal.BuildVRT(str(folder / "tiles.vrt"), [job.output for job in jobs])  # the tiles cover the grid
    for n, job in enumerate(jobs):
        if cancelled():
            raise Cancelled("orthorectification cancelled by the user")
        r0, r1, c0, c1 = job.window
        tile = gdal.Open(job.output)
        blocks = [mosaic.GetRasterBand(k + 1).ReadAsArray(c0, r0, c1 - c0, r1 - r0)
                  for k in range(tile.RasterCount)]
        overviews = [[tile.GetRasterBand(k + 1).GetOverview(v).ReadAsArray() for v in range(len(levels))]
                     for k in range(tile.RasterCount)]
        tile = None
        _write_tile(out_bands, levels, job.window, blocks, overviews)
        report((n + 1) / len(jobs))
    mosaic = None


def _tiles_on_scheduler(scheduler: str, job: Callable[[tuple, str, list[int]], OrthoJob], output_path: Path,
                        windows: list[tuple[int, int, int, int]], out_bands, levels: list[int], report,
                        cancelled) -> float:
    """The ``run_tiles`` of :func:`write_resampled` on a Dask scheduler: ``job(window, tile file,
    levels)`` for each window, run by the workers into a temporary folder beside ``output_path``
    (removed afterwards), then assembled into ``out_bands`` in window order. Returns the worst
    densification error (px)."""
    folder = Path(tempfile.mkdtemp(prefix=f".{output_path.name}.", suffix=".tiles", dir=output_path.parent))
    try:
        jobs = [job(w, str(folder / f"tile_{w[0]}_{w[2]}.tif"), levels) for w in windows]
        worst = _run_jobs(scheduler, jobs, lambda f: report(0.86 * f), cancelled)
        _assemble(jobs, out_bands, levels, folder, lambda f: report(0.86 + 0.14 * f), cancelled)
        return worst
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def orthorectify(scene: SceneModel, image_path, surface, output_path, camera: int = 0, grid: OrthoGrid | None = None,
                 resampling: str = "bilinear", nodata: float | None = 0.0, tile: int = 512, step: int = 32,
                 max_error: float = 0.01, memory_budget: float = 2 ** 30,
                 progress: Callable[[float], None] | None = None,
                 is_cancelled: Callable[[], bool] | None = None, rows: tuple[int, int] | None = None,
                 scheduler: str | None = None, files: OutputSet | None = None) -> dict:
    """Orthorectify ``image_path`` (any GDAL raster, any bands and type, of the scene camera's
    size) onto ``grid`` (default :func:`default_grid`) and write a tiled, compressed GeoTIFF
    with overviews to ``output_path``. The raw image is held in memory when it takes at most
    ``memory_budget`` bytes, else read by window for each tile. ``rows``: (first, end) image
    rows of one scene of a strip (the rest is nodata). Tiles run on a thread per core, or with
    ``scheduler`` (a Dask distributed address, e.g. tcp://host:8786) as :class:`OrthoJob` s on
    its workers, which write tile files in a temporary folder beside the output that are then
    assembled here: the same bytes. With ``files`` the output joins that set (its owner commits
    it). Returns figures: grid, densification error (px), share of the footprint without DEM
    heights, time."""
    import time
    t_start = time.perf_counter()
    check_resampling(resampling, tile, step)
    cam = scene.cameras[camera]
    src = _open_raw(image_path, cam)
    if nodata is not None:
        check_nodata(nodata, gdal_array.GDALTypeCodeToNumericTypeCode(src.GetRasterBand(1).DataType))
    grid = grid or default_grid(scene, camera, surface, rows=rows)
    output_path = Path(output_path)
    check_destination(output_path)
    client = _connect(scheduler) if scheduler else None  # an unreachable scheduler stops before any work
    if client is not None:
        client.close()
    raw = _RawImage(image_path, src, 0 if scheduler else memory_budget)  # workers read their own windows
    cancelled = is_cancelled or (lambda: False)
    report = progress or (lambda fraction: None)
    try:
        mapper = _Mapper(scene, camera, surface, grid, rows)
        planned = mapper.nodes(0, grid.rows, 0, grid.cols, step, is_cancelled=cancelled)
        gaps = mapper.dem_gap_share(planned)
        if gaps > 0:
            log.warning("DEM %s gives no height for %.1f %% of the image's footprint in the output grid: those "
                        "pixels are nodata", getattr(surface, "path", ""), 100 * gaps)
        report(0.05)

        def georeference(out) -> None:
            out.SetGeoTransform(grid.geotransform())
            out.SetProjection(grid.crs.to_wkt())

        run_tiles = None
        if scheduler:
            text = json.dumps(scene_to_dict(scene))
            plain_grid = (grid.crs.to_wkt(), grid.x0, grid.y0, grid.resolution, grid.cols, grid.rows)

            def job(window: tuple[int, int, int, int], output: str, levels: list[int]) -> OrthoJob:
                return OrthoJob(text, camera, str(image_path), plain_grid, window, surface_description(surface),
                                resampling, nodata, output, rows, step, max_error, tuple(levels),
                                planned.window(*window))

            run_tiles = partial(_tiles_on_scheduler, scheduler, job, output_path)
        worst = write_resampled(raw, mapper, planned, (grid.rows, grid.cols), output_path, resampling, nodata, tile,
                                max_error,
                                georeference=georeference, progress=lambda f: report(0.05 + 0.93 * f),
                                is_cancelled=cancelled, files=files, run_tiles=run_tiles)
    finally:
        raw.close()
    report(1.0)
    figures = {"cols": grid.cols, "rows": grid.rows, "resolution_m": grid.resolution, "crs": grid.crs.to_string(),
               "densification_error_px": worst, "max_error_px": max_error, "dem_gap_share": gaps,
               "seconds": time.perf_counter() - t_start}
    log.info("orthoimage %d x %d at %.3f m in %.1f s; densification error <= %.2e px", grid.cols, grid.rows,
             grid.resolution, figures["seconds"], worst)
    return figures


def check_resampling(resampling: str, tile: int, step: int) -> None:
    """InputError for an unknown resampling; ValueError for a tile that is not a multiple of the
    node step and of the largest overview factor."""
    if resampling not in RESAMPLING:
        raise InputError(f"resampling must be one of {', '.join(RESAMPLING)} (got {resampling!r})")
    if tile % step or tile % OVERVIEW_FACTORS[-1]:
        raise ValueError(f"tile ({tile}) must be a multiple of step ({step}) and of {OVERVIEW_FACTORS[-1]}")


def write_resampled(raw: _RawImage, mapper: _Mapper, planned: _Nodes, shape: tuple[int, int], output_path,
                    resampling: str,
                    nodata: float | None, tile: int, max_error: float,
                    georeference: Callable[[gdal.Dataset], None] | None = None,
                    progress: Callable[[float], None] | None = None,
                    is_cancelled: Callable[[], bool] | None = None, files: OutputSet | None = None,
                    run_tiles: Callable | None = None) -> float:
    """Resample ``raw`` through ``mapper`` (output pixel -> raw image position; any subclass of
    :class:`_Mapper` with its own ``exact``) onto an output of ``shape`` (rows, cols), whose node
    grid ``planned`` (:meth:`_Mapper.nodes` over the whole output) it slices, and write it as a tiled, compressed
    GeoTIFF with overviews to ``output_path``; ``georeference(dataset)`` sets its georeferencing.
    Tiles on a thread per core, or by ``run_tiles(windows, out_bands, levels, progress,
    is_cancelled)`` (e.g. :func:`_tiles_on_scheduler`), which writes every window (r0, r1, c0, c1)
    into the output's bands with :func:`_write_tile` in the order given and returns the worst
    densification error; ``progress`` gets the share of tiles done. Written completely
    or not at all: with ``files`` as part of that set (its owner commits it). Returns the largest
    densification error measured (px)."""
    rows, cols = shape
    fill = nodata if nodata is not None else 0.0
    cancelled = is_cancelled or (lambda: False)
    report = progress or (lambda fraction: None)
    levels = overview_levels(cols, rows)
    own = files is None
    files = files or OutputSet()
    failed = ""
    worst = 0.0
    try:
        out = _create_geotiff(files.path(output_path), cols, rows, raw.count, raw.data_type, levels, nodata,
                              ["TILED=YES", f"BLOCKXSIZE={tile}", f"BLOCKYSIZE={tile}", "COMPRESS=DEFLATE",
                               "PREDICTOR=2", "BIGTIFF=IF_SAFER", "NUM_THREADS=ALL_CPUS"])
        if georeference is not None:
            georeference(out)
        out_bands = [out.GetRasterBand(k + 1) for k in range(raw.count)]
        windows = [(r0, min(r0 + tile, rows), c0, min(c0 + tile, cols))
                   for r0 in range(0, rows, tile) for c0 in range(0, cols, tile)]
        if run_tiles is not None:
            worst = run_tiles(windows, out_bands, levels, report, cancelled)
        else:
            order = RESAMPLING[resampling]

            def work(window):
                if cancelled():
                    raise Cancelled("resampling cancelled by the user")
                return _tile_blocks(mapper, raw, window, planned.step, max_error, planned, order, fill, levels,
                                    nodata)

            with ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as pool:
                for n, (window, (blocks, overviews, err)) in enumerate(zip(windows, pool.map(work, windows))):
                    _write_tile(out_bands, levels, window, blocks, overviews)
                    worst = max(worst, err)
                    report((n + 1) / len(windows))
        out_bands = None
        out.FlushCache()
        out = None
        if own:
            files.commit()
    except RuntimeError as exc:  # GDAL: disk full, file system errors; raised below, as this error's
        failed = str(exc)        # traceback holds the file open
    finally:
        try:
            out_bands = out = None  # closes the file
        except RuntimeError as exc:  # flushing it failed
            failed = failed or str(exc)
        if own:
            files.discard()
    if failed:
        raise InputError(f"cannot write {output_path}: {failed}")
    return worst



# --- every camera of a scene, every scene of a strip ------------------------------------------------
@dataclass(frozen=True)
class OrthoProduct:
    """One orthoimage of a multi-camera run: camera index, image rows (first, end) of its scene
    of the strip (None: the whole image) and the output file's name."""
    camera: int
    rows: tuple[int, int] | None
    name: str


def strip_products(scene: SceneModel, cameras: list[int]) -> list[OrthoProduct]:
    """The orthoimages of ``cameras``: one per camera (``ortho_<CAMERA>.tif``), or for a strip
    of n scenes (``info.n_scenes``, the scenes of one pass in one image per camera, equal row
    counts) one per camera and scene (``ortho_<CAMERA>_s<k>.tif``, k = 1..n along the pass)."""
    n = int(scene.info.get("n_scenes", 1) or 1)
    products = []
    for c in cameras:
        cam = scene.cameras[c]
        if n <= 1:
            products.append(OrthoProduct(c, None, f"ortho_{cam.name}.tif"))
            continue
        products += [OrthoProduct(c, (cam.rows * k // n, cam.rows * (k + 1) // n), f"ortho_{cam.name}_s{k + 1}.tif")
                     for k in range(n)]
    return products


def check_images(scene: SceneModel, images: dict[int, str]) -> None:
    """Refuse, before any work, a raw image that cannot be read or whose size is not its camera's
    (``images``: {camera index: path})."""
    for camera, path in images.items():
        _open_raw(path, scene.cameras[camera])


def orthorectify_products(scene: SceneModel, images: dict[int, str], surface, folder, products: list[OrthoProduct],
                          grids: list[OrthoGrid], progress: Callable[[float], None] | None = None,
                          **options) -> list[dict]:
    """Orthorectify every product (:func:`strip_products`) onto its grid into ``folder``,
    completely or not at all: every orthoimage, or none when one fails or the user cancels.
    ``images``: {camera index: raw image path}; ``options``: those of :func:`orthorectify`.
    Progress runs over the whole run (weighted by each grid's pixels)."""
    report = progress or (lambda fraction: None)
    weights = np.array([g.cols * g.rows for g in grids], dtype=float)
    starts = np.concatenate([[0.0], np.cumsum(weights)]) / weights.sum()
    figures = []
    with atomic_outputs() as files:
        for k, (product, grid) in enumerate(zip(products, grids)):
            figures.append(orthorectify(scene, images[product.camera], surface, Path(folder) / product.name,
                                        product.camera, grid, rows=product.rows, files=files, **options,
                                        progress=lambda f, a=starts[k], b=starts[k + 1]: report(a + (b - a) * f)))
    return figures
