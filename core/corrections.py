"""Light-path corrections between the camera's apparent line of sight and geometry.

Velocity aberration: a camera moving at v sees light from a ground point shifted toward
its motion. With light-time included (the Earth turns while light travels), the apparent
direction is ``normalize(u_geo + (v_ecef + omega x (S - P)) / c)`` with u_geo the
geometric unit direction from the satellite S to the ground point P (both ECEF).

Atmospheric refraction: in a layered atmosphere the true ray is steeper near the ground
than its straight extension from space, so the straight apparent ray meets the ground a
distance ``N(h) tan(z) sec^2(z)`` too far from nadir, with z the zenith angle of the ray
at the ground and N(h) = integral of (n - 1) dz above height h (Snell's law, first order).
"""
from __future__ import annotations

import numpy as np

from .geodesy import C_LIGHT, OMEGA_EARTH

OMEGA_VECTOR = np.array([0.0, 0.0, OMEGA_EARTH])
REFRACTIVITY_SEA_LEVEL = 2.78e-4  # n - 1 for visible/NIR light, 15 degC, 1013 hPa
PRESSURE_SCALE_HEIGHT = 8430.0    # m, R*T0/(M*g) at 288 K: column of (n-1) = (n0-1)*H*p/p0


def aberration_velocity(v_ecef: np.ndarray, sat_minus_ground: np.ndarray) -> np.ndarray:
    """Effective velocity (n, 3) m/s whose ratio to c shifts the apparent direction."""
    return v_ecef + np.cross(OMEGA_VECTOR, sat_minus_ground)


def apparent_from_geometric(u_geo: np.ndarray, v_eff: np.ndarray) -> np.ndarray:
    """Apparent unit directions (n, 3) from geometric unit directions and effective velocity."""
    u = u_geo + v_eff / C_LIGHT
    return u / np.linalg.norm(u, axis=-1, keepdims=True)


def geometric_from_apparent(u_app: np.ndarray, v_eff: np.ndarray) -> np.ndarray:
    """Exact inverse of :func:`apparent_from_geometric`: the unit g with normalize(g + w) = u_app.

    Writing g + w = k u_app with |g| = 1 gives k = a.w + sqrt((a.w)^2 - |w|^2 + 1).
    """
    w = v_eff / C_LIGHT
    aw = np.einsum("ni,ni->n", u_app, w)
    k = aw + np.sqrt(aw * aw - np.einsum("ni,ni->n", w, w) + 1.0)
    return k[:, None] * u_app - w


def refraction_offset(cos_zenith: np.ndarray, height: np.ndarray) -> np.ndarray:
    """Horizontal distance (m) by which the straight apparent ray overshoots the true point.

    cos_zenith: cosine of the ray's zenith angle at the ground; height: ellipsoidal height (m)
    of the ground point (used as height above sea level: the difference is irrelevant here).
    """
    cz = np.clip(cos_zenith, 1e-3, 1.0)
    tan_z = np.sqrt(1.0 - cz * cz) / cz
    column = REFRACTIVITY_SEA_LEVEL * PRESSURE_SCALE_HEIGHT * np.exp(-np.asarray(height) / PRESSURE_SCALE_HEIGHT)
    return column * tan_z / (cz * cz)


def horizontal_direction(u: np.ndarray, up: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(unit horizontal component of ray direction u (n,3), cos zenith) at local up vectors."""
    cos_z = -np.einsum("ni,ni->n", u, up)
    hor = u + cos_z[:, None] * up
    norm = np.linalg.norm(hor, axis=-1, keepdims=True)
    return np.where(norm > 1e-12, hor / np.maximum(norm, 1e-300), 0.0), cos_z
