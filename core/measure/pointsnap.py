"""Snap for points: a clicked image position refined to the image of the same ground point in a
template image (another scene's raw image where the point is measured already, or a reference
orthoimage), by least-squares template matching.

The template is the other image resampled into the clicked image's geometry around the point:
template pixel u (offsets in clicked-image px, a ``window`` x ``window`` grid) is the other image
at t + J u, t its position of the point and J (2, 2) the local map clicked px -> other px that
the scene models give on the DEM (:func:`local_map`; only its linear part is used, so the
models' absolute errors do not matter). Then:

1. normalised cross-correlation of the template over +-``radius`` px around the click (the
   clicked image resampled by cubic convolution centred on the click), its peak refined by a
   paraboloid (:mod:`core.measure.correlation`);
2. least-squares matching from that peak: the shift d (2) and a radiometric gain and offset
   that fit g(click + d + u) = a + b T(u) best, by Gauss-Newton (the clicked image resampled at
   each step, gradients by central differences); the shift's sigma (px, the larger axis) is
   the fit's standard error, sigma0^2 (A^T A)^-1, floored at SIGMA_FLOOR.

A weak match is refused (InputError, the click kept): correlation peak below
``min_correlation``, a second peak nearly as high (> ``max_peak_ratio`` of the first), the peak
on the border of the search area, a least-squares solution that leaves the search area or
whose sigma exceeds ``max_sigma``.

Pixel coordinates (col, row) are GDAL's (pixel centres at +0.5); the arrays of
:mod:`core.measure.reference` index pixel centres at integers (x = col - 0.5).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..errors import InputError
from .correlation import find_peaks, ncc, sample
from .reference import Reference

log = logging.getLogger(__name__)

SIGMA_FLOOR = 0.03   # px: the least sigma reported (the formula knows nothing of resampling or the models)
MAX_STEPS = 20       # Gauss-Newton steps of the least-squares matching


@dataclass(frozen=True)
class PointSnapSettings:
    """window (px, odd): template size; radius (px): search around the click; min_correlation,
    max_peak_ratio: the correlation peak's tests; max_sigma (px): the shift's sigma refused above."""
    window: int = 21
    radius: int = 6
    min_correlation: float = 0.7
    max_peak_ratio: float = 0.9
    max_sigma: float = 0.3


def require_valid(s: PointSnapSettings) -> None:
    """InputError naming the ranges when settings ``s`` are out of them."""
    if not (7 <= s.window <= 101 and s.window % 2 == 1 and 2 <= s.radius <= 50 and 0 < s.min_correlation < 1
            and 0 < s.max_peak_ratio <= 1 and s.max_sigma > SIGMA_FLOOR):
        raise InputError("point snapping settings: need an odd window of 7-101 px, a radius of 2-50 px, "
                             f"0 < min_correlation < 1, 0 < max_peak_ratio <= 1, max_sigma > {SIGMA_FLOOR} px")


@dataclass
class PointSnap:
    """The refined position (col, row px), the shift from the click (dcol, drow px), its sigma
    (px, larger axis), the correlation of the fitted template and the Gauss-Newton steps."""
    col: float
    row: float
    shift: tuple[float, float]
    sigma_px: float
    correlation: float
    iterations: int


def local_map(scene, camera: int, col: float, row: float, surface, to_template: Callable, half: float) -> np.ndarray:
    """J (2, 2): d(template x, y) / d(col, row) at (col, row) of ``scene``'s ``camera``, from the
    3 x 3 image points +-``half`` px around it taken to the ground on ``surface`` (anything with
    height(lon, lat) in ellipsoidal m) and to the template's array positions by
    ``to_template(ECEF (n, 3)) -> (x (n,), y (n,))``; an affine fit. InputError when a ray misses
    the surface or the template does not see the ground there."""
    d = np.array([-half, 0.0, half])
    dc, dr = (a.ravel() for a in np.meshgrid(d, d))
    ground = scene.image_to_ground_dem(col + dc, row + dr, surface, camera)
    x, y = to_template(ground)
    if not (np.isfinite(x).all() and np.isfinite(y).all()):
        raise InputError(f"snapping: the ground around ({col:.1f}, {row:.1f}) px is not seen in the other image "
                         "(off the DEM, or outside it)")
    design = np.stack([np.ones(dc.size), dc, dr], axis=1)
    coef = np.linalg.lstsq(design, np.stack([x, y], axis=1), rcond=None)[0]   # (3, 2)
    return coef[1:].T


def snap_point(target: Reference, col: float, row: float, template: Reference, tx: float, ty: float,
               jacobian: np.ndarray, settings: PointSnapSettings = PointSnapSettings(),
               what: str = "the other image") -> PointSnap:
    """Refine the click (col, row) px in ``target`` to the template of ``template`` around its
    array position (tx, ty) mapped by ``jacobian`` (see the module docstring). ``what`` names the
    template in messages. InputError (the click to be kept) when the match is weak."""
    require_valid(settings)
    h, r = settings.window // 2, settings.radius
    u = np.arange(-h, h + 1, dtype=float)
    uu, vv = np.meshgrid(u, u)
    j = np.asarray(jacobian, dtype=float)
    px, py = tx + j[0, 0] * uu + j[0, 1] * vv, ty + j[1, 0] * uu + j[1, 1] * vv
    t = _sampled(template, px, py, f"the template from {what} reaches beyond it (the point is too near its edge)")
    if float(np.std(t)) < 1.0:
        raise InputError(f"snapping: {what} shows no texture around the point (standard deviation "
                         f"{float(np.std(t)):.2f} DN): nothing to match")
    x0, y0 = col - 0.5, row - 0.5
    s = np.arange(-h - r, h + r + 1, dtype=float)
    sx, sy = np.meshgrid(x0 + s, y0 + s)
    window, ox, oy = target.float_window(sx, sy, 6)
    search = sample(window, ox, oy, sx, sy, None)
    if not np.isfinite(search).all():
        raise InputError(f"snapping: the click ({col:.1f}, {row:.1f}) px is within {h + r} px of the image's edge "
                         "(or of nodata): too near to match a template")
    peaks = find_peaks(ncc(t[None].astype(float), search[None].astype(float)), 2)
    value, ratio = float(peaks.value[0]), float(peaks.ratio[0])
    if value < settings.min_correlation:
        raise InputError(f"snapping: the best correlation with {what} is {value:.2f}, below "
                         f"{settings.min_correlation:g}: the point does not look alike there (cloud, change, low "
                         "texture, or the click is far off); the click is kept")
    if ratio > settings.max_peak_ratio or peaks.border[0]:
        raise InputError(f"snapping: the match with {what} is ambiguous ("
                         + ("best peak on the border of the search area" if peaks.border[0] else
                            f"second peak {ratio:.2f} of the first") + f", +-{r} px around the click): click "
                         "closer to the point; the click is kept")
    d0 = np.array([peaks.dx[0] - r, peaks.dy[0] - r])
    d, sigma, rho, steps = _least_squares(window, ox, oy, x0, y0, uu, vv, t.astype(float), d0,
                                          MAX_STEPS)
    if not (np.isfinite(d).all() and np.abs(d).max() <= r + 1.0 and np.hypot(*(d - d0)) < 1.5):
        raise InputError(f"snapping: least-squares matching with {what} did not converge near the correlation "
                         f"peak (shift {d0[0]:+.2f}, {d0[1]:+.2f} px); the click is kept")
    if sigma > settings.max_sigma:
        raise InputError(f"snapping: the match with {what} is too uncertain (sigma {sigma:.2f} px > "
                         f"{settings.max_sigma:g} px, correlation {rho:.2f}); the click is kept")
    log.info("snapped (%.2f, %.2f) px by (%+.3f, %+.3f) px to %s: sigma %.3f px, correlation %.3f, %d steps",
             col, row, d[0], d[1], what, sigma, rho, steps)
    return PointSnap(col + float(d[0]), row + float(d[1]), (float(d[0]), float(d[1])),
                     max(sigma, SIGMA_FLOOR), rho, steps)


def _sampled(image: Reference, x: np.ndarray, y: np.ndarray, message: str) -> np.ndarray:
    """Cubic samples of ``image`` at array positions (x, y); InputError ``message`` where it has none."""
    window, ox, oy = image.float_window(x, y, 3)
    values = sample(window, ox, oy, x, y, None)
    if not np.isfinite(values).all():
        raise InputError(f"snapping: {message}")
    return values


def _least_squares(window, ox, oy, x0, y0, uu, vv, t, d, max_iterations):
    """Gauss-Newton on (shift (2), offset, gain) so that window(x0 + d + u) = a + b t(u): (shift (2,)
    array px, its sigma px (larger axis), the final correlation, the steps taken)."""
    ext = np.pad(uu, 1, mode="reflect", reflect_type="odd"), np.pad(vv, 1, mode="reflect", reflect_type="odd")
    tv = t.ravel()
    for step in range(1, max_iterations + 1):
        g = sample(window, ox, oy, x0 + d[0] + ext[0], y0 + d[1] + ext[1], None)
        if not np.isfinite(g).all():
            return np.full(2, np.nan), np.inf, 0.0, step
        gc = g[1:-1, 1:-1].ravel()
        gx = 0.5 * (g[1:-1, 2:] - g[1:-1, :-2]).ravel()
        gy = 0.5 * (g[2:, 1:-1] - g[:-2, 1:-1]).ravel()
        b, a = np.polyfit(tv, gc, 1)
        design = np.stack([gx, gy, -np.ones_like(tv), -tv], axis=1)
        delta = np.linalg.lstsq(design, a + b * tv - gc, rcond=None)[0]
        d = d + delta[:2]
        if np.abs(delta[:2]).max() < 1e-3:
            break
    g = sample(window, ox, oy, x0 + d[0] + uu, y0 + d[1] + vv, None).ravel()
    b, a = np.polyfit(tv, g, 1)
    residual = g - a - b * tv
    normal = design.T @ design
    sigma0 = float(np.sqrt(residual @ residual / max(tv.size - 4, 1)))
    cov = sigma0 ** 2 * np.linalg.pinv(normal)[:2, :2]
    return d, float(np.sqrt(np.max(np.diag(cov)))), float(np.corrcoef(g, tv)[0, 1]), step
