"""Tie points triangulated through a block's RPC scenes, and how their heights changed: the median
and the tilt of a plane fitted to the change (tests/scenarios/test_real_datum.py,
tests/bench/bench_rpc_datum.py)."""
from __future__ import annotations

import numpy as np

from pushbroom_adjust.core.geodesy import ecef_to_geodetic, enu_rotation, geodetic_to_ecef
from pushbroom_adjust.core.model.intersection import intersect
from pushbroom_adjust.core.model.mixedblock import compose_mixed


def tie_heights(scenes: dict, ties) -> tuple[np.ndarray, np.ndarray]:
    """(ids (m,) sorted, ground (m, 3) lon, lat (deg), h (m)) of the tie points of ``ties`` (their
    scene column naming ``scenes``, name -> RPC scene) intersected through ``scenes``."""
    block = compose_mixed(scenes)
    names = [c.name for c in block.cameras]
    camera = np.array([names.index(f"{s}/{scenes[s].cameras[0].name}") for s in ties.scene])
    ids, point = np.unique(ties.id, return_inverse=True)
    out = intersect(block, camera, ties.col, ties.row, point, ids.size)
    return ids, np.stack(ecef_to_geodetic(out.ground), axis=1)


def height_change(ground: np.ndarray, dh: np.ndarray, along: np.ndarray | None = None) -> dict:
    """The height change dh (m,) m at the points ``ground`` (m, 3 lon, lat, h): its median, and the
    plane fitted to it by least squares over the points' east and north: ``tilt_m`` its height
    difference across the points' extent along its steepest direction, and with ``along`` (2,) an
    east, north unit vector, ``along_m`` and ``across_m`` across their extent along and across it."""
    ok = np.isfinite(dh)
    lon, lat = np.median(ground[ok, 0]), np.median(ground[ok, 1])
    xyz = geodetic_to_ecef(ground[ok, 0], ground[ok, 1], ground[ok, 2]).reshape(-1, 3)
    en = ((xyz - xyz.mean(axis=0)) @ enu_rotation(lon, lat).T)[:, :2]
    gradient = np.linalg.lstsq(np.c_[np.ones(en.shape[0]), en], dh[ok], rcond=None)[0][1:]
    steepest = gradient / max(float(np.linalg.norm(gradient)), 1e-12)
    out = {"median_m": float(np.median(dh[ok])), "tilt_m": float(np.linalg.norm(gradient) * np.ptp(en @ steepest))}
    if along is not None:
        across = np.array([-along[1], along[0]])
        out["along_m"] = float(gradient @ along * np.ptp(en @ along))
        out["across_m"] = float(gradient @ across * np.ptp(en @ across))
    return out
