"""The checks a match passes beyond its correlation peak (:mod:`core.measure.matching`): every chip
it compares lies within one CCD chip, and its offset agrees with its neighbours'.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

NEIGHBOURS = 8             # matches of the same chip whose offsets a match is compared with
INCONSISTENT_PX = 1.0      # px: a match this far (at least) from its neighbours' median offset is rejected
INCONSISTENT_SIGMAS = 5.0  # ... or this many robust sigmas of all matches' distances, if that is more


def within_one_chip(cam, first: np.ndarray, last: np.ndarray) -> np.ndarray:
    """(n,) whether the image columns ``first`` to ``last`` (pixel centres, either order) all come
    from one CCD chip of ``cam`` (always for a single-chip camera)."""
    return cam.chip_index(np.minimum(first, last)) == cam.chip_index(np.maximum(first, last))


def inconsistent(cam, col: np.ndarray, row: np.ndarray, mcol: np.ndarray, mrow: np.ndarray,
                 ok: np.ndarray) -> np.ndarray:
    """(n,) the matches ``ok`` whose offset (matched (mcol, mrow) minus grid point (col, row), px)
    lies farther than INCONSISTENT_PX (or INCONSISTENT_SIGMAS robust sigmas, 1.4826 MAD, of all
    those distances if that is more) both from the median offset of their NEIGHBOURS nearest
    matches on the same chip and from the plane fitted to those neighbours' offsets. The onboard
    model's error varies smoothly over a chip (a few hundredths of a pixel between neighbouring
    grid points, a few tenths where the terrain height jumps), so a match that disagrees with its
    neighbours by a pixel or more found another place (repeated texture, a cloud edge): the
    adjustment would only flag it later, and as a check point it would count as a blunder. The
    plane keeps what the median alone would throw away: the parallax of a slope the surface
    lacks (a pyramid's face on a flat HEIGHT) grows steadily across the grid, pixels from one
    point to the next, and its neighbours' plane predicts it."""
    out = np.zeros(col.size, bool)
    idx = np.nonzero(ok)[0]
    if idx.size <= NEIGHBOURS:
        return out
    offset = np.stack([mcol[idx] - col[idx], mrow[idx] - row[idx]], axis=1)
    chip = cam.chip_index(mcol[idx])
    distance = np.full(idx.size, np.nan)
    for k in np.unique(chip):
        mine = np.nonzero(chip == k)[0]
        if mine.size <= NEIGHBOURS:
            continue
        xy = np.stack([col[idx[mine]], row[idx[mine]]], axis=1)
        _, near = cKDTree(xy).query(xy, NEIGHBOURS + 1)
        others = offset[mine][near[:, 1:]]                       # (m, NEIGHBOURS, 2): the neighbours' (not its own)
        median = np.median(others, axis=1)
        planar = plane_at(xy, xy[near[:, 1:]], others)
        distance[mine] = np.minimum(np.hypot(*(offset[mine] - median).T), np.hypot(*(offset[mine] - planar).T))
    known = np.isfinite(distance)
    if not known.any():
        return out
    limit = max(INCONSISTENT_PX, INCONSISTENT_SIGMAS * 1.4826 * float(np.median(distance[known])))
    out[idx[known & (distance > limit)]] = True
    return out


def plane_at(xy: np.ndarray, points: np.ndarray, values: np.ndarray) -> np.ndarray:
    """(m, 2) the planes a + b x + c y fitted by least squares to ``values`` (m, k, 2) at
    ``points`` (m, k, 2) (px), evaluated at xy (m, 2)."""
    rel = (points - xy[:, None, :]) / 100.0                        # scaled: a well-conditioned design
    design = np.concatenate([np.ones(rel.shape[:2] + (1,)), rel], axis=2)
    normal = np.einsum("mki,mkj->mij", design, design) + 1e-9 * np.eye(3)
    return np.linalg.solve(normal, np.einsum("mki,mkc->mic", design, values))[:, 0, :]
