"""Raw pushbroom images rendered from a known ground texture (:mod:`simulation.texture`): the
truth that orthorectification is checked against.

A raw image pixel (col, row) (GDAL convention, centre at +0.5) takes the texture value at
the ground point its line of sight meets on the DEM. Exact image -> ground is computed on a
node grid every ``GRID_STEP`` pixels of each CCD chip (extended beyond the chip so every
pixel has two nodes each side) and interpolated to the pixels with Catmull-Rom cubics. The
interpolation error is checked on sample pixels and logged: about 2e-4 px for a nadir camera
and 0.01 px for one tilted by 25 deg, set by the kinks of the bilinear DEM surface at its cell
edges (halving the node step barely changes it).
"""
from __future__ import annotations

import logging
import math
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace
from typing import Callable

import numpy as np
from osgeo import gdal

from ..core.errors import Cancelled, InputError
from ..core.files import check_closed, closing_errors
from ..core.geodesy import ecef_to_geodetic
from ..core.model.sensor import SceneModel
from .radiometry import Radiometry
from .roads import painter_for
from .texture import texture, texture_plane, to_digital_numbers

gdal.UseExceptions()
log = logging.getLogger(__name__)

GRID_STEP = 16          # px between exact image -> ground nodes
TILE_ROWS = 256         # rows rendered at once


def _cubic_weights(x: np.ndarray, first: float, step: float, n_nodes: int) -> np.ndarray:
    """Dense (len(x), n_nodes) Catmull-Rom interpolation matrix for positions x on nodes
    first + k*step; x must lie at least one step inside the node range."""
    f = (x - first) / step
    k = np.clip(np.floor(f).astype(int), 1, n_nodes - 3)
    t = f - k
    taps = np.stack([(-t + 2 * t * t - t ** 3) / 2, (2 - 5 * t * t + 3 * t ** 3) / 2,
                     (t + 4 * t * t - 3 * t ** 3) / 2, (-t * t + t ** 3) / 2], axis=1)
    w = np.zeros((x.size, n_nodes))
    rows = np.arange(x.size)[:, None]
    w[rows, k[:, None] + np.arange(-1, 3)] = taps
    return w


def _nodes(start: float, end: float, step: int) -> np.ndarray:
    """Node positions covering [start, end] with one extra node beyond each end."""
    n = int(math.ceil((end - start) / step)) + 3
    return start - step + step * np.arange(n)


