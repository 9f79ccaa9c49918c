"""The references image matching compares a raw image with: a georeferenced orthoimage
(:class:`Reference`) or another camera's raw image through the scene model
(:class:`ImageReference`, for tie points), each also block-averaged for the coarse levels of the
search (:meth:`Reference.level`); and the checks that the images can be matched at all (contrast,
overlap with the scene).
"""
from __future__ import annotations

import math
import threading

import numpy as np
from osgeo import gdal
from pyproj import CRS, Transformer
from pyproj.exceptions import CRSError

from ..errors import InputError
from ..geodesy import ecef_to_geodetic
from ..model.sensor import SceneModel
from ..products.rawimage import image_on_surface, open_raw
from ..rasters import open_input_raster
from .correlation import BlockMeans, strip_block_mean

gdal.UseExceptions()

MEMORY_BUDGET = 2 ** 30   # bytes of raw image / reference pixels held in memory
CUBIC_TAPS = 2            # px either side of a sample that cubic convolution reads


class Reference:
    """A north-up reference orthoimage (any projected or geographic CRS): its CRS, geotransform and
    pixels (in memory when they fit in ``budget`` bytes, else read by window through a GDAL
    dataset per thread)."""

    def __init__(self, path, budget: float = MEMORY_BUDGET):
        self.path = str(path)
        try:
            ds = open_input_raster(self.path)
        except RuntimeError as exc:
            raise InputError(f"reference {self.path}: cannot be opened as a raster ({exc})") from None
        self.cols, self.rows = ds.RasterXSize, ds.RasterYSize
        gt = ds.GetGeoTransform(can_return_null=True)
        wkt = ds.GetProjection()
        if not wkt or gt is None:
            raise InputError(f"reference {self.path}: no coordinate reference system or georeferencing: a reference "
                             "orthoimage must say where it lies (a GeoTIFF with its CRS, or a .prj/.aux.xml)")
        try:
            self.crs = CRS.from_wkt(wkt)
        except CRSError as exc:
            raise InputError(f"reference {self.path}: unknown coordinate reference system ({exc})") from None
        if gt[2] != 0 or gt[4] != 0 or not (gt[1] > 0 and gt[5] < 0):
            raise InputError(f"reference {self.path}: the geotransform {gt} is rotated or not north-up; warp it "
                             "north-up first (gdalwarp)")
        if not (self.crs.is_projected or self.crs.is_geographic):
            raise InputError(f"reference {self.path}: its coordinate reference system ({self.crs.name}) is neither "
                             "projected nor geographic, so its place on the Earth is unknown; assign the right CRS")
        self.geotransform = gt
        self.nodata = ds.GetRasterBand(1).GetNoDataValue()
        self.to_map = Transformer.from_crs(CRS.from_epsg(4326), self.crs, always_xy=True)
        centre = Transformer.from_crs(self.crs, CRS.from_epsg(4326), always_xy=True).transform(
            gt[0] + gt[1] * self.cols / 2, gt[3] + gt[5] * self.rows / 2)
        # pixel size on the ground (m): degrees of a geographic CRS at the raster's centre
        unit = (math.radians(6378137.0) * math.cos(math.radians(centre[1])) if self.crs.is_geographic
                else self.crs.axis_info[0].unit_conversion_factor)
        self.gsd = float(gt[1] * unit)
        if not (np.all(np.isfinite(centre)) and 1e-3 <= self.gsd <= 1e4):
            raise InputError(f"reference {self.path}: implausible georeferencing (pixel size {self.gsd:g} m in "
                             f"{self.crs.name}); expected an orthoimage with pixels of 1 mm to 10 km")
        self._local = threading.local()
        self.budget = budget
        self._levels: BlockMeans | None = None
        self.data = ds.GetRasterBand(1).ReadAsArray() if self.cols * self.rows * 4 <= budget else None
        ds = None

    def straddles_seam(self, x: np.ndarray) -> np.ndarray:
        """(n,) whether the windows at array columns x (n, ...) straddle a CCD seam of the image
        they sample: never for an orthoimage."""
        return np.zeros(x.shape[0], bool)

    def dataset(self):
        if not hasattr(self._local, "ds"):
            self._local.ds = open_input_raster(self.path)
        return self._local.ds

    def ground_pixel(self, ground: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Fractional array indices (x, y) of ECEF points (n, 3); NaN for points that are NaN (a
        ray that missed the surface)."""
        x, y = np.full(len(ground), np.nan), np.full(len(ground), np.nan)
        finite = np.isfinite(ground).all(axis=1)
        if finite.any():
            x[finite], y[finite] = self._ground_pixel(ground[finite])
        return x, y

    def _ground_pixel(self, ground: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        lon, lat, _ = ecef_to_geodetic(ground)
        return self.pixel(lon, lat)

    def level(self, factor: int) -> tuple[np.ndarray, int]:
        """The pixels block-averaged by ``factor`` (a power of two; or by a larger one when its
        pixels would not fit the memory budget), float32 with nodata NaN (a block holding nodata is
        NaN), and the factor used (:class:`core.measure.correlation.BlockMeans`). Factor 1 of pixels
        in memory is the pixels themselves (their own type, nodata as it is)."""
        if factor == 1 and self.data is not None:
            return self.data, 1
        factor = max(2, factor)
        while self.data is None and self.cols * self.rows * 4 / factor ** 2 > self.budget:
            factor *= 2
        if self._levels is None:
            self._levels = BlockMeans(self._read_level, self.cols, self.rows,
                                      self.budget if self.data is not None else 0)
        return self._levels.level(factor), factor

    def _read_level(self, factor: int) -> np.ndarray:
        """The pixels block-averaged by ``factor``: from memory, or read decimated by GDAL (average)."""
        cols, rows = self.cols // factor, self.rows // factor
        if cols < 1 or rows < 1:
            return np.full((1, 1), np.nan, np.float32)
        if self.data is not None:
            return strip_block_mean(self.data, factor, self.nodata)
        a = self.dataset().GetRasterBand(1).ReadAsArray(0, 0, cols * factor, rows * factor, buf_xsize=cols,
                                                        buf_ysize=rows, resample_alg=gdal.GRIORA_Average)
        return _blanked(a, self.nodata)

    def pixel(self, lon, lat) -> tuple[np.ndarray, np.ndarray]:
        """Fractional array indices (x = column, y = row; pixel centres at integers) of (lon, lat)."""
        x, y = self.to_map.transform(lon, lat)
        gt = self.geotransform
        return (np.asarray(x) - gt[0]) / gt[1] - 0.5, (np.asarray(y) - gt[3]) / gt[5] - 0.5

    def window(self, x: np.ndarray, y: np.ndarray, pad: int) -> tuple[np.ndarray, int, int]:
        """Pixels covering array positions (x, y) + ``pad``, clipped to the raster, in its own data
        type (the whole array when in memory: sample() indexes it flat, without a copy), and
        their origin."""
        x0, y0 = max(int(np.floor(np.nanmin(x))) - pad, 0), max(int(np.floor(np.nanmin(y))) - pad, 0)
        x1 = min(int(np.ceil(np.nanmax(x))) + pad + 1, self.cols)
        y1 = min(int(np.ceil(np.nanmax(y))) + pad + 1, self.rows)
        if x1 <= x0 or y1 <= y0:
            return np.full((1, 1), np.nan, np.float32), 0, 0
        if self.data is not None:
            return self.data, 0, 0
        return self.dataset().GetRasterBand(1).ReadAsArray(x0, y0, x1 - x0, y1 - y0), x0, y0

    def float_window(self, x: np.ndarray, y: np.ndarray, pad: int) -> tuple[np.ndarray, int, int]:
        """Like :meth:`window`, only the covering pixels, as float32 with nodata NaN."""
        a, ox, oy = self.window(x, y, pad)
        x0, y0 = max(int(np.floor(np.nanmin(x))) - pad - ox, 0), max(int(np.floor(np.nanmin(y))) - pad - oy, 0)
        x1, y1 = int(np.ceil(np.nanmax(x))) + pad + 1 - ox, int(np.ceil(np.nanmax(y))) + pad + 1 - oy
        return _blanked(a[y0:y1, x0:x1], self.nodata), ox + x0, oy + y0


class ImageReference(Reference):
    """Another camera's raw image as the reference (tie points): ground -> its image through the
    scene model. Pixels as :class:`Reference`'s."""

    def __init__(self, scene: SceneModel, camera: int, image_path, gsd: float, budget: float = MEMORY_BUDGET):
        cam = scene.cameras[camera]
        src, self.nodata = open_checked(scene, camera, image_path)
        self.scene, self.camera, self.path, self.gsd = scene, camera, str(image_path), gsd
        self.cols, self.rows = cam.cols, cam.rows
        self.budget = budget
        self._levels = None
        self.data = src.GetRasterBand(1).ReadAsArray() if self.cols * self.rows * 4 <= budget else None
        self._local = threading.local()

    def _ground_pixel(self, ground: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        col, row = self.scene.ground_to_image(ground, self.camera)
        return col - 0.5, row - 0.5

    def straddles_seam(self, x: np.ndarray) -> np.ndarray:
        """(n,) whether the windows at array columns x (n, ...) of this camera's image, with the
        taps of the cubic convolution (2 px either side), reach across one of its CCD seams."""
        flat = x.reshape(x.shape[0], int(np.prod(x.shape[1:])))   # -1 cannot reshape no window
        cam = self.scene.cameras[self.camera]
        first, last = flat.min(axis=1) + 0.5 - CUBIC_TAPS, flat.max(axis=1) + 0.5 + CUBIC_TAPS
        return cam.chip_index(first) != cam.chip_index(last)


def _blanked(a: np.ndarray, nodata) -> np.ndarray:
    """Float32 copy of ``a`` with its nodata pixels NaN."""
    a = a.astype(np.float32)
    if nodata is not None:
        a[a == nodata] = np.nan
    return a


def check_not_constant(what: str, path: str, a: np.ndarray) -> None:
    """InputError when a sample of an image has (almost) no contrast: nothing can be matched."""
    a = a[np.isfinite(a)]
    if a.size == 0 or float(np.std(a)) < 0.5:
        value = f" (value {float(a[0]):g})" if a.size else ""
        raise InputError(f"{what} {path}: the image is blank or constant{value}; nothing can be matched")


def open_checked(scene: SceneModel, camera: int, image_path):
    """(raw image in memory or by window, its nodata) after checking its size and contrast."""
    cam = scene.cameras[camera]
    src = open_raw(image_path, cam)
    band = src.GetRasterBand(1)
    step = max(1, min(cam.cols, cam.rows) // 256)
    check_not_constant("image", str(image_path), band.ReadAsArray(buf_xsize=cam.cols // step,
                                                                  buf_ysize=cam.rows // step).astype(np.float32))
    return src, band.GetNoDataValue()


def check_overlap(scene: SceneModel, camera: int, dem, ref: Reference, search: float) -> None:
    """InputError when the image footprint (onboard model, widened by the search range) and the
    reference's extent do not overlap; also checks the reference is not blank there."""
    lon, lat, _ = ecef_to_geodetic(image_on_surface(scene, camera, dem, footprint=True))
    x, y = ref.pixel(lon[:-2], lat[:-2])
    m = search / ref.gsd
    x0, x1, y0, y1 = np.min(x) - m, np.max(x) + m, np.min(y) - m, np.max(y) + m
    if not (np.all(np.isfinite([x0, x1, y0, y1])) and x1 > 0 and y1 > 0 and x0 < ref.cols and y0 < ref.rows):
        gt = ref.geotransform
        raise InputError(f"reference {ref.path} does not overlap the scene: its extent ({gt[0]:.0f}, "
                         f"{gt[3] + ref.rows * gt[5]:.0f}) - ({gt[0] + ref.cols * gt[1]:.0f}, {gt[3]:.0f}) in "
                         f"{ref.crs.name} lies apart from the image footprint "
                         f"(lon {np.min(lon):.4f}..{np.max(lon):.4f}, lat {np.min(lat):.4f}..{np.max(lat):.4f})")
    step = max(1, int(max(ref.cols, ref.rows) // 512))
    a = ref.data[::step, ::step] if ref.data is not None else ref.dataset().GetRasterBand(1).ReadAsArray(
        buf_xsize=max(ref.cols // step, 1), buf_ysize=max(ref.rows // step, 1))
    check_not_constant("reference", ref.path, _blanked(a, ref.nodata))
