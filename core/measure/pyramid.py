"""Coarse to fine: the offset of every grid point (where the raw image shows what the models put at
it), found over an image pyramid before the fine pass (:mod:`core.measure.matching`).

1. **Search range.** SEARCH_RANGE (m) over the base image's GSD is the search radius in pixels,
   clipped to the base image's larger side (an offset beyond it leaves nothing of the image in
   common with its prediction): a range too large for a small image is clipped and said so, never
   refused.
2. **Global level.** The raw image block-averaged by a power of two f (its larger side at most
   TOP_SIZE px) is correlated as a whole with the reference in its geometry over the whole search
   range: the reference sampled through the models on a lattice reaching the search radius beyond
   the image (:func:`core.measure.prediction.lattice_positions`), block-averaged alike, holes and
   whatever lies beyond the reference's or the other image's edge masked (masked normalised
   cross-correlation, Padfield 2012). Its peak is the models' common offset. A weak peak, or one
   on the border of the search, stops the run: the error exceeds the search range, or the images
   do not show the same ground. The cost grows with the image, not with the search range. Two
   images that share a small part (a region's forward overlap or the corner of four products) are
   correlated at a finer level, so that their common part holds enough level pixels
   (:func:`global_factor`).
3. **Local levels** f, f/4, ..., 2 (:func:`local_factors`). Chips of LEVEL_WINDOW level pixels on a
   grid over the image (at most MAX_LEVEL_CHIPS, no denser than the grid matched) are correlated
   within LEVEL_RADIUS level pixels of the offset predicted for them, each rectified at the offsets
   found so far (:func:`core.measure.prediction.predicted_positions`, ``warp``); a chip's offset is
   kept when its peak is clear and it agrees with its neighbours'. The offset predicted anywhere
   is then the plane fitted to the NEIGHBOURS nearest kept chips' (on a lattice, bilinear between):
   it follows what one plane over the image cannot, the parallax of relief the surface lacks (a
   pyramid on a flat HEIGHT: 20 px on the Giza pair; a 90 m DSM's errors under 0.5 m pixels).

The fine pass then searches FINE_RADIUS px around each grid point's predicted offset.
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

import numpy as np
from osgeo import gdal
from scipy.ndimage import map_coordinates
from scipy.spatial import cKDTree

from ..errors import InputError
from ..model.sensor import SceneModel
from ..products.rawimage import RawImage
from ..rasters import open_input_raster
from .correlation import BlockMeans, find_peaks, masked_ncc, ncc, sample, strip_block_mean
from .matchchecks import plane_at
from .prediction import lattice_positions, predicted_positions, reference_scale
from .reference import MEMORY_BUDGET

log = logging.getLogger(__name__)

TOP_SIZE = 128            # level px: the global level's larger side, at most
LEVEL_WINDOW = 31         # level px: a local level's chip
LEVEL_RADIUS = 8          # level px searched around the offset the coarser level predicts
MAX_LEVEL_CHIPS = 512     # chips of a local level, at most
NEIGHBOURS = 8            # kept chips whose plane of offsets predicts a point's
FIELD_STEP = 16           # base px between the nodes of the predicted offset field, at least
GLOBAL_MIN_PEAK = 0.3     # the global level's correlation peak, at least
LEVEL_MIN_PEAK = 0.5      # a local chip's, at least
MIN_OVERLAP = 0.1         # share of the smaller image's pixels a global placement must overlap, at least ...
MIN_OVERLAP_PX = 1024     # ... and this many level pixels (a small overlap correlates by chance)
MIN_TEXTURE = 1.0         # DN: a chip flatter than this (standard deviation) says nothing
# The global level is made finer (down to the raw pixels, its larger side at most MAX_GLOBAL_SIZE
# px) until the overlap the models predict holds OVERLAP_MARGIN x MIN_OVERLAP_PX level pixels: the
# corner two products of neighbouring strips share (a 20 % side-lap by a 15 % forward overlap:
# 3 % of an image, 165 level pixels at 1:8 of 600 px) could not reach MIN_OVERLAP_PX at the top size.
OVERLAP_MARGIN = 2
MAX_GLOBAL_SIZE = 1024


@dataclass
class CoarseOffsets:
    """The pyramid's result: the search radius (base px) and the range (m) it stands for, whether
    SEARCH_RANGE was clipped, the global level (factor, offset (col, row) px, peak), per local level
    (factor, chips, kept), and the offset field the kept chips of the last level that kept any
    predict: (2, rows, cols) offsets (dc, dr) px at the base image positions (step j, step i),
    None before any local level kept chips."""
    radius_px: float
    search_m: float
    clipped: bool
    factor: int
    offset: tuple[float, float]
    peak: float
    levels: list = field(default_factory=list)
    field: np.ndarray | None = None
    step: float = 1.0

    def predict(self, col: np.ndarray, row: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The offsets (dc, dr) px predicted at base image positions (col, row) (n,): bilinear in
        the field (its edge values beyond it), the global offset without one."""
        if self.field is None:
            return np.full(np.shape(col), self.offset[0]), np.full(np.shape(col), self.offset[1])
        at = [np.asarray(row, float) / self.step, np.asarray(col, float) / self.step]
        return tuple(map_coordinates(f, at, order=1, mode="nearest") for f in self.field)

    def set_field(self, points: np.ndarray, offsets: np.ndarray, cols: int, rows: int, step: float) -> None:
        """The field of the kept chips at ``points`` (m, 2: col, row px) with ``offsets`` (m, 2): at
        each node (every ``step`` px, at least FIELD_STEP) the plane fitted to its NEIGHBOURS nearest
        chips' offsets (their median with fewer chips): a plane follows a slope's steadily growing
        parallax, which a median would flatten."""
        self.step = max(FIELD_STEP, step)
        jj, ii = np.meshgrid(np.arange(int(cols / self.step) + 2), np.arange(int(rows / self.step) + 2))
        xy = np.stack([jj.ravel(), ii.ravel()], axis=1) * self.step
        k = min(NEIGHBOURS, len(points))
        _, near = cKDTree(points).query(xy, k)
        near = near.reshape(len(xy), k)
        if k < NEIGHBOURS:
            d = np.median(offsets[near], axis=1)
        else:
            d = plane_at(xy, points[near], offsets[near])
        self.field = np.stack([d[:, 0].reshape(ii.shape), d[:, 1].reshape(ii.shape)])

    def summary(self) -> dict:
        """The figures a report shows (JSON-ready)."""
        return {"factor": self.factor, "offset_px": list(self.offset), "peak": self.peak,
                "search_px": self.radius_px, "search_m": self.search_m, "clipped": self.clipped,
                "levels": [{"factor": f, "chips": c, "kept": k} for f, c, k in self.levels]}


