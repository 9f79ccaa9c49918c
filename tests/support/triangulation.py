"""Triangulation of image points seen in several scenes by least squares of their own (Gauss-Newton on the
reprojection error through each scene's ground_to_image_geodetic), and the reprojection RMS that judges how
well the scenes' relative orientation fits the observations."""
from __future__ import annotations

import numpy as np

from pushbroom_adjust.core.geodesy import ecef_to_geodetic


def intersect(scenes: list, obs: np.ndarray, start: np.ndarray, iterations: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """Ground points (n, 3: lon, lat, h) minimising the reprojection error in all ``scenes`` of the
    observations ``obs`` (n, 2 * len(scenes): col, row per scene), Gauss-Newton from ``start`` with
    finite-difference Jacobians, vectorised over the points; and the residuals obs - projection."""
    def project(p):
        return np.concatenate([np.stack(s.ground_to_image_geodetic(p[:, 0], p[:, 1], p[:, 2]), axis=1)
                               for s in scenes], axis=1)

    steps = np.array([1e-6, 1e-6, 1.0])  # deg, deg, m
    p = start.copy()
    for _ in range(iterations):
        f = project(p)
        jac = np.stack([(project(p + np.eye(3)[k] * steps[k]) - f) / steps[k] for k in range(3)], axis=2)
        p += np.linalg.solve(np.einsum("nik,nil->nkl", jac, jac), np.einsum("nik,ni->nk", jac, obs - f))
    return p, obs - project(p)


def triangulated(scenes: list, obs: np.ndarray, height: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`intersect` from the first scene's ground at ``height`` (m, ellipsoidal) under its observations."""
    lon, lat, h = ecef_to_geodetic(scenes[0].image_to_ground(obs[:, 0], obs[:, 1], height))
    return intersect(scenes, obs, np.stack([lon, lat, h], axis=1))


def reprojection_rms(residuals: np.ndarray) -> float:
    """RMS (px) per image point of residuals (n, 2 * scenes: col, row per scene)."""
    return float(np.sqrt(np.mean(residuals[:, 0::2] ** 2 + residuals[:, 1::2] ** 2)))
