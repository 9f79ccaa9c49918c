"""Automatic ground control points: the raw image matched against a reference orthoimage
through the scene model (the approach of seed 000, Zheng et al. 2015), and the grid matching that
tie points share (:mod:`core.measure.tiematching`).

For each point p0 (col, row; GDAL pixel centres) of a grid over the raw image:

1. **Prediction.** The onboard model maps the pixels of a window around p0 to the ground (rays on
   the terrain surface: the DEM, its holes filled at the terrain's median height,
   :mod:`core.measure.surface`) and the reference is sampled there: the *predicted chip*, the
   reference resampled into the raw image's geometry, a frame in which view angles, scales and
   the relief the surface holds no longer differ (:mod:`core.measure.prediction`).
2. **Coarse to fine** (:mod:`core.measure.pyramid`). The onboard models' offset is found over an
   image pyramid: the whole image block-averaged, correlated over the whole search range (clipped
   to the image), then local chips at finer levels, each searched a few level pixels around what
   its neighbours found, so the offset follows the parallax of relief the surface lacks.
3. **Fine pass** (:mod:`core.measure.finepass`). Each predicted chip (``window`` px) is correlated
   with the raw image over +-``fine_radius`` px around the offset predicted for it (normalised
   cross-correlation by FFT, vectorised over a batch of chips), refined by least-squares matching
   with gain and offset (Gruen 1985) and checked backward (raw chip -> reference).
4. **Rejection.** A point is rejected, with its reason counted, when a chip it compares would
   straddle a CCD seam (its predicted window, the raw search area where the coarse pass puts the
   match, or for tie points the other camera's window: the chips on either side of a seam look at
   different ground along track, so such a chip mixes two views and its match is biased by up to
   a pixel), its window leaves the image or the reference, its ray misses the surface, the DEM has
   no height under a GCP, the raw chip has too little texture (standard deviation <
   ``min_texture`` DN), the correlation peak is low (< ``min_correlation``: clouds, changed land
   cover, water), ambiguous (second peak / first peak > ``max_peak_ratio``) or on the border of
   the search area, the least-squares fit fails, the backward match disagrees, or its offset
   disagrees with its neighbours' on the same chip by a pixel or more
   (:func:`core.measure.matchchecks.inconsistent`).

A match says: the ground point G0 the onboard model sees at p0 (on the DEM) is seen in the raw
image at p0 + d. So the GCP is ground G0 (lon, lat, ellipsoidal h) at image p0 + d. Its sigma (px)
is the least-squares fit's (sigma0^2 (N^-1) per axis, floor SIGMA_FLOOR).
"""
from __future__ import annotations

import logging
import math
import os
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

from ..errors import Cancelled, InputError
from ..geodesy import ecef_to_geodetic
from ..model.sensor import SceneModel
from ..observations.gcps import GcpTable
from ..products.rawimage import RawImage
from .finepass import BACKWARD_RADIUS, fine_batch
from .matchchecks import inconsistent, within_one_chip
from .prediction import predicted_positions
from .pyramid import NEIGHBOURS, CoarseOffsets, coarse_offsets, raw_levels
from .reference import MEMORY_BUDGET, Reference, check_overlap, open_checked
from .surface import FilledSurface, filled_surface

log = logging.getLogger(__name__)

INCONSISTENT = "inconsistent with its neighbours"
NO_DEM_HEIGHT = "no DEM height"
FIT_FAILED, BACKWARD = "least-squares fit failed", "backward match disagrees"
REASONS = ("near a CCD seam", "outside the image", "off the DEM", "outside the reference", "low texture",
           "low correlation", "ambiguous peak", "peak on the search border", INCONSISTENT, NO_DEM_HEIGHT,
           FIT_FAILED, BACKWARD)
# the reasons a better predicted offset may overcome: matched once more around the matched neighbours'
RETRIED = ("ambiguous peak", "peak on the search border", INCONSISTENT, FIT_FAILED, BACKWARD)


@dataclass(frozen=True)
class MatchSettings:
    """spacing (px between grid points; count > 0 overrides it with about that many points),
    window (px, odd), min_correlation, max_peak_ratio, min_texture (DN), search (m: largest
    onboard error looked for; clipped to the image), fine_radius (px searched around the offset
    the pyramid predicts), batch (chips per FFT batch), workers (threads; 0 = all cores),
    sigma_xy / sigma_z (m, ground sigmas written to the GCPs; sigma_xy None = half a reference
    pixel)."""
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
    rejected: {reason: count} over all grid points; coarse: the coarse-to-fine search
    (:meth:`core.measure.pyramid.CoarseOffsets.summary`); seconds: matching wall time."""
    table: GcpTable
    quality: np.ndarray
    peak_ratio: np.ndarray
    offset: np.ndarray
    grid_points: int
    rejected: dict
    coarse: dict = field(default_factory=dict)
    seconds: float = 0.0


# --- the grid ------------------------------------------------------------------------------------
def grid_spacing(cam, settings: MatchSettings) -> float:
    """The grid's spacing (px): SPACING, or for about N_POINTS points over the image when given."""
    if settings.count > 0:
        return max(math.sqrt(cam.cols * cam.rows / settings.count), 8.0)
    return settings.spacing