def raw_levels(raw: RawImage, nodata) -> BlockMeans:
    """The raw image's (band 1) block means (float32, nodata NaN): from its pixels in memory, or read
    decimated by GDAL (average) from the file."""
    def read(factor: int) -> np.ndarray:
        if raw.data is not None:
            return strip_block_mean(raw.data[0], factor, nodata)
        rows, cols = raw.rows // factor, raw.cols // factor
        ds = open_input_raster(raw.path)  # held while its band is read: a band outliving its dataset crashes GDAL
        a = ds.GetRasterBand(1).ReadAsArray(0, 0, cols * factor, rows * factor, buf_xsize=cols, buf_ysize=rows,
                                            resample_alg=gdal.GRIORA_Average).astype(np.float32)
        ds = None
        if nodata is not None:
            a[a == nodata] = np.nan
        return a

    return BlockMeans(read, raw.cols, raw.rows, MEMORY_BUDGET if raw.data is not None else 0)


def sampled(ref, scale: float, factor: int, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The reference at its array positions (x, y) as seen at base level ``factor``: read from its
    level whose pixels are about ``factor`` base pixels wide (``scale``: reference px per base
    px), so both images are averaged alike. NaN where it has no data."""
    pixels, g = ref.level(2 ** max(0, round(math.log2(max(factor * scale, 1.0)))))
    return sample(pixels, 0, 0, (x - (g - 1) / 2) / g, (y - (g - 1) / 2) / g, ref.nodata if g == 1 else None)


def search_radius(search_m: float, gsd: float, cam) -> tuple[float, float, bool]:
    """(radius px, the range in m it stands for, whether clipped): SEARCH_RANGE over the GSD,
    at most the image's larger side."""
    radius = search_m / gsd
    limit = float(max(cam.cols, cam.rows))
    if radius > limit:
        return limit, limit * gsd, True
    return radius, search_m, False


def coarse_offsets(scene: SceneModel, camera: int, surface, ref, levels: BlockMeans, gsd: float,
                   search_m: float, spacing: float, min_texture: float, max_peak_ratio: float) -> CoarseOffsets:
    """The coarse-to-fine search of the module docstring (local chips no closer than ``spacing`` px,
    the grid's: no level needs more of them than the fine pass matches). InputError when the global
    level finds no clear match within the search range."""
    cam = scene.cameras[camera]
    radius, search_used, clipped = search_radius(search_m, gsd, cam)
    if clipped:
        log.info("search range %g m clipped to %.0f m: %.0f px, the image's larger side (%d x %d px); a larger "
                 "offset would leave the image nothing in common with its prediction", search_m, search_used,
                 radius, cam.cols, cam.rows)
    top = 2 ** max(0, math.ceil(math.log2(max(cam.cols, cam.rows) / TOP_SIZE)))
    scale = reference_scale(scene, camera, surface, ref)
    factor = global_factor(scene, camera, surface, ref, levels, top, scale)
    out = global_offset(scene, camera, surface, ref, levels, factor, scale, radius, search_used, clipped,
                        max_peak_ratio)
    for f in local_factors(factor):
        points, offsets, chips, chip_spacing = local_level(scene, camera, surface, ref, levels, f, scale, out, spacing,
                                                           min_texture, max_peak_ratio)
        out.levels.append((f, chips, len(points)))
        if len(points) >= 3:
            out.set_field(points, offsets, cam.cols, cam.rows, chip_spacing / 2)
    log.info("coarse to fine: the whole image at 1:%d offset by (%.1f, %.1f) px (correlation %.2f); local chips kept "
             "%s", factor, *out.offset, out.peak,
             ", ".join(f"{k} of {c} at 1:{f}" for f, c, k in out.levels) or "none (the image is small)")
    return out


def global_factor(scene: SceneModel, camera: int, surface, ref, levels: BlockMeans, top: int, scale: float) -> int:
    """The global level's factor: ``top`` (the image's larger side at most TOP_SIZE level px),
    halved while the pixels the image and the reference share at the models' offset (counted at
    ``top``, scaled to the finer level) fall short of OVERLAP_MARGIN x MIN_OVERLAP_PX and the level's
    larger side stays within MAX_GLOBAL_SIZE."""
    raw = levels.level(top)
    x, y = lattice_positions(scene, camera, surface, ref, 0.5 * top, 0.5 * top, float(top), raw.shape)
    common = np.count_nonzero(np.isfinite(raw) & np.isfinite(sampled(ref, scale, top, x, y)))
    cam = scene.cameras[camera]
    f = top
    while (f > 1 and common * (top / f) ** 2 < OVERLAP_MARGIN * MIN_OVERLAP_PX
           and max(cam.cols, cam.rows) / (f // 2) <= MAX_GLOBAL_SIZE):
        f //= 2
    return f


def local_factors(top: int) -> list[int]:
    """The local levels' factors below a global level's ``top``: 2, 8, 32, ... up to ``top``, coarse
    first (a level's search, LEVEL_RADIUS level pixels, covers four times the next one's)."""
    out, f = [], 2
    while f <= top:
        out.insert(0, f)
        f *= 4
    return out


def global_offset(scene: SceneModel, camera: int, surface, ref, levels: BlockMeans, f: int, scale: float,
                  radius: float, search_m: float, clipped: bool, max_peak_ratio: float) -> CoarseOffsets:
    """The global level (module docstring, 2)."""
    raw = levels.level(f)
    rc = int(math.ceil(radius / f)) + 1
    shape = (raw.shape[0] + 2 * rc, raw.shape[1] + 2 * rc)
    # level pixel k of the extended lattice: base position (k - rc + 0.5) f, as raw level pixel k's is (k + 0.5) f
    x, y = lattice_positions(scene, camera, surface, ref, (0.5 - rc) * f, (0.5 - rc) * f, float(f), shape)
    extended = sampled(ref, scale, f, x, y)
    smaller = min(int(np.isfinite(raw).sum()), int(np.isfinite(extended).sum()))
    c, _ = masked_ncc(raw, extended, max(MIN_OVERLAP_PX, int(MIN_OVERLAP * smaller)))
    peak = find_peaks(c[None], 2, local=True)
    # the raw level pixel i shows what the reference shows at lattice pixel i + d: offset (rc - d) f
    dc, dr = (rc - float(peak.dx[0])) * f, (rc - float(peak.dy[0])) * f
    value, ratio, border = float(peak.value[0]), float(peak.ratio[0]), bool(peak.border[0])
    log.debug("global level 1:%d: search +-%d level px, peak %.3f at offset (%.1f, %.1f) px, second/first %.2f%s",
             f, rc, value, dc, dr, ratio, ", on the border of the search" if border else "")
    if value < GLOBAL_MIN_PEAK or border or np.hypot(dc, dr) > radius + f:
        raise InputError(
            f"no consistent match between the image and reference {ref.path} within the search range "
            f"(+-{search_m:g} m{', clipped to the image' if clipped else ''}): the best correlation of the whole "
            f"image, {value:.2f} at an offset of ({dc:.0f}, {dr:.0f}) px, is "
            f"{'on the border of the search area' if border or np.hypot(dc, dr) > radius + f else 'too weak'}. "
            "Either the onboard model is farther off than the search range (increase the search range, e.g. to "
            "twice the expected onboard error), or the reference does not show the same ground (check its overlap, "
            "date and CRS)")
    return CoarseOffsets(radius, search_m, clipped, f, (dc, dr), value)


def local_level(scene: SceneModel, camera: int, surface, ref, levels: BlockMeans, f: int, scale: float,
                coarse: CoarseOffsets, grid_spacing: float, min_texture: float,
                max_peak_ratio: float) -> tuple[np.ndarray, np.ndarray, int, float]:
    """One local level (module docstring, 3): the kept chips' positions and offsets (base px), the
    number of chips tried and their spacing (base px)."""
    cam = scene.cameras[camera]
    raw = levels.level(f)
    w, r = LEVEL_WINDOW, LEVEL_RADIUS
    s = w + 2 * r
    none = np.zeros((0, 2))
    if min(raw.shape) < s:
        return none, none, 0, 0.0
    margin = f * ((w - 1) / 2 + 1)
    spacing = max(f * w / 2, grid_spacing, math.sqrt(cam.cols * cam.rows / MAX_LEVEL_CHIPS))
    cols, rows = np.arange(margin, cam.cols - margin, spacing), np.arange(margin, cam.rows - margin, spacing)
    if cols.size == 0 or rows.size == 0:
        return none, none, 0, spacing
    cc, rr = (np.floor(v.ravel()) + 0.5 for v in np.meshgrid(cols, rows))
    pc, pr = coarse.predict(cc, rr)
    px, py, _ = predicted_positions(scene, camera, surface, ref, cc, rr, f * (w - 1) / 2, w, float(f),
                                    coarse.predict if coarse.field is not None else None)
    templates = sampled(ref, scale, f, px, py)
    # the search area's upper-left level pixel: centred on the predicted position's level pixel, moved
    # inside the image where it would leave it (a peak on its edge is then rejected as on the border)
    sc = np.rint((cc + pc) / f - 0.5).astype(int) - (s - 1) // 2
    sr = np.rint((rr + pr) / f - 0.5).astype(int) - (s - 1) // 2
    inside = (sc > -s + w) & (sr > -s + w) & (sc < raw.shape[1] - w) & (sr < raw.shape[0] - w)
    sc, sr = np.clip(sc, 0, raw.shape[1] - s), np.clip(sr, 0, raw.shape[0] - s)
    usable = inside & np.isfinite(templates).all(axis=(1, 2))
    if not usable.any():
        return none, none, int(cc.size), spacing
    k = np.arange(s)
    search = raw[sr[usable, None, None] + k[None, :, None], sc[usable, None, None] + k[None, None, :]]
    t = templates[usable]
    ok = np.isfinite(search).all(axis=(1, 2)) & (t.std(axis=(1, 2)) > min_texture)
    ok &= np.nan_to_num(search).std(axis=(1, 2)) > min_texture
    c = ncc(t, np.nan_to_num(search))
    p = find_peaks(c, 2, local=True)
    ok &= (p.value >= LEVEL_MIN_PEAK) & ~p.border & (p.ratio <= max_peak_ratio)
    # the template's centre pixel (w-1)/2 meets level pixel sc + dx + (w-1)/2, base position (that + 0.5) f
    mc = (sc[usable] + p.dx + (w - 1) / 2 + 0.5) * f
    mr = (sr[usable] + p.dy + (w - 1) / 2 + 0.5) * f
    xy = np.stack([cc[usable], rr[usable]], axis=1)[ok]
    d = np.stack([mc - cc[usable], mr - rr[usable]], axis=1)[ok]
    keep = agreeing(xy, d, 2.0 * f + 2.0)
    return xy[keep], d[keep], int(cc.size), spacing


def agreeing(xy: np.ndarray, d: np.ndarray, tolerance: float) -> np.ndarray:
    """(m,) the offsets d (m, 2) within ``tolerance`` px of the median of their NEIGHBOURS nearest
    others' (all of them when there are too few to tell)."""
    if len(xy) <= NEIGHBOURS:
        return np.ones(len(xy), bool)
    _, near = cKDTree(xy).query(xy, NEIGHBOURS + 1)
    median = np.median(d[near[:, 1:]], axis=1)
    return np.hypot(*(d - median).T) <= tolerance
