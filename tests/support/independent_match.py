"""Conjugate check points between two images of scenes, found by a matcher of its own (numpy and scipy only;
no code of core.measure), to judge the plugin's tie points and adjustment independently (issue 28): the
points triangulated through the scenes (vendor, adjusted) reproject with an RMS that says how well each
set's relative orientation fits the images (:func:`triangulation_check`).

Image points are GDAL (col, row): (0, 0) the upper-left corner of the upper-left pixel, centres at +0.5;
array index = (row - 0.5, col - 0.5). Scenes are anything with image_to_ground(col, row, h) -> ECEF (n, 3)
and ground_to_image(xyz) -> (col, row) (core.model's scenes; only their geometry is used).

Per candidate point p of image A (a grid every ``step`` px, at least ``clearance`` px from every excluded
point, e.g. the plugin's ties):
1. Rectified search. The local affine map of A's pixels into B at the candidate's height (from the scenes:
   p and two neighbours through A onto the ground at that height and through B into its image) resamples a
   search area of B into A's geometry, so view-angle and scale differences are gone; a window of A about p
   is correlated with it (normalised cross-correlation by FFT) over +-``radius`` px: relief parallax along
   the epipolar line and the scenes' relative error across it both lie inside. A peak below
   ``min_correlation``, on the border of the search area, or with a second peak (outside +-2 px of it)
   above ``max_peak_ratio`` of it is rejected.
2. Least-squares matching (Gruen 1985): B sampled (cubic spline) at the affine image of A's window, the
   affine map (6 parameters, both shifts free: the match does not follow the scenes' epipolar geometry) and
   a radiometric gain and offset fitted by Gauss-Newton; kept when it converges (shift step < 1e-3 px).
3. Backward check: the same least-squares matching of B's window about the match in A, from p; kept when it
   returns within ``backward_px`` of p.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from osgeo import gdal
from scipy.ndimage import map_coordinates, spline_filter
from scipy.signal import fftconvolve

from pushbroom_adjust.core.geodesy import ecef_to_geodetic
from tests.support.triangulation import reprojection_rms, triangulated

gdal.UseExceptions()


@dataclass
class CheckPoints:
    """Conjugate points: a (n, 2) and b (n, 2) GDAL (col, row) in images A and B; correlation (n,) of the
    rectified search; rejected: {reason: count} over the candidates."""
    a: np.ndarray
    b: np.ndarray
    correlation: np.ndarray
    rejected: dict = field(default_factory=dict)


@dataclass
class Image:
    """A one-band image for sampling: values (rows, cols) float64, their cubic spline coefficients and their
    gradient (d/drow, d/dcol: central differences), each (rows, cols)."""
    values: np.ndarray
    spline: np.ndarray
    slopes: tuple

    @classmethod
    def read(cls, path) -> "Image":
        ds = gdal.Open(str(path))
        values = ds.GetRasterBand(1).ReadAsArray().astype(np.float64)
        return cls(values, spline_filter(values, order=3), tuple(np.gradient(values)))

    def sample(self, col, row, order: int = 3) -> np.ndarray:
        """Values at GDAL (col, row) (any equal shapes), cubic spline (order 3) or bilinear (order 1); NaN
        outside the pixel centres' hull."""
        col, row = np.asarray(col, dtype=float), np.asarray(row, dtype=float)
        i, j = row - 0.5, col - 0.5
        out = map_coordinates(self.spline if order == 3 else self.values, [i.ravel(), j.ravel()], order=order,
                              prefilter=False, mode="nearest")
        rows, cols = self.values.shape
        inside = (i >= 0) & (i <= rows - 1) & (j >= 0) & (j <= cols - 1)
        return np.where(inside, out.reshape(i.shape), np.nan)

    def gradient(self, col, row) -> tuple[np.ndarray, np.ndarray]:
        """d/dcol, d/drow at (col, row): the central differences interpolated bilinearly (the Gauss-Newton
        steps of least-squares matching need their direction, not their last digit)."""
        i, j = (np.asarray(row, dtype=float) - 0.5).ravel(), (np.asarray(col, dtype=float) - 0.5).ravel()
        d_row, d_col = (map_coordinates(s, [i, j], order=1, mode="nearest").reshape(np.shape(col))
                        for s in self.slopes)
        return d_col, d_row


