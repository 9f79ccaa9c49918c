"""The co-registration check of an orthomosaic: every two orthoimages of one pixel lattice that
overlap, measured by phase correlation on windows of their overlap
(:func:`core.measure.coregistration.coregister`: the same windows, sub-pixel refinement and
reasons for leaving a window out).

Two orthoimages overlap when their grids intersect and at least one pixel of the intersection
holds data in both; the rest of the intersection is nodata in one of them and its windows are
counted as left out for nodata. The figures are in output pixels: with the true (or adjusted)
models the overlaps of a block co-register within a few hundredths of a pixel, with biased onboard
or vendor models by their relative bias (:data:`MISREGISTERED_PX` and above is called out).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import InputError
from ..products.overlaps import meeting_boxes
from ..rasters import open_input_raster
from .coregistration import CoregSettings, coregister

MISREGISTERED_PX = 0.5   # RMS (px) above which a pair is named as not co-registered
LATTICE_TOLERANCE = 1e-6  # px: grid origins this close to a whole pixel apart are on one lattice
# A pair whose overlap holds fewer than MIN_WINDOWS used windows of the settings' size is measured
# again on SMALL_WINDOW px windows every SMALL_WINDOW / 2 px: a region's forward overlap (15 % of a
# 600 px product, slanted on the north-up grid) held 1 window of 64 px, its corners none; on 32 px
# windows 110-120 and 15-18, the true models' RMS 0.03-0.06 px instead of 0.02 on 64 px.
MIN_WINDOWS = 10
SMALL_WINDOW = 32


@dataclass(frozen=True)
class PairCoregistration:
    """One overlapping pair's check: the orthoimages' names, the pixels where both hold data,
    the windows measured, used and left out {reason: count} (core.measure.coregistration.REASONS),
    the RMS, median and largest shift length (px) of the used windows and their mean shift
    (dx east, dy south, px) of the second against the first, NaN without a used window; and the
    windows' size (px)."""
    first: str
    second: str
    common_pixels: int
    windows: int
    used: int
    left_out: dict = field(default_factory=dict)
    rms_px: float = float("nan")
    median_px: float = float("nan")
    max_px: float = float("nan")
    mean_px: tuple = (float("nan"), float("nan"))
    window_px: int = CoregSettings.window

    @property
    def sentence(self) -> str:
        """The pair's figures in words, for the log."""
        out = ", ".join(f"{n} {reason}" for reason, n in self.left_out.items() if n) or "none"
        if not self.used:
            return (f"{self.first} - {self.second}: no window measured ({self.common_pixels} common pixels, "
                    f"{self.windows} windows of {self.window_px} px; left out: {out})")
        return (f"{self.first} - {self.second}: {self.rms_px:.3f} px RMS (median {self.median_px:.3f}, max "
                f"{self.max_px:.3f}, mean shift {self.mean_px[0]:+.3f}, {self.mean_px[1]:+.3f} px) on {self.used} of "
                f"{self.windows} windows of {self.window_px} px; left out: {out}")


@dataclass(frozen=True)
class Raster:
    """An orthoimage's name, file, geotransform, size (cols, rows) and first band's nodata."""
    name: str
    path: str
    geotransform: tuple
    cols: int
    rows: int
    nodata: float | None

    @classmethod
    def open(cls, name: str, path) -> "Raster":
        ds = open_input_raster(path)
        return cls(name, str(path), ds.GetGeoTransform(), ds.RasterXSize, ds.RasterYSize,
                   ds.GetRasterBand(1).GetNoDataValue())


