"""The terrain surface image matching projects its windows on: the DEM where it has heights, an
estimated height in its holes.

A DSM cut from stereo holds NaN or nodata where it saw nothing (water, shadow, the edge of its
coverage). A window whose rays fall in such a hole cannot be projected on the DEM, but its grid
point can still be matched: the prediction only has to bring the other image's window within the
search radius, which a height near the terrain's does. :class:`FilledSurface` gives the DEM's
height where it has one and the estimated height (the median of the DEM's heights under the image)
elsewhere, and tells which ground points lie in a hole, so that the matcher counts them: a tie
point is matched there at the estimated height (its ground is intersected later, by the
adjustment), a GCP is rejected ('no DEM height': its height would be a guess).
"""
from __future__ import annotations

import numpy as np

from ..dem import missing_heights, surface_name
from ..errors import InputError
from ..geodesy import ecef_to_geodetic
from ..model.sensor import SceneModel

SAMPLES = 33  # points per side of the image grid whose DEM heights give the estimated height


class FilledSurface:
    """``dem`` (core.dem.Dem or ConstantHeight: ``height(lon, lat)`` in ellipsoidal metres, NaN where
    it has none, ``no_height`` and ``height_range``) with its holes filled at ``estimate`` (m, ellipsoidal)."""

    def __init__(self, dem, estimate: float):
        self.dem, self.estimate = dem, float(estimate)
        self.path = getattr(dem, "path", None)

    def height(self, lon, lat) -> np.ndarray:
        h = np.asarray(self.dem.height(lon, lat), dtype=float)
        return np.where(np.isfinite(h), h, self.estimate)

    @property
    def height_range(self) -> tuple[float, float]:
        lo, hi = self.dem.height_range
        return min(lo, self.estimate), max(hi, self.estimate)

    def in_hole(self, ground: np.ndarray) -> np.ndarray:
        """(n,) whether the DEM gives no height under the ECEF points ``ground`` (n, 3): off its
        extent or on its nodata holes (:meth:`core.dem.Dem.no_height`); False where ``ground`` is
        not finite."""
        out = np.zeros(len(ground), bool)
        finite = np.isfinite(ground).all(axis=1)
        if finite.any():
            lon, lat, _ = ecef_to_geodetic(ground[finite])
            off, hole = self.dem.no_height(lon, lat)
            out[finite] = off | hole
        return out

    def missing(self, ground: np.ndarray, what: str) -> str:
        """'' when the DEM gives a height under every finite ECEF point of ``ground`` (n, 3), else
        :func:`core.dem.missing_heights`'s sentence: for how many of the ``what`` it gives none, off
        its extent or on its holes."""
        lon, lat, _ = ecef_to_geodetic(ground[np.isfinite(ground).all(axis=1)])
        return missing_heights(self.dem, lon, lat, what)


def filled_surface(scene: SceneModel, camera: int, dem) -> FilledSurface:
    """``dem`` filled at the median of its heights under a SAMPLES x SAMPLES grid over the image
    of ``camera`` (where the rays meet the middle of the DEM's height range: the median needs no
    more). InputError naming the DEM when it gives no height under any of them (it does not cover
    the scene)."""
    cam = scene.cameras[camera]
    col, row = (v.ravel() for v in np.meshgrid(np.linspace(0.5, cam.cols - 0.5, SAMPLES),
                                               np.linspace(0.5, cam.rows - 0.5, SAMPLES)))
    lo, hi = dem.height_range
    ground = scene.image_to_ground(col, row, np.full(col.size, (lo + hi) / 2), camera)
    finite = np.isfinite(ground).all(axis=1)
    heights = np.full(col.size, np.nan)
    if finite.any():
        lon, lat, _ = ecef_to_geodetic(ground[finite])
        heights[finite] = dem.height(lon, lat)
    heights = heights[np.isfinite(heights)]
    if heights.size == 0:
        raise InputError(f"{surface_name(dem)} gives no height under the image of camera {cam.name}: it does not cover "
                         "the scene (or holds only nodata there). Use a DEM covering the footprint, or a constant "
                         "height")
    return FilledSurface(dem, float(np.median(heights)))