def affine_maps(scene_a, scene_b, col, row, height, d: float = 8.0) -> tuple[np.ndarray, np.ndarray]:
    """The local affine maps of A's pixels into B at ``height`` (m, ellipsoidal; scalar or (n,)): B's image
    (n, 2) of A's points (col, row) (n,) and the Jacobians (n, 2, 2) d(B col, row)/d(A col, row) (differences
    over ``d`` px)."""
    n = col.size
    cols = np.concatenate([col, col + d, col])
    rows = np.concatenate([row, row, row + d])
    h = np.broadcast_to(np.asarray(height, dtype=float), (n,))
    ground = scene_a.image_to_ground(cols, rows, np.concatenate([h, h, h]))
    bc, br = scene_b.ground_to_image(ground)
    q = np.stack([bc, br], axis=1).reshape(3, n, 2)
    jac = np.stack([(q[1] - q[0]) / d, (q[2] - q[0]) / d], axis=2)  # (n, 2 rows: col,row of B; 2 cols: A col,row)
    return q[0], jac


def window_offsets(size: int) -> tuple[np.ndarray, np.ndarray]:
    """Pixel offsets (size, size) (du along columns, dv along rows) of a window centred on a point."""
    k = np.arange(size) - (size - 1) / 2
    dv, du = np.meshgrid(k, k, indexing="ij")
    return du, dv


def affine_sample(image: Image, centre: np.ndarray, jac: np.ndarray, du: np.ndarray, dv: np.ndarray,
                  order: int = 3) -> np.ndarray:
    """Image values (n, *du.shape) at centre (n, 2) + jac (n, 2, 2) @ (du, dv)."""
    col = centre[:, 0, None, None] + jac[:, 0, 0, None, None] * du + jac[:, 0, 1, None, None] * dv
    row = centre[:, 1, None, None] + jac[:, 1, 0, None, None] * du + jac[:, 1, 1, None, None] * dv
    return image.sample(col, row, order)


def ncc_search(template: np.ndarray, search: np.ndarray) -> np.ndarray:
    """Normalised cross-correlation (n, s - t + 1, s - t + 1) of templates (n, t, t) at every position in
    search areas (n, s, s) (NaN where they hold no values), by FFT; NaN where the search area's window is not
    whole or has no variance."""
    t = template.shape[-1]
    tz = template - template.mean(axis=(1, 2), keepdims=True)
    tz /= np.sqrt(np.sum(tz ** 2, axis=(1, 2), keepdims=True))
    valid = np.isfinite(search)
    values = np.where(valid, search, 0.0)
    ones = np.ones((1, t, t))
    count = fftconvolve(valid.astype(float), ones, mode="valid", axes=(1, 2))
    num = fftconvolve(values, tz[:, ::-1, ::-1], mode="valid", axes=(1, 2))
    s1 = fftconvolve(values, ones, mode="valid", axes=(1, 2))
    s2 = fftconvolve(values ** 2, ones, mode="valid", axes=(1, 2))
    var = s2 - s1 ** 2 / (t * t)
    whole = (count > t * t - 0.5) & (var > 1e-6 * np.max(var))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(whole, num / np.sqrt(np.maximum(var, 1e-12)), np.nan)


