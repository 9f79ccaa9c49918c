"""WGS84 geodesy, vectorised: geodetic <-> ECEF and local east-north-up frames.

Units: metres and degrees at the interface (lon, lat in degrees, h ellipsoidal metres);
ECEF is EPSG:4978. Arrays broadcast; shapes are kept (``(...,)`` in, ``(..., 3)`` out).
"""
from __future__ import annotations

import numpy as np

A = 6378137.0
F = 1.0 / 298.257223563
B = A * (1.0 - F)
E2 = F * (2.0 - F)
EP2 = E2 / (1.0 - E2)
OMEGA_EARTH = 7.2921151467e-5  # rad/s, WGS84 rotation rate
C_LIGHT = 299792458.0


def geodetic_to_ecef(lon_deg, lat_deg, h) -> np.ndarray:
    """(lon, lat) degrees and ellipsoidal height h (m) -> ECEF (..., 3) metres."""
    lon = np.radians(np.asarray(lon_deg, dtype=float))
    lat = np.radians(np.asarray(lat_deg, dtype=float))
    h = np.asarray(h, dtype=float)
    sl, cl = np.sin(lat), np.cos(lat)
    n = A / np.sqrt(1.0 - E2 * sl * sl)
    x = (n + h) * cl * np.cos(lon)
    y = (n + h) * cl * np.sin(lon)
    z = (n * (1.0 - E2) + h) * sl
    return np.stack(np.broadcast_arrays(x, y, z), axis=-1)


def ecef_to_geodetic(xyz) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """ECEF (..., 3) metres -> (lon deg, lat deg, ellipsoidal h m), closed form (Heikkinen).

    Exact to well below a millimetre for points above the Earth's core.
    """
    xyz = np.asarray(xyz, dtype=float)
    x, y, z = xyz[..., 0], xyz[..., 1], xyz[..., 2]
    p2 = x * x + y * y
    p = np.sqrt(p2)
    z2 = z * z
    f54 = 54.0 * B * B * z2
    g = p2 + (1.0 - E2) * z2 - E2 * (A * A - B * B)
    c = E2 * E2 * f54 * p2 / (g * g * g)
    s = np.cbrt(1.0 + c + np.sqrt(c * c + 2.0 * c))
    k = s + 1.0 + 1.0 / s
    pp = f54 / (3.0 * k * k * g * g)
    q = np.sqrt(1.0 + 2.0 * E2 * E2 * pp)
    r0 = -(pp * E2 * p) / (1.0 + q) + np.sqrt(
        np.maximum(0.5 * A * A * (1.0 + 1.0 / q) - pp * (1.0 - E2) * z2 / (q * (1.0 + q)) - 0.5 * pp * p2, 0.0))
    t = p - E2 * r0
    u = np.sqrt(t * t + z2)
    v = np.sqrt(t * t + (1.0 - E2) * z2)
    z0 = B * B * z / (A * v)
    h = u * (1.0 - B * B / (A * v))
    lat = np.degrees(np.arctan2(z + EP2 * z0, p))
    lon = np.degrees(np.arctan2(y, x))
    return lon, lat, h


def up_vector(lon_deg, lat_deg) -> np.ndarray:
    """Ellipsoid normal (local up) at (lon, lat) degrees as ECEF unit vectors (..., 3)."""
    lon = np.radians(np.asarray(lon_deg, dtype=float))
    lat = np.radians(np.asarray(lat_deg, dtype=float))
    cl = np.cos(lat)
    return np.stack(np.broadcast_arrays(cl * np.cos(lon), cl * np.sin(lon), np.sin(lat)), axis=-1)


def enu_rotation(lon0_deg: float, lat0_deg: float) -> np.ndarray:
    """3x3 matrix whose rows are east, north, up at (lon0, lat0): enu = R @ (ecef - origin)."""
    lon, lat = np.radians(lon0_deg), np.radians(lat0_deg)
    so, co, sa, ca = np.sin(lon), np.cos(lon), np.sin(lat), np.cos(lat)
    return np.array([[-so, co, 0.0],
                     [-sa * co, -sa * so, ca],
                     [ca * co, ca * so, sa]])


