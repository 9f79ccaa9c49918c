"""Products derived from a scene model: footprints (ground outlines of each camera's image).

Frames and units: image outlines are GDAL (col, row); footprints are geodetic WGS84 rings
(longitude, latitude in degrees, ellipsoidal height in metres), closed (first point repeated
last) and counter-clockwise seen from above; areas are geodesic, in km².
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pyproj import Geod

from ..dem import no_height_words, surface_name
from ..model.camera import Camera
from ..errors import InputError
from ..geodesy import ecef_to_geodetic
from ..model.sensor import SceneModel

# Columns just left of a chip boundary belong to the chip that ends there (px).
_CHIP_EDGE = 1e-6


@dataclass
class Footprint:
    """Ground outline of one camera's image. lon, lat (deg), height (m, ellipsoidal): (m,).
    note: '' or what the outline left out (its points on a DEM's nodata holes)."""
    camera: str
    cols: int
    rows: int
    lon: np.ndarray
    lat: np.ndarray
    height: np.ndarray
    area_km2: float
    note: str = ""


def image_outline(camera: Camera, samples_per_edge: int = 256) -> tuple[np.ndarray, np.ndarray]:
    """(col, row) arrays (m,) tracing the image border once, closed (last = first).

    Each edge gets ``samples_per_edge`` intervals; the top and bottom edges also get both sides
    of every chip boundary, where staggered chips (imaging a row at different times) make the
    ground outline step.
    """
    n = max(int(samples_per_edge), 1)
    cuts = np.array([camera.chip_range(k)[0] for k in range(1, len(camera.chips))])
    across = np.unique(np.concatenate([np.linspace(0.0, camera.cols, n + 1), cuts, cuts - _CHIP_EDGE]))
    along = np.linspace(0.0, camera.rows, n + 1)[1:-1]
    col = np.concatenate([across, np.full(along.size, float(camera.cols)), across[::-1],
                          np.zeros(along.size), [0.0]])
    row = np.concatenate([np.zeros(across.size), along, np.full(across.size, float(camera.rows)),
                          along[::-1], [0.0]])
    return col, row


def footprints(scene: SceneModel, surface, cameras=None, samples_per_edge: int = 256) -> list[Footprint]:
    """Footprints of the given cameras (names or indices; all by default) on ``surface``.

    surface: core.dem.Dem or core.dem.ConstantHeight (ellipsoidal heights). Points of the outline
    whose lines of sight meet the DEM only on its nodata holes are left out (said in the
    footprint's ``note``); InputError naming the camera and the DEM when part of the outline lies
    off the DEM, or its lines of sight miss the Earth.
    """
    indices = range(len(scene.cameras)) if cameras is None else [scene.camera_index(c) for c in cameras]
    return [_footprint(scene, k, surface, samples_per_edge) for k in indices]


def _footprint(scene: SceneModel, k: int, surface, samples_per_edge: int) -> Footprint:
    cam = scene.cameras[k]
    col, row = image_outline(cam, samples_per_edge)
    coarse = _coarse_enough(scene, k, col, row, surface)
    ground = scene.image_to_ground_dem(col, row, coarse, camera=k)
    missing = ~np.all(np.isfinite(ground), axis=1)
    note = ""
    if missing.any():
        off, hole = rays_without_height(scene, k, col[missing], row[missing], coarse)
        words = surface_name(surface) + " " + no_height_words(int(missing.sum() - hole.sum()), int(hole.sum()),
                                                              col.size, "points of the image outline")
        if not hole.all() or (~missing).sum() < 4:
            raise InputError(f"camera {cam.name!r}: {words} (a DEM that does not cover the scene, or lines of sight "
                             "that miss the Earth); use a DEM covering the footprint, or a constant height")
        note = f"camera {cam.name!r}: {words}: the outline runs without them"
        ground = ground[~missing]
        ground = np.vstack([ground, ground[:1]]) if np.any(ground[0] != ground[-1]) else ground
    lon, lat, h = ecef_to_geodetic(ground)
    lon = _continuous_longitudes(lon)
    area, _ = Geod(ellps="WGS84").polygon_area_perimeter(lon, lat)
    if area < 0:  # clockwise: the image is seen mirrored (e.g. flying south); turn it round
        lon, lat, h = lon[::-1], lat[::-1], h[::-1]
    return Footprint(cam.name, cam.cols, cam.rows, lon, lat, h, abs(area) / 1e6, note)


def rays_without_height(scene: SceneModel, camera: int, col: np.ndarray, row: np.ndarray, surface,
                        samples: int = 17) -> tuple[np.ndarray, np.ndarray]:
    """Why image points (col, row) whose lines of sight met no height of ``surface`` got none:
    (off, hole) masks (n,), from ``samples`` points along each line of sight over the surface's
    height range: ``hole`` where one lies on a DEM's nodata holes, else ``off`` where one lies
    off its extent (neither: the line of sight misses the Earth)."""
    lo, hi = surface.height_range
    off, hole = np.zeros(col.shape, bool), np.zeros(col.shape, bool)
    for h in np.linspace(lo, hi, samples):
        ground = scene.image_to_ground(col, row, h, camera)
        met = np.all(np.isfinite(ground), axis=1)
        if met.any():
            lon, lat, _ = ecef_to_geodetic(ground[met])
            off_here, hole_here = surface.no_height(lon, lat)
            off[met] |= off_here
            hole[met] |= hole_here
    return off & ~hole, hole


def _coarse_enough(scene: SceneModel, k: int, col: np.ndarray, row: np.ndarray, surface):
    """The surface sampled at half the ground spacing of the outline's points (a DEM read no
    finer than that: a footprint needs the terrain under its vertices, not every metre)."""
    if not hasattr(surface, "with_spacing"):
        return surface
    flat = scene.image_to_ground(col, row, float(np.mean(surface.height_range)), camera=k)
    spacing = np.linalg.norm(np.diff(flat, axis=0), axis=1)
    spacing = spacing[np.isfinite(spacing) & (spacing > 0)]
    return surface.with_spacing(0.5 * float(np.median(spacing))) if spacing.size else surface


def _continuous_longitudes(lon: np.ndarray) -> np.ndarray:
    """Longitudes (deg) unwrapped around the first one, so a ring crossing ±180° stays whole."""
    return lon[0] + (lon - lon[0] + 180.0) % 360.0 - 180.0