def least_squares_match(template: np.ndarray, image: Image, centre: np.ndarray, jac: np.ndarray, du: np.ndarray,
                        dv: np.ndarray, iterations: int = 20) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Affine least-squares matching of templates (n, w, w) (pixel offsets du, dv about their centre) in
    ``image``: the centres (n, 2) and Jacobians (n, 2, 2) that minimise sum (image(centre + jac (du, dv)) -
    gain * template - offset)^2, from the given ones; and whether each converged (n,): its last shift step
    below 1e-3 px."""
    centre, jac = centre.copy(), jac.copy()
    n = centre.shape[0]
    u, v, tpl = du.ravel(), dv.ravel(), template.reshape(n, -1)
    gain, offset = np.ones(n), np.zeros(n)
    converged, failed = np.zeros(n, bool), np.zeros(n, bool)
    for _ in range(iterations):
        k = np.nonzero(~converged & ~failed)[0]
        if k.size == 0:
            break
        col = centre[k, 0, None] + jac[k, 0, 0, None] * u + jac[k, 0, 1, None] * v
        row = centre[k, 1, None] + jac[k, 1, 0, None] * u + jac[k, 1, 1, None] * v
        gc, gr = image.gradient(col, row)
        residual = image.sample(col, row) - gain[k, None] * tpl[k] - offset[k, None]
        # unknowns: centre col, row; jac (0,0), (0,1), (1,0), (1,1); gain; offset
        design = np.stack([gc, gr, gc * u, gc * v, gr * u, gr * v, -tpl[k], -np.ones_like(gc)], axis=2)
        ok = np.all(np.isfinite(residual), axis=1)
        failed[k[~ok]] = True
        k, design, residual = k[ok], design[ok], residual[ok]
        normal = design.transpose(0, 2, 1) @ design
        step = -np.linalg.solve(normal, (design.transpose(0, 2, 1) @ residual[:, :, None]))[:, :, 0]
        centre[k] += step[:, :2]
        jac[k] += step[:, 2:6].reshape(-1, 2, 2)
        gain[k] += step[:, 6]
        offset[k] += step[:, 7]
        converged[k] = np.hypot(step[:, 0], step[:, 1]) < 1e-3
    return centre, jac, converged


def candidates(cols: int, rows: int, step: float, margin: float, excluded: np.ndarray,
               clearance: float) -> np.ndarray:
    """Grid points (n, 2) of an image every ``step`` px, ``margin`` px from its border, at least ``clearance``
    px from every point of ``excluded`` (m, 2)."""
    c, r = np.meshgrid(np.arange(margin, cols - margin, step) + 0.5, np.arange(margin, rows - margin, step) + 0.5)
    points = np.stack([c.ravel(), r.ravel()], axis=1)
    if len(excluded):
        distance = np.min(np.hypot(points[:, None, 0] - excluded[None, :, 0],
                                   points[:, None, 1] - excluded[None, :, 1]), axis=1)
        points = points[distance >= clearance]
    return points


def match_check_points(scene_a, image_a: Image, scene_b, image_b: Image, points: np.ndarray, heights,
                       window: int = 31, radius: int = 24, min_correlation: float = 0.7,
                       max_peak_ratio: float = 0.9, backward_px: float = 0.1) -> CheckPoints:
    """Conjugate points in B of A's ``points`` (n, 2) (see the module docstring), searched about the
    scenes' prediction on the surface of ``heights`` (m, ellipsoidal; scalar or (n,))."""
    rejected = {"outside B": 0, "low correlation": 0, "peak on the search border": 0, "ambiguous peak": 0,
                "no convergence": 0, "backward check": 0}
    heights = np.broadcast_to(np.asarray(heights, dtype=float), (len(points),))
    q0, jac = affine_maps(scene_a, scene_b, points[:, 0], points[:, 1], heights)
    du, dv = window_offsets(window)
    su, sv = window_offsets(window + 2 * radius)
    template = image_a.sample(points[:, 0, None, None] + du, points[:, 1, None, None] + dv)
    rows, cols = image_b.values.shape
    half = window / 2
    inside = (np.all(np.isfinite(template), axis=(1, 2)) & np.all(np.isfinite(q0), axis=1)
              & (q0[:, 0] > half) & (q0[:, 0] < cols - half) & (q0[:, 1] > half) & (q0[:, 1] < rows - half))
    rejected["outside B"] = int((~inside).sum())
    points, q0, jac, template = points[inside], q0[inside], jac[inside], template[inside]
    c = ncc_search(template, affine_sample(image_b, q0, jac, su, sv, order=1))  # B in A's geometry about p
    size = 2 * radius + 1
    scores = np.nan_to_num(c, nan=-2.0)
    best = np.argmax(scores.reshape(len(points), -1), axis=1)
    pi, pj = np.divmod(best, size)
    peak = scores.reshape(len(points), -1)[np.arange(len(points)), best]
    ii, jj = np.meshgrid(np.arange(size), np.arange(size), indexing="ij")
    far = (np.abs(ii[None] - pi[:, None, None]) > 2) | (np.abs(jj[None] - pj[:, None, None]) > 2)
    second = np.max(np.where(far, scores, -2.0), axis=(1, 2))
    around = np.pad(scores, ((0, 0), (1, 1), (1, 1)), constant_values=-2.0)
    neighbours = np.stack([around[np.arange(len(points)), pi + 1 + di, pj + 1 + dj]
                           for di in (-1, 0, 1) for dj in (-1, 0, 1)], axis=1)
    low = peak < min_correlation
    border = ~low & np.any(neighbours < -1.5, axis=1)   # next to the search area's edge or its missing part
    ambiguous = ~low & ~border & (second > max_peak_ratio * peak)
    rejected["low correlation"], rejected["peak on the search border"] = int(low.sum()), int(border.sum())
    rejected["ambiguous peak"] = int(ambiguous.sum())
    keep = ~(low | border | ambiguous)
    shift = np.stack([pj - radius, pi - radius], axis=1).astype(float)[keep]  # in A's pixels (du, dv)
    points, q0, jac, template, peak = points[keep], q0[keep], jac[keep], template[keep], peak[keep]
    start = q0 + np.einsum("nij,nj->ni", jac, shift)
    q, jac_q, converged = least_squares_match(template, image_b, start, jac, du, dv)
    rejected["no convergence"] = int((~converged).sum())
    points, q, jac_q, peak = points[converged], q[converged], jac_q[converged], peak[converged]
    back_template = image_b.sample(q[:, 0, None, None] + du, q[:, 1, None, None] + dv)
    p_back, _, back_converged = least_squares_match(back_template, image_a, points, np.linalg.inv(jac_q), du, dv)
    returned = back_converged & (np.hypot(*(p_back - points).T) <= backward_px)
    rejected["backward check"] = int((~returned).sum())
    return CheckPoints(points[returned], q[returned], peak[returned], rejected)


