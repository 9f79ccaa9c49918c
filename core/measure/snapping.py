"""Snapping digitised image lines to the image feature: the centre of a bright or dark
road-like band, or an edge, located to sub-pixel with profiles across the line.

For every vertex of a digitised polyline, ``stations`` profiles are taken across the line
(perpendicular to the local direction, the chord through the neighbouring vertices) at
stations spaced ``station_step`` px along it, within ``reach`` px of the vertex (on the line's
side only at its ends). Each profile is sampled every ``sample_step`` px over +-``search`` px
with cubic-spline interpolation and the feature is found on it:

- ``centre``: the peak of the correlation with a zero-mean bar of the band's width (``width``
  px; bright band for ``polarity`` +1, dark for -1), refined by a parabola through its three
  samples;
- ``edge``: the peak of the gradient magnitude (after a Gaussian of one pixel), refined alike.

A straight line fitted to the feature positions across (weighted least squares on the
stations, one outlier rejection at 3 robust sigmas) gives the vertex's refined position
across the line and its own sigma: the fit's standard error at the vertex (stations closer
than the width counted as one), never below ``sigma_floor`` px (what the background texture
leaves on a rendered road: 0.09 px RMS in tests/unit/measure/test_snapping.py). Two passes: the
second with the refined directions and half the search.
A vertex with fewer than ``min_stations`` usable profiles, or whose fit is worse than
``max_sigma`` px (a junction, a CCD seam where the image of the road jumps, texture that
looks like the feature), keeps its position and sigma and is reported as not refined
(:func:`kept_reasons` counts which). Lines with vertices outside the image are refused.
Pixel coordinates are GDAL's (col, row; pixel centres at +0.5).
All profiles of a line are computed at once (arrays (vertices, stations, samples)).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import numpy as np
from osgeo import gdal
from scipy import ndimage

from ..errors import InputError
from ..observations.lines import ImageLines
from ..rasters import open_input_raster

gdal.UseExceptions()
log = logging.getLogger(__name__)


MODES = ("centre", "edge")


@dataclass(frozen=True)
class SnapSettings:
    """See the module docstring; lengths in px."""
    mode: str = "centre"
    width: float = 3.0
    polarity: int = 1
    search: float = 10.0
    reach: float = 6.0
    station_step: float = 1.0
    sample_step: float = 0.25
    sigma_floor: float = 0.1
    min_stations: int = 4
    max_sigma: float = 0.5

    def validate(self) -> None:
        if self.mode not in MODES:
            raise InputError(f"snapping mode must be 'centre' or 'edge' (got {self.mode!r})")
        if self.polarity not in (1, -1):
            raise InputError(f"polarity must be 1 (bright feature) or -1 (dark) (got {self.polarity})")
        if not (0 < self.width < self.search * 2 and self.search > 0 and self.reach >= 0 and self.station_step > 0
                and 0 < self.sample_step <= 0.5 and 0 < self.sigma_floor < self.max_sigma and self.min_stations >= 2):
            raise InputError("snapping settings: need 0 < width < 2 * search, reach >= 0, station_step > 0, "
                             "0 < sample_step <= 0.5, 0 < sigma_floor < max_sigma and min_stations >= 2")


@dataclass
class SnapResult:
    """lines: the refined image lines (col, row, sigma_px per vertex); refined (V,) bool:
    vertices moved to the feature (the others are unchanged); moved (V,) px: how far each
    vertex moved; stations (V,): profiles used per vertex (for a vertex not refined, the
    usable profiles of the last pass)."""
    lines: ImageLines
    refined: np.ndarray
    moved: np.ndarray
    stations: np.ndarray


def snap_lines(image, lines: ImageLines, settings: SnapSettings = SnapSettings(), band: int = 1) -> SnapResult:
    """Snap every image line of ``lines`` to the feature of ``image`` (a raster path, read a
    window per line, or a 2-D array of the whole image)."""
    settings.validate()
    ds = open_input_raster(image) if not isinstance(image, np.ndarray) else None
    shape = (ds.RasterYSize, ds.RasterXSize) if ds is not None else image.shape
    _require_inside(lines, shape, str(image) if ds is not None else "the image")
    col, row, sigma = lines.col.copy(), lines.row.copy(), lines.sigma_px.copy()
    refined = np.zeros(col.size, bool)
    stations = np.zeros(col.size, np.int64)
    margin = int(np.ceil(settings.search + settings.reach + settings.width + 4))
    blank = 0
    for i in range(len(lines)):  # one window read per line; the profiles of a line are vectorised
        sl = slice(lines.start[i], lines.start[i + 1])
        c0 = max(int(np.floor(col[sl].min())) - margin, 0)
        r0 = max(int(np.floor(row[sl].min())) - margin, 0)
        c1 = min(int(np.ceil(col[sl].max())) + margin, shape[1])
        r1 = min(int(np.ceil(row[sl].max())) + margin, shape[0])
        if c1 - c0 < 4 or r1 - r0 < 4:
            continue
        window = (ds.GetRasterBand(band).ReadAsArray(c0, r0, c1 - c0, r1 - r0) if ds is not None
                  else image[r0:r1, c0:c1]).astype(float)
        if np.ptp(window) == 0:
            blank += 1
            continue
        out = snap_polyline(window, col[sl] - c0, row[sl] - r0, sigma[sl], settings)
        col[sl], row[sl], sigma[sl], refined[sl], stations[sl] = out[0] + c0, out[1] + r0, out[2], out[3], out[4]
    if len(lines) and blank == len(lines):
        raise InputError(f"{image if ds is not None else 'the image'} is blank (one value) under every line: "
                         "nothing to snap to")
    moved = np.hypot(col - lines.col, row - lines.row)
    log.info("snapped %d of %d vertices (median move %.2f px)", int(refined.sum()), refined.size,
             float(np.median(moved[refined])) if refined.any() else 0.0)
    return SnapResult(replace(lines, col=col, row=row, sigma_px=sigma), refined, moved, stations)


def snap_polyline(window: np.ndarray, col: np.ndarray, row: np.ndarray, sigma: np.ndarray,
                  settings: SnapSettings):
    """(col, row, sigma, refined, stations) (V,) of one polyline's vertices (window px) snapped
    in ``window`` (rows, cols), two passes."""
    spline = ndimage.spline_filter(window, order=3)
    c, r = col.astype(float), row.astype(float)
    s_out, ok, used = sigma.astype(float).copy(), np.zeros(c.size, bool), np.zeros(c.size, np.int64)
    for search in (settings.search, 0.5 * settings.search + 0.5 * settings.width):
        across, sd, good, n = _refine(spline, c, r, replace(settings, search=max(search, settings.width)))
        normal = _normals(c, r)
        c = np.where(good, c + across * normal[:, 0], c)
        r = np.where(good, r + across * normal[:, 1], r)
        s_out, ok, used = np.where(good, sd, s_out), good | ok, np.where(good | ~ok, n, used)
    return c, r, s_out, ok, used


def _require_inside(lines: ImageLines, shape, source: str) -> None:
    """Refuse lines with vertices outside an image of ``shape`` (rows, cols): the lines were
    digitised on another image (or one of another size)."""
    outside = (lines.col < 0) | (lines.row < 0) | (lines.col > shape[1]) | (lines.row > shape[0])
    if outside.any():
        parts = np.unique(lines.vertex_part()[outside])
        raise InputError(f"{outside.sum()} vertices of image line(s) {', '.join(lines.line_id[parts][:10])} lie "
                         f"outside {source} ({shape[1]} columns x {shape[0]} rows): lines digitised on another "
                         "image?")


def kept_reasons(result: SnapResult, settings: SnapSettings) -> dict[str, int]:
    """Why the vertices not refined kept their position: {reason: count} (empty when all moved)."""
    kept = ~result.refined
    few = kept & (result.stations < settings.min_stations)
    return {reason: int(n) for reason, n in (
        (f"fewer than {settings.min_stations} profiles found the feature (none there, a junction, the "
         "image edge)", few.sum()),
        (f"the feature's position across the line was worse than {settings.max_sigma} px (texture, a seam, "
         "a bend)", (kept & ~few).sum())) if n}


def _normals(c: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Unit normals (V,2) (col, row) of a polyline at its vertices (chord through neighbours)."""
    p = np.stack([c, r], axis=1)
    t = np.empty_like(p)
    t[1:-1] = p[2:] - p[:-2]
    t[0], t[-1] = p[1] - p[0], p[-1] - p[-2]
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    return np.stack([-t[:, 1], t[:, 0]], axis=1)