def grid_points(cam, settings: MatchSettings, margin: int) -> tuple[np.ndarray, np.ndarray, int]:
    """Pixel centres (col, row) of the grid whose windows (+ ``margin``) lie inside one CCD chip
    and the image rows; and the number of grid points dropped near CCD seams."""
    spacing = grid_spacing(cam, settings)
    cols = np.arange(margin + spacing / 2, cam.cols - margin, spacing)
    rows = np.arange(margin + spacing / 2, cam.rows - margin, spacing)
    cc, rr = np.meshgrid(np.floor(cols) + 0.5, np.floor(rows) + 0.5)
    cc, rr = cc.ravel(), rr.ravel()
    inside = np.zeros(cc.size, bool)
    for k in range(len(cam.chips)):
        start, end = cam.chip_range(k)
        inside |= (cc - margin >= start) & (cc + margin <= end)
    return cc[inside], rr[inside], int((~inside).sum())


@dataclass
class GridMatch:
    """Per grid point (n,): its position (col, row), the matched position, correlation, peak
    ratio, sigma, the reference position matching the grid point itself (ref_col, ref_row: GDAL
    px of the reference's array; the local affine map applied to the match's offset), the ECEF
    ground (n, 3) of the grid point and the reason index (-1: passed); near_seam: the grid points
    left out before matching because their own window straddles a CCD seam; in_hole: (n,) the grid
    points whose ground the DEM has no height under (matched at the estimated height); coarse: the
    pyramid's summary."""
    col: np.ndarray
    row: np.ndarray
    out: dict
    ground: np.ndarray
    reasons: np.ndarray
    near_seam: int
    in_hole: np.ndarray
    coarse: dict
    seconds: float

    def rejected(self) -> dict:
        return {REASONS[0]: self.near_seam + int((self.reasons == 0).sum()),
                **{REASONS[i]: int((self.reasons == i).sum()) for i in range(1, len(REASONS))}}