class _ChipGrid:
    """Exact image -> ground on a node grid of one chip, interpolated to pixel centres."""

    def __init__(self, scene: SceneModel, camera: int, chip: int, dem, centre):
        cam = scene.cameras[camera]
        # A camera holding only this chip extends the chip's geometry past its ends, so that
        # nodes beyond the columns it delivers still follow it.
        single = replace(cam, chips=[cam.chips[chip]])
        self.scene = SceneModel(scene.epoch, scene.platform, [single], scene.aberration, scene.refraction,
                                dict(scene.info))
        self.cols = np.arange(*(int(round(v)) for v in cam.chip_range(chip))) + 0.5
        self.node_cols = _nodes(self.cols[0], self.cols[-1], GRID_STEP)
        self.col_weights = _cubic_weights(self.cols, self.node_cols[0], GRID_STEP, self.node_cols.size)
        self.dem = dem
        self.centre = centre

    def exact_plane(self, col: np.ndarray, row: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        lon, lat, _ = ecef_to_geodetic(self.scene.image_to_ground_dem(col, row, self.dem, 0))
        return texture_plane(lon, lat, self.centre)

    def plane(self, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Plane coordinates (len(rows), n cols) of the chip's pixel centres on these rows."""
        node_rows = _nodes(rows[0], rows[-1], GRID_STEP)
        cc, rr = np.meshgrid(self.node_cols, node_rows)
        x, y = self.exact_plane(cc.ravel(), rr.ravel())
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
            raise InputError(f"camera {self.scene.cameras[0].name}: image rays miss the DEM while rendering")
        w_rows = _cubic_weights(rows, node_rows[0], GRID_STEP, node_rows.size)
        shape = (node_rows.size, self.node_cols.size)
        return (w_rows @ x.reshape(shape) @ self.col_weights.T, w_rows @ y.reshape(shape) @ self.col_weights.T)


def render_image(scene: SceneModel, camera: int, dem, path, frame: dict,
                 progress: Callable[[float], None] | None = None,
                 is_cancelled: Callable[[], bool] | None = None, radiometry: Radiometry | None = None) -> float:
    """Render camera ``camera`` of ``scene`` over ``dem`` into an 8-bit GeoTIFF at ``path``
    (no georeferencing: raw image geometry), with the texture of ``frame`` (see
    :func:`simulation.texture.texture_frame`) and its roads (``frame['roads']``, :mod:`simulation.roads`). Returns the
    largest interpolation error of the ground position measured on sample pixels, in pixels
    (ground metres / GSD). radiometry: the acquisition's gain, gamma, noise and changed land
    cover (:class:`simulation.radiometry.Radiometry`); None: DN = 20 + 215 v, noise-free.
    """
    cam = scene.cameras[camera]
    centre, gsd, seed = tuple(frame["centre"]), float(frame["gsd_m"]), int(frame["seed"])
    grids = [_ChipGrid(scene, camera, k, dem, centre) for k in range(len(cam.chips))]
    roads = painter_for(frame)
    ds = gdal.GetDriverByName("GTiff").Create(str(path), cam.cols, cam.rows, 1, gdal.GDT_Byte,
                                              ["TILED=YES", "COMPRESS=DEFLATE", "PREDICTOR=2", "BIGTIFF=IF_SAFER"])
    ds.SetMetadata({"PUSHBROOM_CAMERA": cam.name, "PUSHBROOM_TEXTURE_SEED": str(seed)})
    band = ds.GetRasterBand(1)
    starts = list(range(0, cam.rows, TILE_ROWS))
    cancelled = is_cancelled or (lambda: False)

    def tile(r0: int) -> np.ndarray:
        if cancelled():
            raise Cancelled("rendering cancelled by the user")
        rows = np.arange(r0, min(r0 + TILE_ROWS, cam.rows)) + 0.5
        out = np.empty((rows.size, cam.cols), np.uint8)
        for k, g in enumerate(grids):
            x, y = g.plane(rows)
            c0 = int(g.cols[0])
            value = texture(x, y, gsd, seed)
            if radiometry is not None:
                value = radiometry.change(x, y, value, gsd, seed)
            if roads is not None:
                value = roads.paint(x, y, value)
            out[:, c0:c0 + g.cols.size] = (to_digital_numbers(value) if radiometry is None
                                           else radiometry.digital_numbers(value, (r0, k)))
        return out

    try:
        with ThreadPoolExecutor(max_workers=min(2, os.cpu_count() or 1)) as pool:
            for n, (r0, block) in enumerate(zip(starts, pool.map(tile, starts))):
                band.WriteArray(block, 0, r0)
                if progress:
                    progress((n + 1) / len(starts))
    finally:
        with closing_errors() as closing:
            band = ds = None  # closes the file, also when cancelled
    check_closed(path, closing)
    error = interpolation_error(grids, cam.rows, gsd)
    log.info("rendered %s (%d x %d); ground interpolation error max %.2e px", cam.name, cam.cols, cam.rows, error)
    return error


def interpolation_error(grids: list[_ChipGrid], rows: int, gsd: float, n: int = 2000) -> float:
    """Largest distance (px) between interpolated and exact ground positions of random pixels."""
    rng = np.random.default_rng(0)
    worst = 0.0
    for g in grids:
        r0 = int(rng.integers(0, max(rows - TILE_ROWS, 1)))
        rows_ = np.arange(r0, min(r0 + TILE_ROWS, rows)) + 0.5
        x, y = g.plane(rows_)
        i = rng.integers(0, rows_.size, n)
        j = rng.integers(0, g.cols.size, n)
        ex, ey = g.exact_plane(g.cols[j], rows_[i])
        worst = max(worst, float(np.max(np.hypot(x[i, j] - ex, y[i, j] - ey))) / gsd)
    return worst