def _refine(spline, c, r, s: SnapSettings):
    """(across offset (V,), sigma (V,), good (V,), stations used (V,)) of the feature near each vertex."""
    v = c.size
    normal = _normals(c, r)
    tangent = np.stack([normal[:, 1], -normal[:, 0]], axis=1)
    along = np.arange(-s.reach, s.reach + 0.5 * s.station_step, s.station_step)       # (m,)
    ok_station = np.ones((v, along.size), bool)
    ok_station[0] &= along >= 0       # at the ends only the line's own side
    ok_station[-1] &= along <= 0
    offsets = np.arange(-s.search, s.search + 0.5 * s.sample_step, s.sample_step)     # (J,)
    base = np.stack([c, r], axis=1)[:, None, None, :] + along[None, :, None, None] * tangent[:, None, None, :]
    pts = base + offsets[None, None, :, None] * normal[:, None, None, :]               # (V, m, J, 2)
    # window index coordinates: pixel (i, j) has its centre at (col, row) = (j + 0.5, i + 0.5)
    prof = ndimage.map_coordinates(spline, [pts[..., 1].ravel() - 0.5, pts[..., 0].ravel() - 0.5], order=3,
                                   prefilter=False, mode="nearest").reshape(pts.shape[:3])
    response, edge = _response(prof, s)
    interior = np.abs(offsets) <= s.search - edge
    response = np.where(interior, response, -np.inf)
    k = np.argmax(response, axis=2)
    k = np.clip(k, 1, offsets.size - 2)
    y0, y1, y2 = (np.take_along_axis(response, (k + d)[..., None], axis=2)[..., 0] for d in (-1, 0, 1))
    with np.errstate(invalid="ignore", divide="ignore"):
        curv = y0 - 2 * y1 + y2
        frac = np.where(curv < 0, 0.5 * (y0 - y2) / curv, 0.0)
    pos = offsets[k] + np.clip(frac, -1.0, 1.0) * s.sample_step
    valid = ok_station & np.isfinite(y0) & np.isfinite(y2) & (y1 > 0)
    return _line_fit(along, pos, valid, s)


