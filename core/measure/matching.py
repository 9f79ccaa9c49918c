"""Automatic ground control points: the raw image matched against a reference orthoimage
through the scene model (the approach of seed 000, Zheng et al. 2015).

For each point p0 (col, row; GDAL pixel centres) of a grid over the raw image:

1. **Prediction.** The onboard model maps the pixels of a window around p0 to the ground
   (rays on the DEM) and the reference is sampled there: the *predicted chip*, the
   reference resampled into the raw image's geometry. The map raw -> reference pixel is exact
   at 3 x 3 nodes of each window and interpolated between them by biquadratic Lagrange
   polynomials (the map is smooth over a window; the error is far below 0.01 px).
2. **Coarse pass.** Onboard errors of hundreds of metres are found first at low resolution:
   a few large chips (raw image block-averaged by a factor f, reference smoothed alike) are
   correlated over the whole search range, and a plane offset(col, row) is fitted to the
   consistent matches. Too few consistent matches is an error that names the search range.
3. **Fine pass.** Each predicted chip (``window`` px) is correlated with the raw image over
   +-``fine_radius`` px around the coarse prediction: normalised cross-correlation computed
   by FFT (scipy.fft, vectorised over a batch of chips; local sums by integral images), the
   peak refined to sub-pixel by a least-squares paraboloid on its 3 x 3 neighbourhood.
4. **Rejection.** A point is rejected, with its reason counted, when a chip it compares would
   straddle a CCD seam (its predicted window, the raw search area where the coarse pass puts the
   match, or for tie points the other camera's window: the chips on either side of a seam look at
   different ground along track, so such a chip mixes two views and its match is biased by up to
   a pixel), its window leaves the image or the reference, its ray misses the DEM, the raw chip has too little texture
   (standard deviation < ``min_texture`` DN), the correlation peak is low (< ``min_correlation``:
   clouds, changed land cover, water), ambiguous (second peak / first peak > ``max_peak_ratio``)
   or on the border of the search area, or its offset disagrees with its neighbours' on the same
   chip by a pixel or more (:func:`core.measure.matchchecks.inconsistent`).

Tie points (:mod:`core.measure.tiematching`) use the same machinery (:func:`match_grid`) with
another raw image as the reference (ground -> its image through its scene model): the images are
compared in the base image's geometry, so different view angles do not defeat the correlation.

A match says: the ground point G0 the onboard model sees at p0 (on the DEM) is seen in the
raw image at p0 + d. So the GCP is ground G0 (lon, lat, ellipsoidal h) at image p0 + d.
Its sigma (px) follows least-squares matching precision: sigma^2 = (1 - rho) / sum(g'^2) per
axis, g the raw chip in standard units, rho the correlation (floor SIGMA_FLOOR).
"""
from __future__ import annotations

import logging
import math
import os
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from scipy.ndimage import gaussian_filter

from ..errors import Cancelled, InputError
from ..geodesy import ecef_to_geodetic
from ..model.sensor import SceneModel
from ..observations.gcps import GcpTable
from ..products.rawimage import RawImage
from .correlation import Peaks, block_mean, find_peaks, ncc, sample
from .matchchecks import inconsistent, within_one_chip
from .reference import MEMORY_BUDGET, Reference, check_overlap, open_checked

log = logging.getLogger(__name__)

INCONSISTENT = "inconsistent with its neighbours"
REASONS = ("near a CCD seam", "outside the image", "off the DEM", "outside the reference", "low texture",
           "low correlation", "ambiguous peak", "peak on the search border", INCONSISTENT)
COARSE_TEMPLATE = 64      # coarse chip size (coarse px)
COARSE_RADIUS = 40        # coarse search radius (coarse px): sets the block-averaging factor
COARSE_GRID = 5           # coarse chips per side
MIN_CONSISTENT = 3        # coarse matches that must agree
SIGMA_FLOOR = 0.08        # px per axis: the error floor bench_matchgcps.py measures (RMSE 0.081 px per axis of the
                          # matches within 1 px of the truth: spline sampling, peak fit), unseen by the formula


