"""Forward intersection: ground points from their image positions in several cameras.

A point seen in two or more cameras (three-line scenes, overlapping scenes of a strip) is
intersected in two steps:

1. the least-squares meeting point of its apparent lines of sight (closed form per point:
   sum (I - u u') X = sum (I - u u') S), good to a few metres;
2. Gauss-Newton on the image residuals through the full model (``ground_to_image``, with
   aberration and refraction), so the result is the point whose projections best fit the
   measurements (px, unit weights). The derivatives (1 m differences along ECEF axes) are taken
   once, at the start: over the few metres the points move they change by a part in 1e5 (the
   satellite is hundreds of km away), so each later pass still gains about 1e5 and costs one
   projection instead of four (the chord method). The last residuals are the last projection
   moved by the last step through those derivatives (a step below TOLERANCE: exact to 1e-9 px).

Points whose rays meet at less than MIN_CONVERGENCE (consecutive products of one strip see a point
along one line of one pass) are not intersected (NaN, ``weak``): their meeting point is fixed along
the rays by nothing but the models' errors (see MIN_CONVERGENCE); the adjustment starts them from a
height (:func:`core.adjust.ties.set_up_ties`).

Used for tie-point start values (onboard model) and for the 3D check figures (adjusted model).
Arrays: n observations (camera index, col, row, point index), m points.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .sensor import SceneModel, rows_by

STEP = 1.0               # m: finite-difference step of the image Jacobian
ITERATIONS = 5           # Gauss-Newton passes; the start is metres off, each pass gains ~1e4
TOLERANCE = 1e-4         # m: a step below this for every point ends the iteration
# rad (1 degree): the smallest convergence angle of a point's rays that fixes its height. Rays a miss
# distance d apart meet d / angle along them: the onboard or vendor errors (d of tens of metres) put a
# point of rays 1 degree apart a kilometre along them, outside the height domain of the models, and
# 1 px of image noise moves its height by sqrt(2) GSD / angle = 81 GSD (170 m at ZY-3's 2.1 m), worse
# than any reference DEM or the scene's relief. Real stereo lies far above it: three-line cameras
# (ZY-3 +-22 degrees), agile stereo pairs (over 8 degrees), neighbouring nadir strips (ZY-3 at 20 %
# side-lap: 4.6 degrees; 60 %: 2.3); consecutive products of one strip lie far below it (one line of
# one pass: their rays differ by the products' fits and biases only, 2e-4 rad measured on a simulated
# ZY-3 region, tests/unit/adjust/test_weakrays.py).
MIN_CONVERGENCE = np.radians(1.0)


@dataclass
class Intersection:
    """ground (m,3) ECEF m (NaN where fewer than two rays); rays (m,) number of observations;
    residuals (n,2) px, predicted minus measured (col, row); condition (m,) m per px: the
    largest standard deviation of the point for 1 px image noise (large: near-parallel rays);
    iterations: Gauss-Newton passes run; converged: whether the last step was below TOLERANCE;
    convergence (m,) rad: the rays' effective convergence angle (NaN with fewer than two rays);
    weak (m,) bool: two or more rays meeting at less than MIN_CONVERGENCE, not intersected."""
    ground: np.ndarray
    rays: np.ndarray
    residuals: np.ndarray
    condition: np.ndarray
    iterations: int
    converged: bool
    convergence: np.ndarray
    weak: np.ndarray


def _sum_by_point(point: np.ndarray, values: np.ndarray, m: int) -> np.ndarray:
    flat = values.reshape(values.shape[0], -1)
    out = np.stack([np.bincount(point, weights=flat[:, k], minlength=m) for k in range(flat.shape[1])], axis=1)
    return out.reshape((m,) + values.shape[1:])


def onboard_rays(scene: SceneModel, camera, col, row) -> tuple[np.ndarray, np.ndarray]:
    """Origins (n,3) and unit directions (n,3) ECEF of the observations' lines of sight (camera (n,)
    index, col, row (n,) px)."""
    origin = np.empty((col.size, 3))
    direction = np.empty((col.size, 3))
    for c, m in enumerate(rows_by(camera, len(scene.cameras))):
        if m.size:
            _, origin[m], _, direction[m] = scene.line_of_sight(col[m], row[m], c)
    return origin, direction


def _project(scene: SceneModel, camera, x, near) -> np.ndarray:
    """Image positions (n,2) of ECEF points x (n,3) in cameras ``camera`` (n,), from image
    positions ``near`` (n,2) px close to them (the measurement, the last projection;
    :meth:`SceneModel.ground_to_image_near`)."""
    out = np.empty((x.shape[0], 2))
    for c, m in enumerate(rows_by(camera, len(scene.cameras))):
        if m.size:
            out[m] = np.stack(scene.ground_to_image_near(x[m], c, near[m, 0], near[m, 1]), axis=1)
    return out


def convergence_angle(A: np.ndarray, rays: np.ndarray) -> np.ndarray:
    """Effective convergence angles (m,) rad of points' rays from their sums A (m,3,3) of
    I - u u' over their ``rays`` (m,) unit directions u: 2 arcsin sqrt(lambda_min / rays), the angle
    between two rays with the same smallest eigenvalue per ray (two rays: lambda_min = 1 - cos angle;
    parallel rays: 0). NaN with fewer than two rays."""
    out = np.full(rays.shape, np.nan)
    two = rays >= 2
    if two.any():
        smallest = np.clip(np.linalg.eigvalsh(A[two])[:, 0], 0.0, None)
        out[two] = 2.0 * np.arcsin(np.minimum(np.sqrt(smallest / rays[two]), 1.0))
    return out


def intersect(scene: SceneModel, camera, col, row, point, n_points: int | None = None,
              sight: tuple[np.ndarray, np.ndarray] | None = None) -> Intersection:
    """Intersect the observations (camera (n,) index, col, row (n,) px) of points ``point``
    (n,) index in 0..n_points-1; ``sight``: their :func:`onboard_rays` when the caller has them."""
    camera = np.asarray(camera, dtype=np.int64)
    point = np.asarray(point, dtype=np.int64)
    col, row = np.asarray(col, dtype=float), np.asarray(row, dtype=float)
    m = int(point.max()) + 1 if n_points is None else int(n_points)
    if col.size and (point.min() < 0 or point.max() >= m):
        raise InputError("point indices of the observations are out of range")
    rays = np.bincount(point, minlength=m)
    origin, u = sight if sight is not None else onboard_rays(scene, camera, col, row)
    projector = np.eye(3)[None] - u[:, :, None] * u[:, None, :]          # (n,3,3)
    A = _sum_by_point(point, projector, m)
    b = _sum_by_point(point, np.einsum("nij,nj->ni", projector, origin), m)
    convergence = convergence_angle(A, rays)
    weak = (rays >= 2) & (convergence < MIN_CONVERGENCE)
    ok = (rays >= 2) & ~weak
    ground = np.full((m, 3), np.nan)
    ground[ok] = np.linalg.solve(A[ok], b[ok][:, :, None])[:, :, 0]
    measured = np.stack([col, row], axis=1)
    use = ok[point]
    iterations, converged = 0, not use.any()
    near = measured[use]  # where each projection starts: the measurement, then the last projection
    normal = np.zeros((m, 3, 3))
    r = np.zeros((0, 2))
    J = np.zeros((0, 2, 3))
    step = np.zeros((m, 3))
    for iterations in range(1, ITERATIONS + 1 if use.any() else 1):  # none to iterate without a 2-ray point
        x = ground[point[use]]
        cam = camera[use]
        base = _project(scene, cam, x, near)
        if iterations == 1:
            J = np.stack([(_project(scene, cam, x + STEP * e, base) - base) / STEP for e in np.eye(3)],
                         axis=2)  # (k,2,3)
            normal[ok] = _sum_by_point(point[use], J.transpose(0, 2, 1) @ J, m)[ok]
        near = np.where(np.isfinite(base), base, near)
        r = base - measured[use]
        rhs = _sum_by_point(point[use], np.einsum("kji,kj->ki", J, r), m)
        good = ok & np.all(np.isfinite(normal), axis=(1, 2)) & np.all(np.isfinite(rhs), axis=1)
        step = np.zeros((m, 3))
        step[good] = -np.linalg.solve(normal[good], rhs[good][:, :, None])[:, :, 0]
        ground[good] += step[good]
        if np.all(np.linalg.norm(step[good], axis=1) < TOLERANCE):
            converged = True
            break
    # A point some model no longer images (an RPC far outside its ground domain, reached from
    # near-parallel rays) is not intersected.
    lost = ok & ~np.all(np.isfinite(normal), axis=(1, 2))
    ground[lost] = np.nan
    ok &= ~lost
    residuals = np.full((col.size, 2), np.nan)
    if r.size:
        residuals[use] = r + np.einsum("kij,kj->ki", J, step[point[use]])
        residuals[~ok[point]] = np.nan
    condition = np.full(m, np.inf)
    if ok.any():
        with np.errstate(divide="ignore", invalid="ignore"):
            condition[ok] = np.sqrt(1.0 / np.linalg.eigvalsh(normal[ok])[:, 0])
    return Intersection(ground, rays, residuals, condition, iterations, converged, convergence, weak)