def _response(prof: np.ndarray, s: SnapSettings) -> tuple[np.ndarray, float]:
    """(feature response along the profiles' last axis, half its support in px)."""
    if s.mode == "centre":
        half = int(round(0.5 * s.width / s.sample_step))
        kernel = np.r_[-np.ones(half), np.ones(2 * half + 1), -np.ones(half)] * s.polarity
        kernel[kernel < 0] *= (2 * half + 1) / (2 * half)   # zero mean: a flat profile gives no response
        return ndimage.correlate1d(prof, kernel / (2 * half + 1), axis=2, mode="nearest"), s.width
    smooth = ndimage.gaussian_filter1d(prof, 1.0 / s.sample_step, axis=2, mode="nearest")
    return np.abs(np.gradient(smooth, s.sample_step, axis=2)), 2.0


def _line_fit(along: np.ndarray, pos: np.ndarray, valid: np.ndarray, s: SnapSettings):
    """Per vertex, the straight line pos = alpha + beta along through the valid stations, with
    one rejection pass at 3 robust sigmas: (alpha, its sigma, good, stations used)."""
    a = np.broadcast_to(along, pos.shape)
    alpha, res, am, saa, n = _fit(a, pos, valid)
    with np.errstate(invalid="ignore"):
        mad = np.nanmedian(np.where(valid, np.abs(res), np.nan), axis=1) if valid.any() else np.full(n.shape, np.nan)
        valid = valid & (np.abs(res) <= np.maximum(3 * 1.4826 * mad[:, None], 2 * s.sample_step))
    alpha, res, am, saa, n = _fit(a, pos, valid)
    with np.errstate(invalid="ignore", divide="ignore"):
        s0 = np.sqrt(np.where(valid, res ** 2, 0.0).sum(axis=1) / np.maximum(n - 2, 1))
        # neighbouring profiles closer than the feature's width see the same pixels: their
        # errors are correlated, so count one independent station per width
        share = min(1.0, s.station_step / s.width)
        sd = s0 * np.sqrt((1.0 / n + am ** 2 / np.where(saa > 0, saa, np.inf)) / share)
    good = (n >= s.min_stations) & np.isfinite(alpha) & (sd < s.max_sigma)
    return np.where(good, alpha, 0.0), np.maximum(np.where(good, sd, np.inf), s.sigma_floor), good, n.astype(np.int64)


def _fit(a: np.ndarray, pos: np.ndarray, valid: np.ndarray):
    """Weighted (0/1) straight-line fits per row: (alpha (V,) at along = 0, residuals (V,m),
    mean along, sum of squared along deviations, count)."""
    w = valid.astype(float)
    n = w.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        am = (w * a).sum(axis=1) / n
        pm = (w * np.where(valid, pos, 0.0)).sum(axis=1) / n
        saa = (w * (a - am[:, None]) ** 2).sum(axis=1)
        beta = np.where(saa > 0, (w * (a - am[:, None]) * np.where(valid, pos - pm[:, None], 0.0)).sum(axis=1) / saa,
                        0.0)
        alpha = pm - beta * am
    return alpha, pos - alpha[:, None] - beta[:, None] * a, am, saa, n