@dataclass(frozen=True)
class MatchSettings:
    """spacing (px between grid points; count > 0 overrides it with about that many points),
    window (px, odd), min_correlation, max_peak_ratio, min_texture (DN), search (m: largest
    onboard error looked for), fine_radius (px around the coarse prediction), batch (chips
    per FFT batch), workers (threads; 0 = all cores), sigma_xy / sigma_z (m, ground sigmas
    written to the GCPs; sigma_xy None = half a reference pixel)."""
    spacing: float = 200.0
    count: int = 0
    window: int = 31
    min_correlation: float = 0.6
    max_peak_ratio: float = 0.85
    min_texture: float = 2.0
    search: float = 1000.0
    fine_radius: int = 8
    batch: int = 256
    workers: int = 0
    sigma_xy: float | None = None
    sigma_z: float = 5.0

    def validate(self) -> None:
        checks = {"spacing": self.spacing >= 8 or self.count > 0, "count": 0 <= self.count <= 10_000_000,
                  "window": 9 <= self.window <= 257 and self.window % 2 == 1,
                  "min_correlation": 0 < self.min_correlation < 1, "max_peak_ratio": 0 < self.max_peak_ratio <= 1,
                  "min_texture": self.min_texture >= 0, "search": 0 < self.search <= 50_000,
                  "fine_radius": 2 <= self.fine_radius <= 64, "batch": self.batch >= 1,
                  "workers": self.workers >= 0, "sigma_xy": self.sigma_xy is None or self.sigma_xy >= 0,
                  "sigma_z": self.sigma_z >= 0}
        bad = [k for k, ok in checks.items() if not ok]
        if bad:
            raise InputError(f"matching settings out of range: {', '.join(f'{k}={getattr(self, k)}' for k in bad)} "
                             "(window odd 9-257 px, spacing >= 8 px, correlation in (0, 1), search 0-50 km, "
                             "fine radius 2-64 px)")


@dataclass
class MatchResult:
    """The matched GCPs and how they were found. table: the GCPs that passed; quality: their
    correlation peak (n,); peak_ratio (n,); offset (n, 2) px matched minus p0 (col, row);
    rejected: {reason: count} over all grid points; coarse: the coarse pass (offset plane
    coefficients in px, number of consistent chips, factor); seconds: matching wall time."""
    table: GcpTable
    quality: np.ndarray
    peak_ratio: np.ndarray
    offset: np.ndarray
    grid_points: int
    rejected: dict
    coarse: dict = field(default_factory=dict)
    seconds: float = 0.0


# --- geometry ------------------------------------------------------------------------------------
_LAGRANGE = lambda t: np.stack([t * (t - 1) / 2, 1 - t * t, t * (t + 1) / 2], axis=-1)  # noqa: E731


