"""Least-squares matching (Gruen 1985): a chip's match refined to a fraction of a pixel by fitting
the image to the template through an affine map of positions and a linear map of grey values.

For a template T (w x w, pixel (i, j) at u = j - (w-1)/2, v = i - (w-1)/2 from its centre) and an
image G, the unknowns of each chip are the match's centre (x, y), the affine terms a (G is read at
(x, y) + (I + a) (u, v)) and the radiometric offset r0 and gain r1:

    T(u, v) = r0 + r1 G((x, y) + (I + a) (u, v)) + noise,

solved by Gauss-Newton from the correlation peak, vectorised over a batch of chips (each its own
8 x 8 normal equations). G is read by cubic convolution (:func:`core.measure.correlation.sample`),
its gradients by central differences of the chip read one pixel wider, turned from template axes
into image axes through (I + a). Gain and offset absorb what normalised cross-correlation is blind
to but a plain least-squares fit is not (another date, sensor or exposure); the affine terms absorb
what the rectification through the models leaves (a slope the DEM lacks tilts a window's parallax),
held by a prior (0 +- AFFINE_SIGMA) where the texture hardly fixes them.
A chip converges when its centre moves less than CONVERGED_PX (or less than SETTLED_PX at the
MAX_ITERATIONS-th step); it fails (``converged`` False) when it moves farther than MAX_MOVE_PX from
where it started (another place than the peak the correlation found), its affine terms reach
MAX_AFFINE, its gain is not positive, or it still moves after MAX_ITERATIONS.

The precision of the centre is the fit's: sigma0^2 (N^-1)_xx with sigma0^2 = v'v / (w^2 - 8), the
residuals' variance (both images' noise, and what the model leaves), in the image's pixels.
Array positions (x = column, y = row) have pixel centres at integers, as in correlation.py.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .correlation import sample

UNKNOWNS = 8            # x, y, a11, a12, a21, a22, r0, r1
CONVERGED_PX = 0.02     # px: a step of the centre this small ends the iterations
MAX_ITERATIONS = 8      # ... or this many, the centre then still moving by less than SETTLED_PX: converged too
SETTLED_PX = 0.05       # (real images' fits, trees and relief in the window, wander by a few hundredths)
MAX_MOVE_PX = 1.5       # px from the correlation peak: farther is another match than the peak's
MAX_AFFINE = 0.3        # |a_ij|: a window sheared or scaled by 30 % is no rectified window
AFFINE_SIGMA = 0.05     # the affine terms' prior sigma: what the rectification may leave (a steep slope's parallax)
AFFINE = [2, 3, 4, 5]   # the affine terms' indices among the unknowns


@dataclass
class Refined:
    """Per chip (b,): the refined centre (x, y) in the image's array positions, gain and offset,
    the affine terms a (b, 2, 2), the centre's sigma (b, 2: x, y) in px, the residuals' RMS (grey
    values) and whether the fit converged."""
    x: np.ndarray
    y: np.ndarray
    gain: np.ndarray
    offset: np.ndarray
    affine: np.ndarray
    sigma: np.ndarray
    rms: np.ndarray
    converged: np.ndarray


def refine(templates: np.ndarray, image: np.ndarray, x0: int, y0: int, x: np.ndarray,
           y: np.ndarray) -> Refined:
    """Least-squares matches of ``templates`` (b, w, w, finite) in ``image`` (a 2-D array whose
    pixel [0, 0] is array position (x0, y0); NaN or out of reach where it has no data) from the
    starting centres (x, y) (b,), see the module docstring."""
    b, w, _ = templates.shape
    k = np.arange(w + 2) - (w + 1) / 2                   # the template's axes, one pixel wider
    uu, vv = np.meshgrid(k, k)
    u, v = uu[1:-1, 1:-1].ravel().astype(np.float32), vv[1:-1, 1:-1].ravel().astype(np.float32)
    t = templates.reshape(b, -1).astype(np.float64)
    p = np.zeros((b, UNKNOWNS))
    p[:, 0], p[:, 1] = x, y
    start = p[:, :2].copy()
    active = np.ones(b, bool)
    converged = np.zeros(b, bool)
    normal = np.zeros((b, UNKNOWNS, UNKNOWNS))
    residual = np.zeros((b, w * w))
    first = True
    for it in range(MAX_ITERATIONS):
        idx = np.nonzero(active)[0]
        if idx.size == 0:
            break
        q = p[idx]
        a = q[:, 2:6].reshape(-1, 2, 2) + np.eye(2)
        gx_pos = q[:, 0, None, None] + a[:, 0, 0, None, None] * uu + a[:, 0, 1, None, None] * vv
        gy_pos = q[:, 1, None, None] + a[:, 1, 0, None, None] * uu + a[:, 1, 1, None, None] * vv
        g = sample(image, x0, y0, gx_pos, gy_pos)                       # (n, w + 2, w + 2), float32
        du = (g[:, 1:-1, 2:] - g[:, 1:-1, :-2]).reshape(idx.size, -1) / 2
        dv = (g[:, 2:, 1:-1] - g[:, :-2, 1:-1]).reshape(idx.size, -1) / 2
        g = g[:, 1:-1, 1:-1].reshape(idx.size, -1)
        # template-axis gradients -> image-axis gradients: [du, dv] = (I + a)^T [gx, gy]
        inv = np.linalg.inv(a).astype(np.float32)
        gx = inv[:, 0, 0, None] * du + inv[:, 1, 0, None] * dv
        gy = inv[:, 0, 1, None] * du + inv[:, 1, 1, None] * dv
        if first:
            # the radiometry that best fits the starting position, so the first geometric step
            # is not spent on it
            gm, tm = g.mean(axis=1, keepdims=True), t[idx].mean(axis=1, keepdims=True)
            gain = ((g - gm) * (t[idx] - tm)).sum(axis=1) / np.maximum(((g - gm) ** 2).sum(axis=1), 1e-12)
            q[:, 7] = np.where(np.isfinite(gain) & (gain > 0), gain, 1.0)
            q[:, 6] = tm[:, 0] - q[:, 7] * gm[:, 0]
            first = False
        r1 = q[:, 7, None].astype(np.float32)
        sx, sy = r1 * gx, r1 * gy
        jac = np.stack([sx, sy, sx * u, sx * v, sy * u, sy * v, np.ones_like(g), g], axis=1)  # (n, 8, w*w) float32
        res = (t[idx] - (q[:, 6, None] + q[:, 7, None] * g)).astype(np.float32)
        bad = ~np.isfinite(res).all(axis=1)
        jac[bad], res[bad] = 0.0, 0.0
        n = (jac @ jac.transpose(0, 2, 1)).astype(np.float64)
        rhs = (jac @ res[..., None]).astype(np.float64)[..., 0]
        # the affine terms' prior (0 +- AFFINE_SIGMA), weighed against the residuals' variance: it holds
        # the terms smooth or flat texture hardly fixes, which would otherwise drift for many iterations
        prior = (res.astype(np.float64) ** 2).mean(axis=1) / AFFINE_SIGMA ** 2
        n[:, AFFINE, AFFINE] += prior[:, None]
        rhs[:, AFFINE] -= prior[:, None] * q[:, AFFINE]
        # keeps flat chips (and those without data, all zero) solvable
        n += (1e-9 * np.trace(n, axis1=1, axis2=2) + 1e-9)[:, None, None] * np.eye(UNKNOWNS)
        step = np.linalg.solve(n, rhs[..., None])[..., 0]
        q += step
        p[idx] = q
        normal[idx], residual[idx] = n, res
        moved = np.hypot(*(q[:, :2] - start[idx]).T)
        failed = (bad | ~np.isfinite(q).all(axis=1) | (moved > MAX_MOVE_PX)
                  | (np.abs(q[:, 2:6]) > MAX_AFFINE).any(axis=1) | (q[:, 7] <= 0))
        moving = np.hypot(step[:, 0], step[:, 1])
        done = ~failed & ((moving < CONVERGED_PX) | ((it == MAX_ITERATIONS - 1) & (moving < SETTLED_PX)))
        converged[idx[done]] = True
        active[idx[done | failed]] = False
    dof = max(w * w - UNKNOWNS, 1)
    s0 = (residual ** 2).sum(axis=1) / dof
    cov = np.linalg.inv(normal + np.where(converged[:, None, None], 0.0, np.eye(UNKNOWNS)))
    sigma = np.sqrt(np.maximum(s0[:, None] * cov[:, [0, 1], [0, 1]], 0.0))
    return Refined(p[:, 0], p[:, 1], p[:, 7], p[:, 6], p[:, 2:6].reshape(-1, 2, 2), sigma, np.sqrt(s0), converged)