@dataclass
class TriangulationCheck:
    """The independent check of two scenes' relative orientation: the check points (at least ``clearance``
    px from every tie), and their reprojection RMS (px per image point) triangulated through each set of
    scenes given, by name."""
    points: CheckPoints
    clearance_px: float
    rms: dict


def triangulation_check(scene_sets: dict, images: tuple, ties: np.ndarray, surface, step: float = 12.0,
                        clearance: float = 35.0, margin: float = 16.0, radius: int = 24) -> TriangulationCheck:
    """Check points between images A and B (paths) matched independently of the plugin (through the first set
    of ``scene_sets``, {name: (scene A, scene B)}: the vendor models) on a grid every ``step`` px of A at least
    ``clearance`` px from the plugin's ``ties`` (m, 2: their positions in A), searched about the surface
    ``surface`` (a height in m, ellipsoidal, or a core.dem DEM: the height under each point through scene A);
    then triangulated through every set of scenes (least squares of tests/support/triangulation.py)."""
    first_a, first_b = next(iter(scene_sets.values()))
    image_a, image_b = Image.read(images[0]), Image.read(images[1])
    rows, cols = image_a.values.shape
    points = candidates(cols, rows, step, margin, ties, clearance)
    heights = surface
    if hasattr(surface, "height"):
        heights = ecef_to_geodetic(first_a.image_to_ground_dem(points[:, 0], points[:, 1], surface))[2]
        heights = np.where(np.isfinite(heights), heights, np.nanmedian(heights))
    found = match_check_points(first_a, image_a, first_b, image_b, points, heights, radius=radius)
    obs = np.concatenate([found.a, found.b], axis=1)
    start = float(np.median(np.atleast_1d(heights)))
    rms = {name: reprojection_rms(triangulated(list(pair), obs, start)[1]) for name, pair in scene_sets.items()}
    return TriangulationCheck(found, clearance, rms)