def predicted_positions(scene: SceneModel, camera: int, dem, ref: Reference, col: np.ndarray, row: np.ndarray,
                        half: float, size: int, step: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Reference array positions (x, y), each (n, size, size), of the raw pixels
    p0 + step * (k - (size-1)/2), k = 0..size-1 (rows then cols) around the n points (col, row),
    through ``scene`` on ``dem``; and the ECEF ground (n, 3) of the points themselves. The map is
    exact at 3 x 3 nodes spaced ``half`` px and biquadratic between. NaN where a ray misses."""
    n = col.size
    d = np.array([-half, 0.0, half])
    nc = (col[:, None, None] + d[None, None, :]) + 0 * d[None, :, None]
    nr = (row[:, None, None] + d[None, :, None]) + 0 * d[None, None, :]
    ground = scene.image_to_ground_dem(nc.ravel(), nr.ravel(), dem, camera)
    x, y = (v.reshape(n, 3, 3) for v in ref.ground_pixel(ground))
    w = _LAGRANGE(step * (np.arange(size) - (size - 1) / 2) / half)  # (size, 3)
    px = np.einsum("ia,jb,nab->nij", w, w, x)
    py = np.einsum("ia,jb,nab->nij", w, w, y)
    return px, py, ground.reshape(n, 9, 3)[:, 4]


# --- the grid ------------------------------------------------------------------------------------
def grid_points(cam, settings: MatchSettings, margin: int) -> tuple[np.ndarray, np.ndarray, int]:
    """Pixel centres (col, row) of the grid whose windows (+ ``margin``) lie inside one CCD chip
    and the image rows; and the number of grid points dropped near CCD seams."""
    spacing = settings.spacing
    if settings.count > 0:
        spacing = max(math.sqrt(cam.cols * cam.rows / settings.count), 8.0)
    cols = np.arange(margin + spacing / 2, cam.cols - margin, spacing)
    rows = np.arange(margin + spacing / 2, cam.rows - margin, spacing)
    cc, rr = np.meshgrid(np.floor(cols) + 0.5, np.floor(rows) + 0.5)
    cc, rr = cc.ravel(), rr.ravel()
    inside = np.zeros(cc.size, bool)
    for k in range(len(cam.chips)):
        start, end = cam.chip_range(k)
        inside |= (cc - margin >= start) & (cc + margin <= end)
    return cc[inside], rr[inside], int((~inside).sum())


# --- coarse pass ---------------------------------------------------------------------------------
def coarse_offsets(scene: SceneModel, camera: int, dem, ref: Reference, raw: RawImage, gsd: float,
                   settings: MatchSettings) -> dict:
    """The offset plane (raw px) d(col, row) = a + b (col - c0) / cols + e (row - r0) / rows from
    block-averaged chips correlated over the whole search range. InputError when too few
    chips agree: the reference does not show the scene's ground, or the error exceeds the range."""
    cam = scene.cameras[camera]
    radius_px = settings.search / gsd
    f = max(1, int(math.ceil(radius_px / COARSE_RADIUS)))
    r = int(math.ceil(radius_px / f)) + 2
    t = COARSE_TEMPLATE
    span = f * (t + 2 * r)
    if span > min(cam.cols, cam.rows):
        raise InputError(f"search range {settings.search:g} m needs {span} px chips, more than the image "
                         f"({cam.cols} x {cam.rows} px): choose a smaller search range")
    half = span / 2
    c0 = np.linspace(half, cam.cols - half, COARSE_GRID)
    r0 = np.linspace(half, cam.rows - half, COARSE_GRID)
    cc, rr = (np.floor(v.ravel()) + 0.5 for v in np.meshgrid(c0, r0))
    px, py, _ = predicted_positions(scene, camera, dem, ref, cc, rr, f * t / 2, t, f)
    smooth = 0.5 * f * gsd / ref.gsd
    templates, searches = [], []
    for k in range(cc.size):
        finite = np.isfinite(px[k])
        if not finite.all():
            templates.append(None)
            searches.append(None)
            continue
        win, wx, wy = ref.float_window(px[k], py[k], 4)
        templates.append(sample(gaussian_filter(win, smooth) if smooth > 0.3 else win, wx, wy, px[k], py[k]))
        sx, sy = int(np.floor(cc[k] - half)), int(np.floor(rr[k] - half))
        searches.append(block_mean(raw.window(sy, sy + span, sx, sx + span)[0].astype(np.float32), f))
    usable = [k for k in range(cc.size) if templates[k] is not None and np.isfinite(templates[k]).all()
              and np.std(templates[k]) > settings.min_texture and np.std(searches[k]) > settings.min_texture]
    if not usable:
        raise InputError(f"reference {ref.path}: it does not cover the scene's ground where the onboard model "
                         "puts it (or shows no texture there): check that it overlaps the scene")
    c = ncc(np.stack([templates[k] for k in usable]), np.stack([searches[k] for k in usable]))
    peaks = find_peaks(c, 4)
    good = (peaks.value > 0.5) & (peaks.ratio < settings.max_peak_ratio) & ~peaks.border
    # offset (raw px) of the raw chip from the prediction: template pixel k (centre p0 + f (k - (t-1)/2))
    # meets coarse search pixel k + d, whose centre is origin + f (k + d + 1/2)
    cu, ru = cc[usable], rr[usable]
    dx = np.floor(cu - half) + f * (peaks.dx + t / 2) - cu
    dy = np.floor(ru - half) + f * (peaks.dy + t / 2) - ru
    consistent = good.copy()
    if good.sum() >= MIN_CONSISTENT:
        mx, my = np.median(dx[good]), np.median(dy[good])
        consistent &= np.hypot(dx - mx, dy - my) <= 2.0 * f + 4.0
    n_ok = int(consistent.sum())
    log.info("coarse pass: factor %d, %d chips, %d usable, %d good, %d consistent", f, cc.size, len(usable),
             int(good.sum()), n_ok)
    if n_ok < MIN_CONSISTENT:
        on_border = int(peaks.border.sum())
        raise InputError(
            f"no consistent match between the image and reference {ref.path} within the search range "
            f"(+-{settings.search:g} m): {n_ok} of {len(usable)} coarse chips agree ({on_border} peak on the border "
            "of the search area). Either the onboard model is farther off than the search range (increase the "
            "search range, e.g. to twice the expected onboard error), or the reference does not show the same "
            "ground (check its overlap, date and CRS)")
    a = np.stack([np.ones(n_ok), (cu[consistent] - cam.cols / 2) / cam.cols,
                  (ru[consistent] - cam.rows / 2) / cam.rows], axis=1)
    coef_x = np.linalg.lstsq(a if n_ok >= 4 else a[:, :1], dx[consistent], rcond=None)[0]
    coef_y = np.linalg.lstsq(a if n_ok >= 4 else a[:, :1], dy[consistent], rcond=None)[0]
    pad = np.zeros(3 - coef_x.size)
    return {"factor": f, "chips": int(cc.size), "consistent": n_ok, "col_plane_px": np.r_[coef_x, pad].tolist(),
            "row_plane_px": np.r_[coef_y, pad].tolist(),
            "spread_px": float(np.max(np.hypot(dx[consistent] - np.median(dx[consistent]),
                                               dy[consistent] - np.median(dy[consistent])))) if n_ok else 0.0}


def _plane(coarse: dict, cam, col: np.ndarray, row: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    u, v = (col - cam.cols / 2) / cam.cols, (row - cam.rows / 2) / cam.rows
    a, b = np.array(coarse["col_plane_px"]), np.array(coarse["row_plane_px"])
    return a[0] + a[1] * u + a[2] * v, b[0] + b[1] * u + b[2] * v


# --- fine pass -----------------------------------------------------------------------------------
def _fine_batch(px, py, col, row, shift_c, shift_r, ref: Reference, raw: RawImage, nodata,
                settings: MatchSettings, workers: int) -> dict:
    """Match one batch: reference chips (b, w, w) sampled at (px, py) against raw search areas
    centred on (col, row) + integer shifts. Returns per-chip offsets, peaks and reasons."""
    w, r = settings.window, settings.fine_radius
    s = w + 2 * r
    b = col.size
    win, wx, wy = ref.window(px, py, 3)
    templates = sample(win, wx, wy, px, py, ref.nodata)
    # raw search areas: upper-left pixel index of each
    sc = (np.floor(col) + shift_c - (s - 1) / 2).astype(int)
    sr = (np.floor(row) + shift_r - (s - 1) / 2).astype(int)
    outside = (sc < 0) | (sr < 0) | (sc + s > raw.cols) | (sr + s > raw.rows)
    scc, src = np.clip(sc, 0, raw.cols - s), np.clip(sr, 0, raw.rows - s)
    bx0, by0 = int(scc.min()), int(src.min())
    block = raw.window(by0, int(src.max()) + s, bx0, int(scc.max()) + s)[0]
    k = np.arange(s)
    search = block[(src - by0)[:, None, None] + k[None, :, None], (scc - bx0)[:, None, None] + k[None, None, :]]
    search = search.astype(np.float32)
    if nodata is not None:
        outside |= (search == nodata).any(axis=(1, 2))
    no_ref = ~np.isfinite(templates).all(axis=(1, 2))
    templates = np.where(np.isfinite(templates), templates, 0.0)
    centre = search[:, r:r + w, r:r + w]
    texture = np.minimum(centre.std(axis=(1, 2)), templates.std(axis=(1, 2)))
    c = ncc(templates, search, workers)
    p = find_peaks(c, 4)
    # matched image position of the template centre
    mc = scc + p.dx + (w - 1) / 2 + 0.5
    mr = src + p.dy + (w - 1) / 2 + 0.5
    top = np.clip(np.rint(p.dy).astype(int), 0, 2 * r)[:, None, None]
    left = np.clip(np.rint(p.dx).astype(int), 0, 2 * r)[:, None, None]
    g = search[np.arange(b)[:, None, None], top + k[None, :w, None], left + k[None, None, :w]]
    g = (g - g.mean(axis=(1, 2), keepdims=True)) / np.maximum(g.std(axis=(1, 2), keepdims=True), 1e-6)
    gy, gx = np.gradient(g, axis=(1, 2))
    rho = np.clip(p.value, 1e-3, 1.0)
    sig = np.sqrt(0.5 * ((1 - rho) / np.maximum((gx * gx).sum(axis=(1, 2)), 1e-9)
                         + (1 - rho) / np.maximum((gy * gy).sum(axis=(1, 2)), 1e-9)))
    return {"col": mc, "row": mr, "value": p.value, "ratio": p.ratio, "sigma": np.maximum(sig, SIGMA_FLOOR),
            "reasons": _reasons(outside, no_ref, texture, p, settings)}


def _reasons(outside, no_ref, texture, p: Peaks, settings: MatchSettings) -> np.ndarray:
    """Index into REASONS of each chip's first failed test; -1 for a match that passes."""
    tests = [(1, outside), (3, no_ref), (4, texture < settings.min_texture), (5, p.value < settings.min_correlation),
             (6, p.ratio > settings.max_peak_ratio), (7, p.border)]
    reason = np.full(outside.size, -1)
    for index, failed in reversed(tests):
        reason = np.where(failed, index, reason)
    return reason


@dataclass
class GridMatch:
    """Per grid point (n,): its position (col, row), the matched position, correlation, peak
    ratio, sigma, the reference position matching the grid point itself (ref_col, ref_row: GDAL
    px of the reference's array; the local affine map applied to the match's offset), the ECEF
    ground (n, 3) of the grid point and the reason index (-1: passed); near_seam: the grid points
    left out before matching because their own window straddles a CCD seam."""
    col: np.ndarray
    row: np.ndarray
    out: dict
    ground: np.ndarray
    reasons: np.ndarray
    near_seam: int
    coarse: dict
    seconds: float

    def rejected(self) -> dict:
        return {REASONS[0]: self.near_seam + int((self.reasons == 0).sum()),
                **{REASONS[i]: int((self.reasons == i).sum()) for i in range(1, len(REASONS))}}


def match_grid(scene: SceneModel, camera: int, image_path, ref: Reference, dem, gsd: float,
                settings: MatchSettings, report, cancelled) -> GridMatch:
    """Match the grid of camera ``camera``'s raw image against ``ref`` (coarse, then fine pass)."""
    cam = scene.cameras[camera]
    src, nodata = open_checked(scene, camera, image_path)
    report(0.01, "reading the images")
    raw = RawImage(image_path, src, MEMORY_BUDGET)
    # Closed at once: a dataset that an error's traceback keeps alive is destroyed after GDAL at
    # the interpreter's exit, which crashes it (a refused block ended Python with SIGSEGV).
    src = None
    start = time.perf_counter()
    report(0.02, "coarse pass: looking for the onboard model's offset")
    coarse = coarse_offsets(scene, camera, dem, ref, raw, gsd, settings)
    log.info("coarse offset plane: col %s, row %s px", coarse["col_plane_px"], coarse["row_plane_px"])
    half = (settings.window - 1) / 2
    h = int(half)
    col, row, near_seam = grid_points(cam, settings, int(half + settings.fine_radius + 1))
    if col.size == 0:
        raise InputError(f"no grid point fits in the image ({cam.cols} x {cam.rows} px) with window "
                         f"{settings.window} px and spacing {settings.spacing:g} px")
    shift_c, shift_r = (np.rint(v).astype(int) for v in _plane(coarse, cam, col, row))
    # The raw search area sits where the coarse pass predicts the match (tens of pixels from the
    # grid point): it too must lie in one chip, or the matched chip mixes two chips' views.
    s = settings.window + 2 * settings.fine_radius
    first = np.floor(col) + shift_c - (s - 1) // 2
    straddles = ~within_one_chip(cam, first, first + s - 1)
    reasons = np.full(col.size, 2)
    reasons[straddles] = 0
    order = np.argsort(np.floor(row / (settings.spacing * 8)) * cam.cols + col, kind="stable")
    order = order[~straddles[order]]
    batches = [order[i:i + settings.batch] for i in range(0, order.size, settings.batch)]
    workers = settings.workers or os.cpu_count() or 1
    out = {k: np.full(col.size, np.nan) for k in ("col", "row", "value", "ratio", "sigma", "ref_col", "ref_row")}
    ground = np.full((col.size, 3), np.nan)

    def run(idx: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict, np.ndarray]:
        """Predict and match one batch of grid points (indices idx); also the indices whose
        reference window straddles a seam of the other camera (tie points)."""
        if cancelled():
            raise Cancelled("matching cancelled by the user")
        px, py, g = predicted_positions(scene, camera, dem, ref, col[idx], row[idx], half, settings.window, 1.0)
        ok = np.isfinite(g).all(axis=1) & np.isfinite(px).all(axis=(1, 2)) & np.isfinite(py).all(axis=(1, 2))
        seam = np.zeros_like(ok)
        seam[ok] = ref.straddles_seam(px[ok])
        ok &= ~seam
        if not ok.any():
            return idx[:0], g[:0], {}, idx[seam]
        seam_idx = idx[seam]
        px, py, idx = px[ok], py[ok], idx[ok]
        res = _fine_batch(px, py, col[idx], row[idx], shift_c[idx], shift_r[idx], ref, raw, nodata, settings, 1)
        # the reference position of the grid point's own match: centre minus the local map of the offset
        dc, dr = res["col"] - col[idx], res["row"] - row[idx]
        jx = ((px[:, h, h + 1] - px[:, h, h - 1]) / 2, (px[:, h + 1, h] - px[:, h - 1, h]) / 2)
        jy = ((py[:, h, h + 1] - py[:, h, h - 1]) / 2, (py[:, h + 1, h] - py[:, h - 1, h]) / 2)
        res["ref_col"] = px[:, h, h] + 0.5 - jx[0] * dc - jx[1] * dr
        res["ref_row"] = py[:, h, h] + 0.5 - jy[0] * dc - jy[1] * dr
        return idx, g[ok], res, seam_idx

    with ThreadPoolExecutor(max_workers=workers) as pool:
        for n, (idx, g, res, seam_idx) in enumerate(pool.map(run, batches)):
            reasons[seam_idx] = 0
            if idx.size:
                for k in out:
                    out[k][idx] = res[k]
                reasons[idx], ground[idx] = res["reasons"], g
            report(0.1 + 0.85 * (n + 1) / len(batches), None)
    reasons[inconsistent(cam, col, row, out["col"], out["row"], reasons < 0)] = REASONS.index(INCONSISTENT)
    return GridMatch(col, row, out, ground, reasons, near_seam, coarse, time.perf_counter() - start)


def match_gcps(scene: SceneModel, camera: int, image_path, reference_path, dem,
               settings: MatchSettings = MatchSettings(),
               progress: Callable[[float, str | None], None] | None = None,
               is_cancelled: Callable[[], bool] | None = None) -> MatchResult:
    """Ground control points for camera ``camera`` of ``scene`` by matching its raw image
    (``image_path``) against a reference orthoimage over ``dem`` (core.dem.Dem or
    ConstantHeight; heights of the GCPs come from it). See the module docstring."""
    settings.validate()
    report = progress or (lambda fraction, message=None: None)
    cancelled = is_cancelled or (lambda: False)
    cam = scene.cameras[camera]
    ref = Reference(reference_path)
    gsd = float(scene.info.get("gsd_m") or ground_sample_distance(scene, camera, dem))
    check_overlap(scene, camera, dem, ref, settings.search)
    m = match_grid(scene, camera, image_path, ref, dem, gsd, settings, report, cancelled)
    ok = m.reasons < 0
    rejected = m.rejected()
    n, total = int(ok.sum()), int(m.col.size + m.near_seam)
    if n == 0:
        raise InputError(f"no point of {total} matched: " + reason_text(rejected) +
                         ". Lower the quality threshold, enlarge the window, or check the reference")
    lon, lat, h = ecef_to_geodetic(m.ground[ok])
    table = GcpTable(id=np.char.add("M", (np.nonzero(ok)[0] + 1).astype(str)), role="control", camera=cam.name,
                     col=m.out["col"][ok], row=m.out["row"][ok], lon=lon, lat=lat, h=h, sigma_px=m.out["sigma"][ok],
                     sigma_xy=0.5 * ref.gsd if settings.sigma_xy is None else settings.sigma_xy,
                     sigma_z=settings.sigma_z)
    log.info("matched %d of %d grid points in %.2f s; rejected: %s", n, total, m.seconds, reason_text(rejected))
    return MatchResult(table, m.out["value"][ok], m.out["ratio"][ok],
                       np.stack([m.out["col"][ok] - m.col[ok], m.out["row"][ok] - m.row[ok]], axis=1),
                       total, rejected, m.coarse, m.seconds)


def reason_text(rejected: dict) -> str:
    """Rejection counts {reason: n} in words ('none rejected' without any)."""
    return ", ".join(f"{v} {k}" for k, v in rejected.items() if v) or "none rejected"


def ground_sample_distance(scene: SceneModel, camera: int, dem) -> float:
    """Ground distance (m) between two neighbouring pixels at the image centre."""
    cam = scene.cameras[camera]
    g = scene.image_to_ground_dem(np.array([cam.cols / 2, cam.cols / 2 + 1]), np.array([cam.rows / 2] * 2), dem,
                                  camera)
    return float(np.linalg.norm(g[1] - g[0]))