def overlap_window(a: Raster, b: Raster) -> tuple | None:
    """(col_a, row_a, col_b, row_b, cols, rows): the intersection of two north-up grids of one
    pixel lattice, in each one's pixels; None when they do not intersect. InputError when their
    pixel sizes differ or their origins are not whole pixels apart."""
    ga, gb = a.geotransform, b.geotransform
    if ga[2] or ga[4] or gb[2] or gb[4] or ga[1] != gb[1] or ga[5] != gb[5]:
        raise InputError(f"{a.name} and {b.name} are not on one north-up grid of one pixel size (geotransforms "
                         f"{ga} and {gb})")
    dc, dr = (gb[0] - ga[0]) / ga[1], (gb[3] - ga[3]) / ga[5]
    if abs(dc - round(dc)) > LATTICE_TOLERANCE or abs(dr - round(dr)) > LATTICE_TOLERANCE:
        raise InputError(f"{a.name} and {b.name} are not on one pixel lattice: {b.name}'s origin is {dc:.6f}, "
                         f"{dr:.6f} px from {a.name}'s")
    dc, dr = int(round(dc)), int(round(dr))
    c0, r0 = max(0, dc), max(0, dr)
    c1, r1 = min(a.cols, dc + b.cols), min(a.rows, dr + b.rows)
    if c1 <= c0 or r1 <= r0:
        return None
    return c0, r0, c0 - dc, r0 - dr, c1 - c0, r1 - r0


def _window(raster: Raster, col: int, row: int, cols: int, rows: int) -> np.ndarray:
    """Band 1 of ``raster`` in the window, float, its nodata as NaN."""
    ds = open_input_raster(raster.path)  # held while its band is read
    data = ds.GetRasterBand(1).ReadAsArray(col, row, cols, rows).astype(np.float64)
    if raster.nodata is not None:
        data[data == raster.nodata] = np.nan
    return data


def check_pair(a: Raster, b: Raster, settings: CoregSettings = CoregSettings()) -> PairCoregistration | None:
    """The co-registration of ``b`` against ``a`` on their overlap (see the module docstring), on
    SMALL_WINDOW px windows when those of ``settings`` leave fewer than MIN_WINDOWS used and the
    small ones use more; None when they do not overlap (no pixel with data in both)."""
    window = overlap_window(a, b)
    if window is None:
        return None
    ca, ra, cb, rb, cols, rows = window
    first, second = _window(a, ca, ra, cols, rows), _window(b, cb, rb, cols, rows)
    common = int(np.count_nonzero(np.isfinite(first) & np.isfinite(second)))
    if not common:
        return None
    c = coregister(first, second, settings)
    if c.n_used < MIN_WINDOWS and settings.window > SMALL_WINDOW:
        small = replace(settings, window=SMALL_WINDOW, spacing=SMALL_WINDOW // 2)
        again = coregister(first, second, small)
        if again.n_used > c.n_used:
            c, settings = again, small
    return PairCoregistration(a.name, b.name, common, int(c.reason.size), c.n_used, c.left_out(), c.rms, c.median,
                              c.max, c.mean, settings.window)


def check_mosaic(orthoimages: dict, settings: CoregSettings = CoregSettings()) -> list[PairCoregistration]:
    """Every overlapping pair of ``orthoimages`` ({name: file}, one pixel lattice), in the order
    given (first, second with first before second), checked by :func:`check_pair`; the candidate
    pairs are those whose grids' boxes meet (:func:`meeting_boxes`), not every pair."""
    rasters = [Raster.open(name, path) for name, path in orthoimages.items()]
    pairs = []
    for i, j in meeting_boxes(np.array([grid_box(r) for r in rasters]).reshape(-1, 4)):
        checked = check_pair(rasters[i], rasters[j], settings)
        if checked is not None:
            pairs.append(checked)
    return pairs


def grid_box(raster: Raster) -> tuple[float, float, float, float]:
    """(xmin, ymin, xmax, ymax) of a north-up grid, in its CRS's units."""
    x0, dx, _, y0, _, dy = raster.geotransform
    xs, ys = (x0, x0 + dx * raster.cols), (y0, y0 + dy * raster.rows)
    return min(xs), min(ys), max(xs), max(ys)


def misregistered(pairs: list[PairCoregistration], limit: float = MISREGISTERED_PX) -> list[PairCoregistration]:
    """The pairs whose RMS exceeds ``limit`` px, or that no window could measure."""
    return [p for p in pairs if not p.used or p.rms_px > limit]
