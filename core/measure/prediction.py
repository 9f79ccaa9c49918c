"""Where the models put a raw image's pixels in the reference: the geometry of image matching.

The base image's pixels are mapped to the ground on the terrain surface through the base scene's
model and from there into the reference (an orthoimage's pixels, or another raw image through its
own scene's model): the reference resampled there is the reference in the base image's geometry,
the frame in which the two are compared (view angles, relief the surface holds, the images' scales
and rotations all taken out). Positions are reference array positions (x = column, y = row; pixel
centres at integers); base image positions are GDAL's (pixel centres at +0.5).
"""
from __future__ import annotations

from typing import Callable

import numpy as np
from scipy.ndimage import map_coordinates

from ..model.sensor import SceneModel

_LAGRANGE = lambda t: np.stack([t * (t - 1) / 2, 1 - t * t, t * (t + 1) / 2], axis=-1)  # noqa: E731
LATTICE_STEP = 8  # level pixels between the exact nodes of an extended map (linear between them)


def predicted_positions(scene: SceneModel, camera: int, surface, ref, col: np.ndarray, row: np.ndarray,
                        half: float, size: int, step: float,
                        warp: Callable | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Reference array positions (x, y), each (n, size, size), of the raw pixels
    p0 + step * (k - (size-1)/2), k = 0..size-1 (rows then cols) around the n points (col, row),
    through ``scene`` on ``surface``; and the ECEF ground (n, 3) of the points themselves. The
    map is exact at 3 x 3 nodes spaced ``half`` px and biquadratic between. NaN where a ray misses.

    ``warp``: the offsets (dc, dr) = warp(col, row) found so far (the raw image shows at p + d(p)
    what the models put at p). A window compared around p0 + d(p0) then holds at node q what the
    models put at q - (d(q) - d(p0)): the window is rectified at the current estimate, not at the
    surface alone, so the parallax of relief the surface lacks (a DSM's error, a flat HEIGHT over
    hills) no longer shears or stretches it; only the common offset d(p0) is left to find."""
    n = col.size
    d = np.array([-half, 0.0, half])
    nc = (col[:, None, None] + d[None, None, :]) + 0 * d[None, :, None]
    nr = (row[:, None, None] + d[None, :, None]) + 0 * d[None, None, :]
    if warp is not None:
        wc, wr = (v.reshape(n, 3, 3) for v in warp(nc.ravel(), nr.ravel()))
        nc, nr = nc - (wc - wc[:, 1:2, 1:2]), nr - (wr - wr[:, 1:2, 1:2])
    ground = scene.image_to_ground_dem(nc.ravel(), nr.ravel(), surface, camera)
    x, y = (v.reshape(n, 3, 3) for v in ref.ground_pixel(ground))
    w = _LAGRANGE(step * (np.arange(size) - (size - 1) / 2) / half)  # (size, 3)
    px = np.einsum("ia,jb,nab->nij", w, w, x)
    py = np.einsum("ia,jb,nab->nij", w, w, y)
    return px, py, ground.reshape(n, 9, 3)[:, 4]


def reference_scale(scene: SceneModel, camera: int, surface, ref) -> float:
    """Reference pixels per base pixel at the image centre (the larger of the two axes' scales): a
    reference of twice the base image's GSD gives 0.5."""
    cam = scene.cameras[camera]
    px, py, _ = predicted_positions(scene, camera, surface, ref, np.array([cam.cols / 2]),
                                    np.array([cam.rows / 2]), 8.0, 3, 8.0)
    scales = [np.hypot(px[0, 1, 2] - px[0, 1, 0], py[0, 1, 2] - py[0, 1, 0]) / 16,
              np.hypot(px[0, 2, 1] - px[0, 0, 1], py[0, 2, 1] - py[0, 0, 1]) / 16]
    scale = float(np.nanmax(scales)) if np.isfinite(scales).any() else 1.0
    return scale if scale > 0 else 1.0


def lattice_positions(scene: SceneModel, camera: int, surface, ref, col0: float, row0: float, step: float,
                      shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Reference array positions (x, y), each of ``shape`` (rows, cols), of the base image
    positions (col0 + step j, row0 + step i): exact every LATTICE_STEP nodes, linear between (the
    map is smooth at that scale: a coarse level's accuracy needs no more). The base image's model
    is extrapolated beyond its image (a search reaches past its edges). NaN where a ray misses."""
    rows, cols = shape
    ni, nj = (rows - 1) // LATTICE_STEP + 2, (cols - 1) // LATTICE_STEP + 2
    jj, ii = np.meshgrid(np.arange(nj) * LATTICE_STEP, np.arange(ni) * LATTICE_STEP)
    ground = scene.image_to_ground_dem(col0 + step * jj.ravel().astype(float), row0 + step * ii.ravel().astype(float),
                                       surface, camera)
    nodes = [v.reshape(ni, nj) for v in ref.ground_pixel(ground)]
    yy, xx = np.mgrid[0:rows, 0:cols] / LATTICE_STEP
    return tuple(map_coordinates(v, [yy, xx], order=1, mode="nearest") for v in nodes)
