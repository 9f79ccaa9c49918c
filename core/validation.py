"""Plausibility checks of the values users and files give: terrain heights, image coordinates,
the spread of points over an image, nodata values. Every message names the value's source (a
file or parameter) and the value found. The checks of scene files: :mod:`core.formats.schema`.
"""
from __future__ import annotations

import math

import numpy as np

from .errors import InputError

# Ellipsoidal heights (m) terrain can have: the Dead Sea shore is about -410 m, Everest about
# 8820 m (ellipsoidal); the margins keep the padded height ranges of vendor products inside.
PLAUSIBLE_HEIGHTS = (-1000.0, 9000.0)
MAX_IMAGE_COORDINATE = 1e8  # px: no image is that large; beyond it a coordinate is a typo


def plausible_heights_text() -> str:
    """PLAUSIBLE_HEIGHTS in words, for messages."""
    return f"{PLAUSIBLE_HEIGHTS[0]:g} to {PLAUSIBLE_HEIGHTS[1]:g} m above the WGS84 ellipsoid"


def check_terrain_height(value: float, what: str) -> float:
    """A terrain height (m, ellipsoidal) given by the user; InputError naming ``what`` unless
    it is finite and within PLAUSIBLE_HEIGHTS (terrain, well below any orbit)."""
    v = float(value)
    if not (math.isfinite(v) and PLAUSIBLE_HEIGHTS[0] <= v <= PLAUSIBLE_HEIGHTS[1]):
        raise InputError(f"{what}: {value:g} m is not a terrain height (plausible: {plausible_heights_text()})")
    return v


def implausible_heights(h) -> np.ndarray:
    """Mask of heights (m) that are not finite or outside PLAUSIBLE_HEIGHTS."""
    h = np.asarray(h, dtype=float)
    with np.errstate(invalid="ignore"):
        return ~((h >= PLAUSIBLE_HEIGHTS[0]) & (h <= PLAUSIBLE_HEIGHTS[1]))


def check_surface_heights(height_range: tuple[float, float], what: str) -> None:
    """The (lowest, highest) heights of a DEM; InputError naming ``what`` when they are not
    terrain heights (a nodata value the file does not declare, feet, a wrong datum...)."""
    lo, hi = (float(v) for v in height_range)
    if implausible_heights([lo, hi]).any():
        raise InputError(f"{what}: heights from {lo:g} to {hi:g} m are not all terrain heights (plausible: "
                         f"{plausible_heights_text()}); is a nodata value not declared, or are the heights not in "
                         "metres?")


def implausible_image_coordinates(col, row) -> np.ndarray:
    """Mask of image coordinates (px) that are not finite or beyond any image."""
    col, row = np.asarray(col, dtype=float), np.asarray(row, dtype=float)
    with np.errstate(invalid="ignore"):
        return ~((np.abs(col) <= MAX_IMAGE_COORDINATE) & (np.abs(row) <= MAX_IMAGE_COORDINATE))


# The plausible range of each RPC offset and of each |scale| (degrees, metres, pixels), by RpcModel field:
# an RPC beyond them is a broken file (a typo, another format's field), not a scene on the Earth.
PLAUSIBLE_RPC = {"lat_off": (-90.0, 90.0), "lon_off": (-180.0, 360.0), "height_off": (-12000.0, 100000.0),
                 "line_off": (-MAX_IMAGE_COORDINATE, MAX_IMAGE_COORDINATE),
                 "samp_off": (-MAX_IMAGE_COORDINATE, MAX_IMAGE_COORDINATE),
                 "lat_scale": (0.0, 90.0), "lon_scale": (0.0, 180.0), "height_scale": (0.0, 100000.0),
                 "line_scale": (0.0, MAX_IMAGE_COORDINATE), "samp_scale": (0.0, MAX_IMAGE_COORDINATE)}


def rpc_value_problem(field: str, value: float) -> str | None:
    """Why an RPC offset or scale (RpcModel field ``field``: lat_off, line_scale, ...) is implausible,
    in words for a message naming the file and the key; None when it is plausible."""
    low, high = PLAUSIBLE_RPC[field]
    scale = field.endswith("_scale")
    if scale and not (value != 0 and math.isfinite(value)):
        return "a scale must be a non-zero number"
    if not (math.isfinite(value) and low <= (abs(value) if scale else value) <= high):
        return f"a plausible {'|scale|' if scale else 'value'} lies between {low:g} and {high:g}"
    return None


# Points must reach beyond this share of the image in one direction at least (below it in both
# they sit in one corner), and their second principal spread must exceed this share of the first
# (below it they lie on a line). The adjustment's control-point check uses the same rule.
MIN_IMAGE_SPAN = 0.1
MIN_SPREAD_RATIO = 0.01