def match_grid(scene: SceneModel, camera: int, image_path, ref: Reference, surface: FilledSurface, gsd: float,
               settings: MatchSettings, report, cancelled) -> GridMatch:
    """Match the grid of camera ``camera``'s raw image against ``ref`` (coarse to fine, then the
    fine pass; see the module docstring). The grid points the fine pass rejects for their peak or
    its checks (RETRIED) are matched once more around the offsets their matched neighbours found
    (the plane of the nearest: on a pyramid's face or a hillside these predict a point's parallax
    to a fraction of a pixel where the coarse levels' chips, tens of metres wide, could not)."""
    cam = scene.cameras[camera]
    src, nodata = open_checked(scene, camera, image_path)
    report(0.01, "reading the images")
    raw = RawImage(image_path, src, MEMORY_BUDGET)
    # Closed at once: a dataset that an error's traceback keeps alive is destroyed after GDAL at
    # the interpreter's exit, which crashes it (a refused block ended Python with SIGSEGV).
    src = None
    start = time.perf_counter()
    report(0.02, "coarse to fine: looking for the onboard models' offsets")
    coarse = coarse_offsets(scene, camera, surface, ref, raw_levels(raw, nodata), gsd, settings.search,
                            grid_spacing(cam, settings), settings.min_texture, settings.max_peak_ratio)
    w = settings.window
    half = (w - 1) / 2 + BACKWARD_RADIUS
    h = int(half)
    col, row, near_seam = grid_points(cam, settings, int((w - 1) / 2 + settings.fine_radius + 1))
    if col.size == 0:
        raise InputError(f"no grid point fits in the image ({cam.cols} x {cam.rows} px) with window "
                         f"{settings.window} px and spacing {settings.spacing:g} px")
    workers = settings.workers or os.cpu_count() or 1
    out = {k: np.full(col.size, np.nan) for k in ("col", "row", "value", "ratio", "sigma", "gain", "ref_col",
                                                  "ref_row")}
    ground = np.full((col.size, 3), np.nan)
    reasons = np.full(col.size, 2)

    def run(idx: np.ndarray, field: CoarseOffsets) -> tuple[np.ndarray, np.ndarray, dict, np.ndarray]:
        """Predict (rectified at ``field``) and match one batch of grid points (indices idx); also
        the indices whose reference window straddles a seam of the other camera (tie points)."""
        if cancelled():
            raise Cancelled("matching cancelled by the user")
        px, py, g = predicted_positions(scene, camera, surface, ref, col[idx], row[idx], half, 2 * h + 1, 1.0,
                                        field.predict if field.field is not None else None)
        ok = np.isfinite(g).all(axis=1) & np.isfinite(px).all(axis=(1, 2)) & np.isfinite(py).all(axis=(1, 2))
        seam = np.zeros_like(ok)
        seam[ok] = ref.straddles_seam(px[ok])
        ok &= ~seam
        if not ok.any():
            return idx[:0], g[:0], {}, idx[seam]
        seam_idx = idx[seam]
        px, py, idx = px[ok], py[ok], idx[ok]
        shift_c, shift_r = (np.rint(v).astype(int) for v in field.predict(col[idx], row[idx]))
        res = fine_batch(px, py, col[idx], row[idx], shift_c, shift_r, ref, raw, nodata, settings, 1)
        # the reference position of the grid point's own match: centre minus the local map of the offset
        dc, dr = res["col"] - col[idx], res["row"] - row[idx]
        jx = ((px[:, h, h + 1] - px[:, h, h - 1]) / 2, (px[:, h + 1, h] - px[:, h - 1, h]) / 2)
        jy = ((py[:, h, h + 1] - py[:, h, h - 1]) / 2, (py[:, h + 1, h] - py[:, h - 1, h]) / 2)
        res["ref_col"] = px[:, h, h] + 0.5 - jx[0] * dc - jx[1] * dr
        res["ref_row"] = py[:, h, h] + 0.5 - jy[0] * dc - jy[1] * dr
        return idx, g[ok], res, seam_idx

    def match(todo: np.ndarray, field: CoarseOffsets, progress: tuple[float, float]) -> None:
        """Match the grid points ``todo`` (indices) in batches on the workers, the results into out,
        reasons and ground; their raw search areas (where ``field`` puts the match, tens of pixels
        from the grid point) must lie in one CCD chip too, or the matched chip mixes two views."""
        s = w + 2 * settings.fine_radius
        first = np.floor(col[todo]) + np.rint(field.predict(col[todo], row[todo])[0]) - (s - 1) // 2
        straddles = ~within_one_chip(cam, first, first + s - 1)
        reasons[todo[straddles]] = 0
        todo = todo[~straddles]
        order = todo[np.argsort(np.floor(row[todo] / (grid_spacing(cam, settings) * 8)) * cam.cols + col[todo],
                                kind="stable")]
        batches = [order[i:i + settings.batch] for i in range(0, order.size, settings.batch)]
        with ThreadPoolExecutor(max_workers=workers) as pool:
            for n, (idx, g, res, seam_idx) in enumerate(pool.map(lambda b: run(b, field), batches)):
                reasons[seam_idx] = 0
                if idx.size:
                    for k in out:
                        out[k][idx] = res[k]
                    reasons[idx], ground[idx] = res["reasons"], g
                report(progress[0] + (progress[1] - progress[0]) * (n + 1) / len(batches), None)
        reasons[inconsistent(cam, col, row, out["col"], out["row"], reasons < 0)] = REASONS.index(INCONSISTENT)

    match(np.arange(col.size), coarse, (0.1, 0.85))
    retry = np.nonzero(np.isin(reasons, [REASONS.index(r) for r in RETRIED]))[0]
    ok = reasons < 0
    if retry.size and ok.sum() > NEIGHBOURS:
        dense = replace(coarse)
        dense.set_field(np.stack([col[ok], row[ok]], axis=1),
                        np.stack([out["col"][ok] - col[ok], out["row"][ok] - row[ok]], axis=1), cam.cols, cam.rows,
                        grid_spacing(cam, settings) / 2)
        match(retry, dense, (0.85, 0.95))
        log.info("the fine pass again around the matched neighbours' offsets: %d of %d grid points rejected for "
                 "their peak or its checks matched now", int((reasons[retry] < 0).sum()), retry.size)
    return GridMatch(col, row, out, ground, reasons, near_seam, surface.in_hole(ground), coarse.summary(),
                     time.perf_counter() - start)


def match_gcps(scene: SceneModel, camera: int, image_path, reference_path, dem,
               settings: MatchSettings = MatchSettings(),
               progress: Callable[[float, str | None], None] | None = None,
               is_cancelled: Callable[[], bool] | None = None) -> MatchResult:
    """Ground control points for camera ``camera`` of ``scene`` by matching its raw image
    (``image_path``) against a reference orthoimage over ``dem`` (core.dem.Dem or
    ConstantHeight; heights of the GCPs come from it: grid points where it has none are rejected
    as 'no DEM height'). See the module docstring."""
    settings.validate()
    report = progress or (lambda fraction, message=None: None)
    cancelled = is_cancelled or (lambda: False)
    cam = scene.cameras[camera]
    ref = Reference(reference_path)
    surface = filled_surface(scene, camera, dem)
    gsd = float(scene.info.get("gsd_m") or ground_sample_distance(scene, camera, surface))
    check_overlap(scene, camera, surface, ref, settings.search)
    m = match_grid(scene, camera, image_path, ref, surface, gsd, settings, report, cancelled)
    if m.in_hole.any():
        log.info("%s: the reference was rectified there at the estimated height %.1f m, and the %d matches among "
                 "them rejected as '%s' (a GCP's height there would be a guess)",
                 surface.missing(m.ground, "grid points"), surface.estimate,
                 int(((m.reasons < 0) & m.in_hole).sum()), NO_DEM_HEIGHT)
    m.reasons[(m.reasons < 0) & m.in_hole] = REASONS.index(NO_DEM_HEIGHT)
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
