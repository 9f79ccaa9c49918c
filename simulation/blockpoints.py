"""Ground points of a block of scenes (:mod:`simulation.block`): where the scenes overlap, control,
check and tie points placed uniformly over the ground they cover and measured in every camera of
every scene that sees them.

Frames: ECEF metres for ground points, (lon, lat) degrees and ellipsoidal heights (m) on the DEM,
image coordinates GDAL (col, row). Every array operation runs over all points at once; loops run
over scenes and cameras only.
"""
from __future__ import annotations

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from ..core.errors import InputError
from ..core.geodesy import geodetic_to_ecef
from ..core.model.sensor import SceneModel
from .geometry import scene_bounds
from .measurements import GcpSettings, add_ground_columns, measure_points, observe, point_ids

POOL = 4000          # candidate ground points drawn at a time
MAX_ROUNDS = 25      # draws of candidates before giving up on finding enough shared ground


def block_bounds(scenes: list[SceneModel], margin_deg: float = 0.02) -> tuple[float, float, float, float]:
    """(lon_min, lat_min, lon_max, lat_max) degrees around every camera image of every scene, at
    the ends of each scene's height range, widened by margin_deg (:func:`simulation.geometry.scene_bounds`)."""
    boxes = np.array([scene_bounds(s, tuple(s.height_range), margin_deg) for s in scenes])
    return (float(boxes[:, 0].min()), float(boxes[:, 1].min()), float(boxes[:, 2].max()), float(boxes[:, 3].max()))


def visibility(scenes: list[SceneModel], ground: np.ndarray) -> np.ndarray:
    """(n scenes, n points) bool: whether any camera of each scene sees each ECEF point (n, 3) inside its image."""
    seen = np.zeros((len(scenes), ground.shape[0]), bool)
    for m, scene in enumerate(scenes):
        for _, idx, _, _ in observe(scene, ground):
            seen[m, idx] = True
    return seen


def _candidates(dem, box: tuple[float, float, float, float], n: int, rng: np.random.Generator) -> np.ndarray:
    """ECEF points (n, 3) on the DEM at (lon, lat) uniform in ``box`` (a few km: uniform in area)."""
    lon = rng.uniform(box[0], box[2], n)
    lat = rng.uniform(box[1], box[3], n)
    return geodetic_to_ecef(lon, lat, dem.height(lon, lat))


def check_common_ground(names: list[str], seen: np.ndarray) -> None:
    """InputError unless the scenes' overlaps link them all into one block: each scene shares
    ground with another, and no group of scenes stands apart. ``seen``: :func:`visibility` of
    candidate points spread over the block."""
    if len(names) < 2:
        return
    shared = (seen.astype(np.int64) @ seen.T.astype(np.int64)) > 0
    count, label = connected_components(csr_matrix(shared), directed=False)
    if count > 1:
        groups = [[n for n, lab in zip(names, label) if lab == g] for g in range(count)]
        raise InputError("the block's members share no common ground: " + " | ".join(", ".join(g) for g in groups)
                         + " image separate ground (aim their views or orbit offsets at one area)",
                         parameter="members")


def place_block_points(scenes: list[SceneModel], names: list[str], dem, box, n_gcps: int, n_ties: int,
                       rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(GCP ground (n_gcps, 3), tie ground (n_ties, 3)) ECEF points on the DEM, uniform over the
    block: GCPs where at least one scene sees them, tie points where at least two do; distinct
    points. Checks first that the scenes share ground (:func:`check_common_ground`)."""
    pools, seens = [], []
    n_seen1 = n_seen2 = 0
    for rounds in range(MAX_ROUNDS):
        ground = _candidates(dem, box, POOL, rng)
        seen = visibility(scenes, ground)
        if rounds == 0:
            check_common_ground(names, seen)
        pools.append(ground)
        seens.append(seen)
        # Even candidates may become tie points, odd ones GCPs: each set a uniform sample of its
        # own ground (taking ties first from one pool would leave GCPs the ground seen once).
        count = seen.sum(axis=0)
        n_seen1 += int((count[1::2] >= 1).sum())
        n_seen2 += int((count[0::2] >= 2).sum())
        if n_seen2 >= n_ties and n_seen1 >= n_gcps:
            break
    else:
        raise InputError(f"the block's members share too little ground for {n_ties} tie points and {n_gcps} GCPs "
                         f"({n_seen2} of {POOL * MAX_ROUNDS // 2} candidate points are seen by two scenes)",
                         parameter="n_tie_points")
    ground, count = np.concatenate(pools), np.concatenate(seens, axis=1).sum(axis=0)
    # The candidates are in random order: the first eligible ones are a uniform sample.
    even = np.arange(count.size) % 2 == 0
    ties = np.nonzero(even & (count >= 2))[0][:n_ties]
    gcps = np.nonzero(~even & (count >= 1))[0][:n_gcps]
    return ground[gcps], ground[ties]


def measure_block(scenes: list[SceneModel], names: list[str], ground: np.ndarray, ids: np.ndarray,
                  settings: GcpSettings, rng: np.random.Generator) -> dict:
    """:func:`simulation.measurements.measure_points` in every scene (its true model) that sees the
    points, concatenated: one row per scene and camera seeing a point, a 'scene' column of the
    scene names, '_index' the row's point in ``ground``."""
    parts = []
    for scene, name in zip(scenes, names):
        part = measure_points(scene, ground, ids, settings, rng)
        part["scene"] = np.full(part["id"].size, name)
        parts.append(part)
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}


def block_gcp_columns(scenes, names, ground: np.ndarray, settings: GcpSettings, rng: np.random.Generator) -> dict:
    """The GCP CSV columns (:data:`simulation.measurements.GCP_COLUMNS`) of ground points (n, 3) ECEF:
    ids G1..Gn, the same in every scene; ground noise and role drawn once per point."""
    data = measure_block(scenes, names, ground, point_ids("G", ground.shape[0]), settings, rng)
    add_ground_columns(data, ground, settings, rng)
    return data


def block_tie_columns(scenes, names, ground: np.ndarray, settings: GcpSettings, rng: np.random.Generator) -> dict:
    """The tie-point CSV columns (:data:`simulation.measurements.TIE_COLUMNS`) of ground points (n, 3)
    ECEF: ids T1..Tn, the same in every scene."""
    data = measure_block(scenes, names, ground, point_ids("T", ground.shape[0]), settings, rng)
    data.pop("_index")
    return data
