"""The simulated ground's texture and the local plane it is defined on.

The texture is value noise (three octaves, smoothstep-interpolated hashed lattice values)
on a local metric plane around a centre (lon0, lat0):
    x = (lon - lon0) * 111320 cos(lat0),  y = (lat - lat0) * 110540     (metres)
with lattice cells of 4, 16 and 64 ground sample distances, so an image pixel always sees
a smooth texture. :func:`texture_at` gives its value anywhere on the ground. The raw images
(:mod:`simulation.render`), the reference orthoimage (:mod:`simulation.reference`), the roads
(:mod:`simulation.roads`) and the terrain (:mod:`simulation.terrain`) share this plane.
"""
from __future__ import annotations

import math

import numpy as np

from ..core.geodesy import ecef_to_geodetic
from ..core.model.sensor import SceneModel

OCTAVES = ((4.0, 0.25), (16.0, 0.35), (64.0, 0.40))  # (cell size in GSD, weight)
M_PER_DEG_LON = 111320.0  # m per degree of longitude on the equator (scaled by cos(lat0) on the plane)
M_PER_DEG_LAT = 110540.0  # m per degree of latitude


def texture_plane(lon, lat, centre: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """Local plane coordinates (x east, y north) in metres of (lon, lat) degrees."""
    return ((np.asarray(lon) - centre[0]) * M_PER_DEG_LON * math.cos(math.radians(centre[1])),
            (np.asarray(lat) - centre[1]) * M_PER_DEG_LAT)


def plane_to_lonlat(x, y, centre) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`texture_plane`: (lon, lat) degrees of plane coordinates (x, y) m."""
    return (centre[0] + np.asarray(x) / (M_PER_DEG_LON * math.cos(math.radians(centre[1]))),
            centre[1] + np.asarray(y) / M_PER_DEG_LAT)


def _lattice(i: np.ndarray, j: np.ndarray, seed: int) -> np.ndarray:
    """Pseudo-random values in [0, 1) at integer lattice nodes (i, j): an integer hash."""
    with np.errstate(over="ignore"):
        h = ((i.astype(np.uint64) * np.uint64(0x9E3779B97F4A7C15))
             ^ (j.astype(np.uint64) * np.uint64(0xC2B2AE3D27D4EB4F)))
        h ^= np.uint64(seed * 0x165667B19E3779F9 & 0xFFFFFFFFFFFFFFFF)
        h ^= h >> np.uint64(29)
        h *= np.uint64(0xBF58476D1CE4E5B9)
        h ^= h >> np.uint64(32)
    return (h >> np.uint64(40)).astype(np.float64) / float(1 << 24)


def texture(x, y, gsd: float, seed: int) -> np.ndarray:
    """Texture value in [0, 1] at plane coordinates (x, y) metres; any shape."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    out = np.zeros(np.broadcast(x, y).shape)
    for level, (cells, weight) in enumerate(OCTAVES):
        gx, gy = x / (cells * gsd), y / (cells * gsd)
        i, j = np.floor(gx), np.floor(gy)
        fx, fy = gx - i, gy - j
        wx, wy = fx * fx * (3 - 2 * fx), fy * fy * (3 - 2 * fy)
        ii, jj = i.astype(np.int64), j.astype(np.int64)
        s = seed * 4 + level
        top = _lattice(ii, jj, s) * (1 - wx) + _lattice(ii + 1, jj, s) * wx
        bottom = _lattice(ii, jj + 1, s) * (1 - wx) + _lattice(ii + 1, jj + 1, s) * wx
        out += weight * (top * (1 - wy) + bottom * wy)
    return out


def texture_at(lon, lat, centre: tuple[float, float], gsd: float, seed: int) -> np.ndarray:
    """Texture value in [0, 1] at ground (lon, lat) degrees."""
    return texture(*texture_plane(lon, lat, centre), gsd, seed)


def to_digital_numbers(value: np.ndarray) -> np.ndarray:
    """Texture values [0, 1] -> 8-bit digital numbers (20..235)."""
    return np.rint(20.0 + 215.0 * value).astype(np.uint8)


def texture_frame(scene: SceneModel, dem, seed: int) -> dict:
    """The texture's frame for a scene: centre (lon, lat) = the reference camera's image
    centre on the DEM, gsd_m = the scene's ground sample distance, and the seed."""
    cam = scene.cameras[0]
    centre = scene.image_to_ground_dem(np.array([cam.cols / 2]), np.array([cam.rows / 2]), dem, 0)
    lon, lat, _ = ecef_to_geodetic(centre)
    return {"centre": [float(lon[0]), float(lat[0])], "gsd_m": float(scene.info.get("gsd_m", 1.0)), "seed": seed}
