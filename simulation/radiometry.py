"""How an acquisition's digital numbers differ from the ground texture's: gain, offset, gamma,
noise and patches of changed land cover. The reference orthoimage (:mod:`simulation.reference`)
and the images of a block's later dates (:mod:`simulation.block`) use them, so that matching
works across them as across a real archive.

Digital numbers (DN, 8 bits) of texture values v in [0, 1] (:mod:`simulation.texture`):
    DN = offset + gain * (20 + 215 * clip(v, 0, 1) ** gamma) + noise
Changed land cover: inside a disc, the texture of another seed (seed + CHANGED_SEED_OFFSET: other
ground, the same statistics). Discs are (x, y, radius) in metres of a plane: the texture plane for
raw images, UTM for the reference.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from .texture import texture

CHANGED_SEED_OFFSET = 7919   # texture seed of changed land cover: another ground, same statistics


def patches(extent: tuple[float, float, float, float], share: float, radius: tuple[float, float],
            rng: np.random.Generator) -> np.ndarray:
    """(n, 3) discs (x, y, radius; m) covering about ``share`` of the extent (xmin, ymin, xmax, ymax) m."""
    xmin, ymin, xmax, ymax = extent
    mean_area = math.pi * (radius[0] ** 2 + radius[0] * radius[1] + radius[1] ** 2) / 3.0
    n = int(round(share * (xmax - xmin) * (ymax - ymin) / mean_area))
    return np.stack([rng.uniform(xmin, xmax, n), rng.uniform(ymin, ymax, n),
                     rng.uniform(radius[0], radius[1], n)], axis=1)


def disc_weight(x: np.ndarray, y: np.ndarray, discs: np.ndarray, soft: bool) -> np.ndarray:
    """Largest weight of the discs at (x, y) (m, any equal shapes): 1 inside a disc (``soft``: a
    Gaussian-like fade to 0 at its radius, for clouds), 0 outside all."""
    w = np.zeros(np.shape(x), np.float32)
    if not len(discs) or not np.size(x):
        return w
    x_lo, x_hi, y_lo, y_hi = np.min(x), np.max(x), np.min(y), np.max(y)
    for cx, cy, r in discs:  # a few hundred discs at most; each touches a few tiles
        if cx + r < x_lo or cx - r > x_hi or cy + r < y_lo or cy - r > y_hi:
            continue
        d2 = ((x - cx) ** 2 + (y - cy) ** 2) / (r * r)
        w = np.maximum(w, np.clip(1.0 - d2, 0.0, 1.0) ** 2 if soft else (d2 <= 1.0))
    return w


def radiometric_dn(value, gain: float, offset: float, gamma: float) -> np.ndarray:
    """DN (float, before noise and rounding) of texture values (any shape) in [0, 1]."""
    return offset + gain * (20.0 + 215.0 * np.clip(value, 0.0, 1.0) ** gamma)


@dataclass(frozen=True)
class Radiometry:
    """An acquisition's radiometry (see the module docstring): gain, offset (DN), gamma, noise
    (DN, standard deviation), changed (n, 3) discs of changed land cover on the texture plane (m;
    a tuple of (x, y, radius) tuples), seed of the noise."""
    gain: float = 1.0
    offset: float = 0.0
    gamma: float = 1.0
    noise: float = 0.0
    changed: tuple = ()
    seed: int = 0

    def change(self, x: np.ndarray, y: np.ndarray, value: np.ndarray, gsd: float, texture_seed: int) -> np.ndarray:
        """Texture values ``value`` at plane points (x, y) m with the changed land cover in place."""
        if not self.changed:
            return value
        inside = disc_weight(x, y, np.asarray(self.changed, dtype=float), soft=False) > 0
        if not inside.any():
            return value
        value = np.array(value, copy=True)
        value[inside] = texture(x[inside], y[inside], gsd, texture_seed + CHANGED_SEED_OFFSET)
        return value

    def digital_numbers(self, value: np.ndarray, key: tuple[int, ...]) -> np.ndarray:
        """8-bit DN of texture values; the noise is drawn from (seed, *key), so that a tile
        (key: its first row and chip) gets the same noise whatever order tiles are rendered in."""
        dn = radiometric_dn(value, self.gain, self.offset, self.gamma)
        if self.noise > 0:
            dn = dn + np.random.default_rng([self.seed, *key]).normal(0.0, self.noise, dn.shape)
        return np.clip(np.rint(dn), 0, 255).astype(np.uint8)

    def as_dict(self) -> dict:
        """JSON-ready description (the manifest's)."""
        out = asdict(self)
        out["changed"] = [[round(float(v), 1) for v in disc] for disc in self.changed]
        return out


def draw_radiometry(rng: np.random.Generator, extent: tuple[float, float, float, float], seed: int,
                    changed_share: float = 0.05, patch_radius: tuple[float, float] = (100.0, 400.0)) -> Radiometry:
    """Radiometry of another date: gain U(0.75, 1.25), offset U(-15, 15) DN, gamma U(0.8, 1.25),
    noise U(0.5, 2) DN, and discs of changed land cover over about ``changed_share`` of ``extent``
    (texture plane, m) with radii in ``patch_radius`` (m)."""
    gain, offset, gamma, noise = (float(rng.uniform(0.75, 1.25)), float(rng.uniform(-15.0, 15.0)),
                                  float(rng.uniform(0.8, 1.25)), float(rng.uniform(0.5, 2.0)))
    discs = patches(extent, changed_share, patch_radius, rng)
    return Radiometry(gain, offset, gamma, noise, tuple(tuple(float(v) for v in d) for d in discs), seed)
