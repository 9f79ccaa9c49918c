"""Observations of a block of scenes (stereo, tri-stereo, multi-date products adjusted together,
:mod:`core.adjust.block`): every row names the product it was measured in
(``GcpTable.scene``, ``TieTable.scene``). GCPs are checked against that product's model
alone (:func:`check_against_block`); :func:`scene_groups` tells which scenes the points join.

Frames and units as in :mod:`core.observations.gcps` (GDAL image px, WGS84 degrees, ellipsoidal m).
"""
from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from ..errors import InputError
from ..model.sensor import SceneModel
from .gcps import GcpTable, Residuals, apriori_residuals, assign_check_points
from .tables import resolve_cameras, rows_of_scenes, scene_of_rows

log = logging.getLogger(__name__)


def rpc_product_cameras(table, scene_of, scenes: dict):
    """``table`` (a GCP or tie table: ``camera`` (n,) str, a dataclass) with the rows measured in an
    RPC product of one image (:class:`core.model.rpcscene.RpcScene`; ``scene_of`` (n,) names each
    row's scene) given that image's camera, whatever their camera field says: an RPC product's
    camera is named after its file, while the tables of the simulator (and of a vendor) name the
    sensor's camera (NAD). Also the names of the scenes whose rows were renamed."""
    cameras = table.camera.astype(object)
    renamed = []
    rows_of = rows_of_scenes(scene_of, scenes)
    for name, scene in scenes.items():
        if scene.rpc_images() and len(scene.cameras) == 1:
            rows = rows_of[name]
            if (cameras[rows] != scene.cameras[0].name).any():
                renamed.append(name)
            cameras[rows] = scene.cameras[0].name
    return replace(table, camera=cameras.astype(str)), renamed


def check_against_block(table: GcpTable, scenes: dict[str, SceneModel], paths: dict[str, str],
                        camera: str | None = None, check_fraction: float = 0.0) -> GcpTable:
    """The table with every row checked against its own scene of ``scenes`` (name -> model; its
    file in ``paths``): cameras resolved within that scene (``camera``: one camera name or index
    for every row, as in :func:`core.observations.tables.resolve_cameras`), a-priori residuals
    (:class:`core.observations.gcps.Residuals`, px and m) through that scene's model, check points
    assigned over the whole block (:func:`core.observations.gcps.assign_check_points`). InputError
    naming the scene for a camera it lacks (parameter 'gcps.camera'; rows of an RPC product take its
    one image's camera, :func:`rpc_product_cameras`), and the errors of
    :func:`core.observations.tables.scene_of_rows` (parameter 'gcps.scene')."""
    scene_of = scene_of_rows(table.scene, table.id, scenes, parameter="gcps.scene")
    table, renamed = rpc_product_cameras(table, scene_of, scenes)
    for name in renamed:
        log.info("scene %s is an RPC product of one image: its rows are measurements in that image (camera %s)",
                 name, scenes[name].cameras[0].name)
    n = len(table)
    cameras = table.camera.astype(object)
    res = {k: np.full(n, np.nan) for k in ("col", "row", "px", "m")}
    inside = np.zeros(n, dtype=bool)
    for name, scene in scenes.items():
        rows = np.nonzero(scene_of == name)[0]
        if rows.size == 0:
            log.info("scene %s: no GCP measured in it", name)
            continue
        try:
            part = apriori_residuals(resolve_cameras(table.select(rows), scene, camera), scene, paths[name])
        except InputError as exc:
            raise InputError(f"scene {name}: {exc}", parameter="gcps.camera") from None
        cameras[rows] = part.camera
        for k in res:
            res[k][rows] = getattr(part.residuals, k)
        inside[rows] = part.residuals.inside
    checked = replace(table, camera=cameras.astype(str), scene=scene_of, scene_path="",
                      residuals=Residuals(res["col"], res["row"], res["px"], res["m"], inside))
    return assign_check_points(checked, check_fraction)


def scene_groups(scenes, ids, scene_of) -> list[list[str]]:
    """The groups of the block's scene names ``scenes`` (a sequence) that the points join: two
    scenes are in one group when a point (rows of one id in ``ids`` (n,) str, each measured in the
    scene ``scene_of`` (n,) names) is seen in both, or through a chain of such scenes. A scene in
    which no row is measured is a group of its own. Groups in the order of their first scene."""
    scenes = list(scenes)
    ids, scene_of = np.asarray(ids, dtype=str), np.asarray(scene_of, dtype=str)
    order = np.argsort(scenes)
    column = order[np.searchsorted(np.asarray(scenes)[order], scene_of)]
    _, point = np.unique(ids, return_inverse=True)
    seen = csr_matrix((np.ones(ids.size), (point, column)), shape=(point.max(initial=-1) + 1, len(scenes)))
    shared = (seen.T @ seen) > 0  # (scenes, scenes): a point seen in both
    _, label = connected_components(shared, directed=False)
    groups: dict[int, list[str]] = {}
    for name, k in zip(scenes, label.tolist()):
        groups.setdefault(k, []).append(name)
    return list(groups.values())
