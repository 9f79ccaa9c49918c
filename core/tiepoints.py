"""Tie points: image observations of ground points whose coordinates are unknown.

One tie point is one ground point measured in two or more cameras of a scene (three-line
cameras) or in overlapping scenes of a strip; the adjustment estimates its ground position
(eliminated per point, like a weighted GCP's) starting from a forward intersection of the
onboard rays (:mod:`core.intersection`).

Conventions as in :mod:`core.gcps`: image coordinates are GDAL's (pixel centres at
half-integers), sigma_px is the image measurement sigma (px).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import InputError

DEFAULT_SIGMA_PX = 0.5


@dataclass
class TieTable:
    """Tie-point observations, parallel arrays of shape (n,): id (str; one id is one ground
    point), camera (camera name), col, row (GDAL px), sigma_px (px), scene (str: the scene of a
    strip the observation was measured in, '' when not stated; informational)."""
    id: np.ndarray
    camera: np.ndarray
    col: np.ndarray
    row: np.ndarray
    sigma_px: np.ndarray
    scene: np.ndarray
    ARRAYS = ("id", "camera", "col", "row", "sigma_px", "scene")

    def __post_init__(self):
        n = np.size(self.id)
        for name in self.ARRAYS:
            kind = str if name in ("id", "camera", "scene") else float
            setattr(self, name, np.broadcast_to(np.asarray(getattr(self, name), dtype=kind), (n,)).copy())
        if not (np.all(np.isfinite(self.col)) and np.all(np.isfinite(self.row))):
            raise InputError("tie-point image coordinates contain empty, NaN or infinite values")
        if not np.all(self.sigma_px > 0):
            raise InputError("tie-point image sigmas must be positive")

    def __len__(self) -> int:
        return int(self.id.size)

    def select(self, mask) -> "TieTable":
        return TieTable(*(getattr(self, name)[mask] for name in self.ARRAYS))

    def points(self) -> tuple[np.ndarray, np.ndarray]:
        """(ids (m,) sorted unique, index (n,) of each observation's point in ids)."""
        return np.unique(self.id, return_inverse=True)