def enu_rotations(lon_deg, lat_deg) -> np.ndarray:
    """enu_rotation for many points at once: (n, 3, 3), rows east, north, up."""
    lon, lat = np.radians(np.asarray(lon_deg, dtype=float)), np.radians(np.asarray(lat_deg, dtype=float))
    so, co, sa, ca = np.sin(lon), np.cos(lon), np.sin(lat), np.cos(lat)
    zero = np.zeros_like(lon)
    return np.stack([np.stack([-so, co, zero], -1), np.stack([-sa * co, -sa * so, ca], -1),
                     np.stack([ca * co, ca * so, sa], -1)], axis=-2)


def geodetic_by_ecef(lon_deg, lat_deg, h) -> np.ndarray:
    """Derivatives (n, 3, 3) of (lon deg, lat deg, h m) by ECEF (x, y, z) m at geodetic points
    (n,): the east, north and up rows of :func:`enu_rotations` over the radii of the parallel
    ((N + h) cos lat) and of the meridian (M + h), in degrees per metre, and up (m per m)."""
    lat = np.radians(np.asarray(lat_deg, dtype=float))
    w2 = 1.0 - E2 * np.sin(lat) ** 2
    n = A / np.sqrt(w2)
    m = n * (1.0 - E2) / w2
    scale = np.stack(np.broadcast_arrays(np.degrees(1.0) / ((n + h) * np.cos(lat)), np.degrees(1.0) / (m + h),
                                         np.ones_like(lat)), axis=-1)
    return enu_rotations(lon_deg, lat_deg) * scale[..., None]


def ecef_to_enu(xyz, lon0_deg: float, lat0_deg: float, h0: float = 0.0) -> np.ndarray:
    """ECEF (..., 3) -> local east-north-up (..., 3) metres about (lon0, lat0, h0)."""
    origin = geodetic_to_ecef(lon0_deg, lat0_deg, h0)
    return (np.asarray(xyz, dtype=float) - origin) @ enu_rotation(lon0_deg, lat0_deg).T


def ray_height_intersection(origin, direction, h, newton_steps: int = 2) -> np.ndarray:
    """Distance s along unit rays ``origin + s*direction`` (ECEF, (n,3)) to the surface of
    ellipsoidal height h (m, (n,) or scalar), nearest intersection in front of the origin.

    Intersects the ellipsoid inflated by h (exact for h = 0, metres off otherwise), then
    refines with ``newton_steps`` Newton steps on the true geodetic height. Rays that miss,
    and origins on or below that surface (it is then met behind them or from inside), return NaN.
    """
    origin = np.asarray(origin, dtype=float)
    d = np.asarray(direction, dtype=float)
    h = np.broadcast_to(np.asarray(h, dtype=float), origin.shape[:-1])
    ah, bh = A + h, B + h
    w = np.stack([1.0 / ah, 1.0 / ah, 1.0 / bh], axis=-1)
    ow, dw = origin * w, d * w
    qa = np.einsum("...i,...i->...", dw, dw)
    qb = 2.0 * np.einsum("...i,...i->...", ow, dw)
    qc = np.einsum("...i,...i->...", ow, ow) - 1.0
    disc = qb * qb - 4.0 * qa * qc
    with np.errstate(invalid="ignore"):
        s = np.where(qc > 0, (-qb - np.sqrt(disc)) / (2.0 * qa), np.nan)
        s = np.where(s > 0, s, np.nan)
    for _ in range(newton_steps):
        p = origin + s[..., None] * d
        lon, lat, hp = ecef_to_geodetic(p)
        rate = np.einsum("...i,...i->...", d, up_vector(lon, lat))
        s = s - (hp - h) / rate
    return s
