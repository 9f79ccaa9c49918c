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
overviews, under a temporary name renamed at the end: the output is complete or absent.
Coordinates: image positions in the GDAL convention (pixel centres at +0.5); output pixel
centres at the geotransform's +0.5.
"""
from __future__ import annotations

import logging
import math
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
from osgeo import gdal
from pyproj import CRS, Transformer
from scipy import ndimage

from .errors import Cancelled, InputError
from .geodesy import ecef_to_geodetic, geodetic_to_ecef
from .sensor import SceneModel

gdal.UseExceptions()
log = logging.getLogger(__name__)

RESAMPLING = {"nearest": 0, "bilinear": 1, "cubic": 3}  # spline orders of scipy.ndimage
SEAM_MARGIN = 8.0  # px from a chip boundary within which cells are mapped pixel by pixel


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


def default_grid(scene: SceneModel, camera: int, surface, crs: CRS | None = None,
                 resolution: float | None = None, extent: tuple | None = None) -> OrthoGrid:
    """The grid covering the image's footprint on the surface (or ``extent`` = (xmin, ymin,
    xmax, ymax) in ``crs``), in ``crs`` (default: the UTM zone of the scene centre), at
    ``resolution`` m (default: the ground sample distance at the image centre)."""
    cam = scene.cameras[camera]
    s = np.linspace(0.0, 1.0, 33)
    col = np.concatenate([s * cam.cols, np.full_like(s, cam.cols), s * cam.cols, np.zeros_like(s), [cam.cols / 2,
                                                                                                    cam.cols / 2 + 1]])
    row = np.concatenate([np.zeros_like(s), s * cam.rows, np.full_like(s, cam.rows), s * cam.rows, [cam.rows / 2] * 2])
    ground = scene.image_to_ground_dem(col, row, surface, camera)
    if not np.all(np.isfinite(ground)):
        raise InputError("the image's border does not meet the DEM everywhere: the DEM does not cover the scene")
    lon, lat, _ = ecef_to_geodetic(ground)
    crs = crs or utm_crs(float(lon[-1]), float(lat[-1]))
    x, y = Transformer.from_crs(CRS.from_epsg(4326), crs, always_xy=True).transform(lon, lat)
    if resolution is None:
        resolution = float(np.hypot(x[-1] - x[-2], y[-1] - y[-2]))
    if not resolution > 0:
        raise InputError(f"the output resolution must be positive (got {resolution})")
    xmin, ymin, xmax, ymax = extent or (np.min(x[:-2]), np.min(y[:-2]), np.max(x[:-2]), np.max(y[:-2]))
    x0 = math.floor(xmin / resolution) * resolution
    y0 = math.ceil(ymax / resolution) * resolution
    cols, rows = int(math.ceil((xmax - x0) / resolution)), int(math.ceil((y0 - ymin) / resolution))
    if cols * rows > 2e9:
        raise InputError(f"the output would have {cols} x {rows} pixels; choose a coarser resolution or an extent")
    return OrthoGrid(crs, x0, y0, resolution, cols, rows)


class _Mapper:
    """Output pixel centres of a tile -> image positions (col, row) of the raw image."""

    def __init__(self, scene: SceneModel, camera: int, surface, grid: OrthoGrid):
        self.scene, self.camera, self.surface, self.grid = scene, camera, surface, grid
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

    def tile(self, r0: int, r1: int, c0: int, c1: int, step: int, max_error: float) -> tuple[np.ndarray, np.ndarray, float]:
        """(col, row) arrays (r1-r0, c1-c0) of a tile, and the densification error measured (px)."""
        while True:
            ni = np.arange(r0, r1 + step, step, dtype=float)
            nj = np.arange(c0, c1 + step, step, dtype=float)
            gi, gj = np.meshgrid(ni, nj, indexing="ij")
            ncol, nrow = self.exact(gi.ravel(), gj.ravel())
            ncol, nrow = ncol.reshape(gi.shape), nrow.reshape(gi.shape)
            # check at the cell centres where the four corners lie on one chip
            ci, cj = np.meshgrid(ni[:-1] + step / 2, nj[:-1] + step / 2, indexing="ij")
            ecol, erow = self.exact(ci.ravel(), cj.ravel())
            icol = 0.25 * (ncol[:-1, :-1] + ncol[1:, :-1] + ncol[:-1, 1:] + ncol[1:, 1:]).ravel()
            irow = 0.25 * (nrow[:-1, :-1] + nrow[1:, :-1] + nrow[:-1, 1:] + nrow[1:, 1:]).ravel()
            # Seam cells: corners on different chips, or a centre the exact mapping puts on
            # another chip (a seam duplicate: both pixels see the point).
            centre_chip = self.cam.chip_index(np.nan_to_num(ecol, nan=-1.0)).reshape(ci.shape)
            seam = self._seam_cells(ncol) | (centre_chip != self.cam.chip_index(np.nan_to_num(
                ncol[:-1, :-1], nan=-1.0)))
            err = np.hypot(icol - ecol, irow - erow)[~seam.ravel()]
            worst = float(np.nanmax(err, initial=0.0))
            if worst <= max_error or step <= 2:
                break
            step //= 2
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


def orthorectify(scene: SceneModel, image_path, surface, output_path, camera: int = 0, grid: OrthoGrid | None = None,
                 resampling: str = "bilinear", nodata: float | None = 0.0, tile: int = 512, step: int = 32,
                 max_error: float = 0.01, progress: Callable[[float], None] | None = None,
                 is_cancelled: Callable[[], bool] | None = None) -> dict:
    """Orthorectify ``image_path`` (any GDAL raster, any bands and type, of the scene camera's
    size) onto ``grid`` (default :func:`default_grid`) and write a tiled, compressed GeoTIFF
    with overviews to ``output_path``. Returns figures: grid, densification error (px), time."""
    import time
    t_start = time.perf_counter()
    if resampling not in RESAMPLING:
        raise InputError(f"resampling must be one of {', '.join(RESAMPLING)} (got {resampling!r})")
    cam = scene.cameras[camera]
    try:
        src = gdal.Open(str(image_path))
    except RuntimeError as exc:
        raise InputError(f"{image_path}: cannot be opened as a raster ({exc})") from None
    if (src.RasterXSize, src.RasterYSize) != (cam.cols, cam.rows):
        raise InputError(f"{image_path}: the raster is {src.RasterXSize} x {src.RasterYSize} px but camera {cam.name} "
                         f"of the scene images {cam.cols} x {cam.rows} px: is it the scene's image?")
    grid = grid or default_grid(scene, camera, surface)
    bands = [src.GetRasterBand(b + 1) for b in range(src.RasterCount)]
    dtype = bands[0].DataType
    data = [b.ReadAsArray() for b in bands]  # the raw image in memory: random access by the mapping
    fill = nodata if nodata is not None else 0.0
    output_path = Path(output_path)
    tmp = output_path.with_name(output_path.stem + ".part.tif")
    drv = gdal.GetDriverByName("GTiff")
    out = drv.Create(str(tmp), grid.cols, grid.rows, len(bands), dtype,
                     ["TILED=YES", f"BLOCKXSIZE={tile}", f"BLOCKYSIZE={tile}", "COMPRESS=DEFLATE", "PREDICTOR=2",
                      "BIGTIFF=IF_SAFER", "NUM_THREADS=ALL_CPUS"])
    try:
        out.SetGeoTransform(grid.geotransform())
        out.SetProjection(grid.crs.to_wkt())
        for k in range(len(bands)):
            if nodata is not None:
                out.GetRasterBand(k + 1).SetNoDataValue(nodata)
        mapper = _Mapper(scene, camera, surface, grid)
        tiles = [(r0, min(r0 + tile, grid.rows), c0, min(c0 + tile, grid.cols))
                 for r0 in range(0, grid.rows, tile) for c0 in range(0, grid.cols, tile)]
        cancelled = is_cancelled or (lambda: False)
        order = RESAMPLING[resampling]

        def work(t):
            if cancelled():
                raise Cancelled("orthorectification cancelled by the user")
            r0, r1, c0, c1 = t
            col, row, err = mapper.tile(r0, r1, c0, c1, step, max_error)
            outside = ~np.isfinite(col) | (col < 0) | (col > cam.cols) | (row < 0) | (row > cam.rows)
            blocks = [np.full(col.shape, fill, dtype=d.dtype) for d in data]
            if outside.all():
                return t, blocks, err
            # image positions (GDAL, centres at +0.5) -> array indices (centres at 0), in the raw
            # window this tile needs (a cubic spline is prefiltered on that window only)
            i, j = row[~outside] - 0.5, col[~outside] - 0.5
            i0, j0 = max(int(i.min()) - 4, 0), max(int(j.min()) - 4, 0)
            i1, j1 = min(int(i.max()) + 5, cam.rows), min(int(j.max()) + 5, cam.cols)
            coords = np.stack([i - i0, j - j0])
            for b, d in zip(blocks, data):
                window = d[i0:i1, j0:j1]
                values = ndimage.map_coordinates(window.astype(np.float32) if order > 1 else window, coords,
                                                 order=order, mode="nearest", prefilter=order > 1)
                if np.issubdtype(d.dtype, np.integer):
                    info = np.iinfo(d.dtype)
                    values = np.clip(np.rint(values), info.min, info.max)
                b[~outside] = values
            return t, blocks, err

        worst = 0.0
        with ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as pool:
            for n, ((r0, r1, c0, c1), blocks, err) in enumerate(pool.map(work, tiles)):
                for k, b in enumerate(blocks):
                    out.GetRasterBand(k + 1).WriteArray(b, c0, r0)
                worst = max(worst, err)
                if progress:
                    progress(0.9 * (n + 1) / len(tiles))
        levels = [f for f in (2, 4, 8, 16, 32) if max(grid.cols, grid.rows) / f >= 256]
        if levels:
            out.BuildOverviews("AVERAGE" if resampling != "nearest" else "NEAREST", levels)
        out.FlushCache()
        out = None
        tmp.replace(output_path)
    finally:
        out = None
        if tmp.exists():
            tmp.unlink()
    if progress:
        progress(1.0)
    figures = {"cols": grid.cols, "rows": grid.rows, "resolution_m": grid.resolution, "crs": grid.crs.to_string(),
               "densification_error_px": worst, "max_error_px": max_error, "seconds": time.perf_counter() - t_start}
    log.info("orthoimage %d x %d at %.3f m in %.1f s; densification error <= %.2e px", grid.cols, grid.rows,
             grid.resolution, figures["seconds"], worst)
    return figures
