"""The raw image of a scene camera, as the products read it: opened and checked against the
camera, read by window (from memory or from the file), resampled at image positions, and where
the image meets the terrain.

Image positions (col, row) are GDAL's: (0, 0) is the upper-left corner of the upper-left pixel,
pixel centres at +0.5.
"""
from __future__ import annotations

import logging
import threading
from pathlib import Path

import numpy as np
from osgeo import gdal, gdal_array
from scipy import ndimage

from ..dem import ConstantHeight
from ..errors import InputError, MetadataError
from ..formats.rpcfiles import read_rpc_image
from ..geodesy import ecef_to_geodetic
from ..model.rpcscene import size_note
from ..model.sensor import SceneModel
from ..rasters import open_input_raster
from .footprint import rays_without_height

gdal.UseExceptions()
log = logging.getLogger(__name__)

# A raw image that carries its own RPC is not the image of a scene camera when the scene sees the ground of the
# image's centre (by that RPC) this far outside the camera's image (px; or the image's size, when larger): far
# beyond any geolocation error of a model of the same image.
FOREIGN_MARGIN_PX = 2000.0
# Beyond this (px) the image's own RPC and the scene disagree enough to say so in the log.
DISAGREEMENT_NOTE_PX = 100.0


def open_raw(image_path, cam):
    """The raw image as a GDAL dataset (decoded on all cores), checked against the camera's size."""
    try:
        src = open_input_raster(image_path, open_options=["NUM_THREADS=ALL_CPUS"])
    except RuntimeError as exc:
        raise InputError(f"{image_path}: cannot be opened as a raster ({exc})") from None
    if (src.RasterXSize, src.RasterYSize) != (cam.cols, cam.rows):
        raise InputError(f"{image_path}: the raster is {src.RasterXSize} x {src.RasterYSize} px but camera {cam.name} "
                         f"of the scene images {cam.cols} x {cam.rows} px{size_note(cam)}: is it the scene's image?")
    return src


def check_image_belongs(scene: SceneModel, camera: int, image_path) -> None:
    """InputError naming the image and the scene when the raw image carries its own RPC (GDAL's RPC metadata:
    tags, or an ``_RPC.TXT``/``.RPB`` beside it) that puts its centre on ground the scene's camera sees far
    outside its image (FOREIGN_MARGIN_PX) or not at all: the image and the scene do not belong together (e.g.
    an RPC scene given another product's image). An image without an RPC (or with one GDAL reads but that does
    not fit it) cannot be judged so and passes; a disagreement beyond DISAGREEMENT_NOTE_PX is logged."""
    try:
        own = read_rpc_image(Path(image_path))
    except MetadataError as exc:
        log.info("the RPC GDAL reads with %s is not compared with the scene: %s", image_path, exc)
        return
    if own is None:
        return
    cam = scene.cameras[camera]
    # at a height both models hold where their ranges overlap (neither then warns of extrapolation)
    height = float(np.clip(np.mean(scene.height_range), *own.height_range))
    ground = own.image_to_ground(np.array([cam.cols / 2]), np.array([cam.rows / 2]), height)
    if not np.all(np.isfinite(ground)):
        return
    col, row = (float(v[0]) for v in scene.ground_to_image(ground, camera))
    margin = max(FOREIGN_MARGIN_PX, cam.cols, cam.rows)
    scene_name = f"the scene {scene.info.get('source', '')}".rstrip()
    if np.isfinite(col) and np.isfinite(row) and -margin <= col <= cam.cols + margin and \
            -margin <= row <= cam.rows + margin:
        off = float(np.hypot(col - cam.cols / 2, row - cam.rows / 2))
        if off > DISAGREEMENT_NOTE_PX:
            log.warning("%s: its own RPC and %s disagree by %.0f px at the image's centre", image_path, scene_name, off)
        return
    lon, lat, _ = (float(v[0]) for v in ecef_to_geodetic(ground))
    seen = (f"sees at ({col:.0f}, {row:.0f}), far outside its camera {cam.name}'s {cam.cols} x {cam.rows} px image"
            if np.isfinite(col) and np.isfinite(row) else f"does not see with its camera {cam.name}")
    raise InputError(f"{image_path}: the image and {scene_name} do not belong together: the image's own RPC puts its "
                     f"centre at latitude {lat:.5f}, longitude {lon:.5f}, which the scene {seen}. Is it the scene's "
                     "image, and the scene the image's model?")


class RawImage:
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
            ds = self._local.ds = open_input_raster(self.path)
        return ds.ReadAsArray(j0, i0, j1 - j0, i1 - i0).reshape(self.count, i1 - i0, j1 - j0)

    def close(self) -> None:
        """Drop the decoded image and every thread's dataset."""
        self.data, self._local = None, threading.local()


def resample(raw: RawImage, col: np.ndarray, row: np.ndarray, order: int, fill,
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


def image_on_surface(scene: SceneModel, camera: int, surface, footprint: bool,
                     rows: tuple[int, int] | None = None) -> np.ndarray:
    """ECEF points (n, 3) where the image (its ``rows`` = (first, end), default all) meets the
    surface: with ``footprint`` 33 points along each side of the border, then (always) the
    centre pixel and its right neighbour (at the surface's mean height where they meet a DEM only
    on its nodata holes, and without ``footprint`` wherever the surface misses them). InputError
    naming the DEM where they do not meet it."""
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
    missing = ~np.all(np.isfinite(ground), axis=1)
    if missing.any():
        # The centre only sets the default CRS and pixel size, and points on a DEM's nodata holes
        # only widen the grid: the DEM's mean height serves there.
        redo = missing.copy()
        if footprint:
            redo[missing] = rays_without_height(scene, camera, col[missing], row[missing], surface)[1]
        if redo.any():
            flat = ConstantHeight(float(np.mean(surface.height_range)))
            ground[redo] = scene.image_to_ground_dem(col[redo], row[redo], flat, camera)
    if not np.all(np.isfinite(ground)):
        name = getattr(surface, "path", "the terrain surface")
        where = "the image's centre" if not np.all(np.isfinite(ground[-2:])) else "the image's border"
        height = float(np.mean(surface.height_range))
        lon, lat, _ = ecef_to_geodetic(scene.image_to_ground(centre_col[:1], centre_row[:1], height, camera))
        raise InputError(f"DEM {name} does not cover the scene {scene.info.get('source', '')}: {where} does not meet "
                         f"it (the scene puts the image's centre at latitude {lat[0]:.5f}, longitude {lon[0]:.5f} at "
                         f"{height:.0f} m). Use a DEM covering the footprint, a constant height, or an extent inside "
                         "the DEM; or check that the scene is the image's model")
    return ground