def spread_problem(x, y, what: str) -> str | None:
    """Why points at image fractions x, y ((n,) 0..1: col / cols, row / rows) cannot hold an
    image's geometry, or None: all in one corner (span below MIN_IMAGE_SPAN across and along),
    or on a line. ``what`` names the points in the message ('the tie points')."""
    xy = np.stack([np.asarray(x, dtype=float), np.asarray(y, dtype=float)], axis=1)
    span = xy.max(axis=0) - xy.min(axis=0)
    if span[0] < MIN_IMAGE_SPAN and span[1] < MIN_IMAGE_SPAN:
        return (f"{what} cover only {100 * span[0]:.0f}% x {100 * span[1]:.0f}% of the image (one corner); "
                "spread them over the scene")
    singular = np.linalg.svd(xy - xy.mean(axis=0), compute_uv=False)
    if singular[1] < MIN_SPREAD_RATIO * singular[0]:
        return f"{what} lie on a line; the scene's rotation about it cannot be determined. Add points off that line."
    return None


def check_nodata(value: float, dtype) -> None:
    """A nodata value must be representable in the output data type ``dtype`` (numpy): a whole
    number in its range for integer types; NaN or a number in range for floating-point ones."""
    dtype = np.dtype(dtype)
    v = float(value)
    if np.issubdtype(dtype, np.integer):
        info = np.iinfo(dtype)
        if not (math.isfinite(v) and v.is_integer() and info.min <= v <= info.max):
            raise InputError(f"nodata value {value:g} cannot be stored in the output's data type {dtype.name} "
                             f"(the raw image's): whole numbers from {info.min} to {info.max}")
        return
    largest = float(np.finfo(dtype).max)
    if math.isinf(v) or abs(v) > largest:
        raise InputError(f"nodata value {value:g} cannot be stored in the output's data type {dtype.name} "
                         f"(the raw image's): NaN or numbers up to ±{largest:g}")


# --- the arrays of the core's functions ----------------------------------------------------------
# numpy broadcasts a (2,) array against a (1,) or a (3, 1) one without a word: a table built from
# lists of different lengths, or ground points of the wrong shape, would silently be something else.
MIN_GROUND_RADIUS = 5.0e6
"""m from the Earth's centre: ECEF ground points nearer than this (1400 km inside the Earth) are not
ECEF metres (a longitude/latitude/height, or kilometres)."""


def per_point(**arrays) -> list[np.ndarray]:
    """The arguments (name: a single value, or a sequence of one value per point) as 1-D arrays of one
    length n, in their order: single values repeated n times (n = 1 when all are single). InputError
    naming the arguments when their lengths differ, or one has more than one dimension."""
    values = {name: np.asarray(v) for name, v in arrays.items()}
    deep = {name: v.shape for name, v in values.items() if v.ndim > 1}
    if deep:
        raise InputError("; ".join(f"{name}: one value per point is expected, shape (n,), got {shape}"
                                   for name, shape in deep.items()))
    lengths = {name: v.size for name, v in values.items() if v.ndim == 1}
    if len(set(lengths.values())) > 1:
        raise InputError("arguments of different lengths: " + ", ".join(f"{name} {n}" for name, n in lengths.items())
                         + " (one value per point each, or a single value for all)")
    n = next(iter(lengths.values()), 1)
    return [np.full(n, v, dtype=v.dtype) if v.ndim == 0 else v for v in values.values()]


def ground_points(xyz, name: str = "xyz") -> np.ndarray:
    """ECEF ground points (m) as a float array (n, 3) from an array of that shape, or one point of
    shape (3,) (taken as (1, 3)). InputError naming the argument ``name`` for any other shape, NaN or
    infinite values, and points within MIN_GROUND_RADIUS of the Earth's centre."""
    p = np.asarray(xyz, dtype=float)
    if p.shape == (3,):
        p = p[None]
    if p.ndim != 2 or p.shape[1] != 3:
        raise InputError(f"{name}: ground points are ECEF coordinates of shape (n, 3), or one point (3,); got shape "
                         f"{p.shape}")
    if not np.all(np.isfinite(p)):
        raise InputError(f"{name}: ground coordinates contain NaN or infinite values")
    near = np.nonzero(np.linalg.norm(p, axis=1) < MIN_GROUND_RADIUS)[0]
    if near.size:
        raise InputError(f"{name}: {near.size} point(s) (index {', '.join(map(str, near[:5]))}) lie within "
                         f"{MIN_GROUND_RADIUS / 1e3:.0f} km of the Earth's centre: ground points are ECEF metres "
                         "(EPSG:4978), not longitude, latitude and height, nor kilometres")
    return p
