"""Bundle adjustment of a block of independent scenes (stereo pair, tri-stereo, multi-date,
neighbouring orbits; rigorous scenes and RPC products mixed) as one: :func:`adjust_block`.

Route: the block is one composite scene (:func:`core.model.mixedblock.compose_mixed`; of rigorous
scenes alone :func:`core.model.block.compose_block`: every scene's cameras renamed
``<scene>/<camera>``, each looking through its own scene's platform, times from its own scene's
epoch), adjusted by the single-scene engine (:func:`core.adjust.engine.adjust`) unchanged in its
stages, and split back into one adjusted scene per input
(:func:`core.model.mixedblock.split_scenes`). Each member answers for its own kind
(:mod:`core.model.kinds`): no step asks whether it holds a rigorous scene or an RPC product. The
engine's parameters already group cameras into trajectory corrections
(:func:`core.adjust.parameters.trajectory_groups`): one per measured trajectory, i.e. one per scene
of the block (``camera_trajectory='shared'``) on a time basis over that scene's own lines with its
own onboard pseudo-observations, or one per camera (``'per_camera'``); interior and installation
parameters per camera as the settings ask (camera names carry the scene: ``INTERIOR=B/FWD.roll``).
Ground points (GCPs and tie points) are shared unknowns across scenes, eliminated from the normal
equations as in one scene. This reuses the determinability checks, Levenberg-Marquardt, robust
estimation, variance components, check points, the report and the written-vs-fitted check (which
writes and reads back each scene of the block), where composing per-scene normal equations (the
other route) would have had to repeat each of those stages for a block.

RPC scenes (:class:`core.model.rpcscene.RpcScene`, any number, with or without rigorous scenes):
the block is then a :class:`core.model.mixedblock.MixedBlock` (the rigorous scenes' composite and
the RPC images, cameras named ``<scene>/<camera>`` alike) adjusted by the same engine through
:class:`core.adjust.blockproblem.BlockProblem`: each RPC image keeps its own image-space correction
(Grodecki & Dial 2003; RPC_CORRECTION shift, drift or affine, parameters ``<scene>/<camera>.a0``
...), the rigorous scenes their trajectory and interior blocks, and the ground points are shared as
above, so tie points join RPC images with each other and with rigorous scenes. Each adjusted RPC
scene is written as a single RPC scene's adjustment is (scene JSON; a refined RPC by
:func:`core.products.rpcfit.refined_rpcs` of :attr:`BlockResult.scenes`).

Observations name their scene: ``GcpTable.scene``, ``TieTable.scene`` and
``ImageLines.scene`` (a block of one scene may leave them empty). Cameras are resolved within the
scene (a single-camera scene's and an RPC scene's empty camera is its camera).

Control lines (Tommaselli & Marcato Junior 2012, :mod:`core.adjust.linepoints`): each image line
names the scene it was measured in; its camera becomes the composite's ``<scene>/<camera>`` and
the ground lines are shared by all scenes (one road seen in two products holds both, as a ground
point does), so the engine adjusts them as in one scene. Lines need rigorous scene models: a block
with RPC products and lines is refused, naming the products.

Datum: with tie points and no GCPs nothing but the priors holds where the block is: the onboard
pseudo-observations of the rigorous scenes (POSITION_SIGMA, ATTITUDE_SIGMA) and the RPC images'
stated accuracy (RPC_SIGMA, settings.rpc_sigma: a pseudo-observation on every correction term, as
the onboard sigmas are of the trajectories). The report's ``datum`` names which, and the block then
lies within those sigmas of where the onboard data and the vendor RPCs put it. A block of RPC
images tied without GCPs and without RPC_SIGMA has a datum defect (free image shifts of every
image together move the whole block): refused, naming settings.rpc_sigma.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field, replace
from typing import Callable, NamedTuple

import numpy as np

from ..errors import InputError
from ..model.block import SEPARATOR, block_camera
from ..model.intersection import MIN_CONVERGENCE, onboard_rays
from ..model.mixedblock import MixedBlock, compose_mixed, split_scenes
from ..model.rpcscene import RpcScene
from ..model.sensor import SceneModel
from ..observations.gcps import GcpTable
from ..observations.tables import listed, resolve_cameras, rows_of_scenes, stripped
from ..observations.tiepoints import TieTable
from .engine import adjust
from .linepoints import ControlLines
from .blockreport import block_report
from .report_types import BlockReport
from .results import AdjustmentResult
from .scenesigmas import check_scene_sigmas
from .settings import AdjustmentSettings
from .ties import camera_indices

log = logging.getLogger(__name__)

# deg: tie points whose onboard rays are all closer than this meet at a weakly determined height
# (seen from one direction only, e.g. by the nadir cameras of scenes from one orbit): the angle below
# which the intersection does not fix a point's height (core.model.intersection.MIN_CONVERGENCE)
MIN_CONVERGENCE_DEG = float(np.degrees(MIN_CONVERGENCE))


@dataclass
class BlockResult:
    """scenes: the adjusted scenes (name -> SceneModel or RpcScene, the block's order), each writable
    with :func:`core.formats.scene_json.save_scene`; report: the block's figures and its adjustment's
    (:class:`core.adjust.report_types.BlockReport`, :func:`core.adjust.blockreport.block_report`);
    tie_points: per tie point (m,) arrays id, lon, lat (deg), h (ellipsoidal m) of its adjusted
    ground (NaN for points left out), rays (observations used), scenes (scenes it was seen in),
    convergence_deg (the largest angle between its onboard rays, :func:`ray_convergence`);
    adjustment: the composite's :class:`AdjustmentResult` (per-observation arrays, camera names
    ``<scene>/<camera>``, the full engine report); line_points: the engine's per line point arrays
    (:attr:`AdjustmentResult.lines`) with ``camera`` the scene's own camera name and ``scene`` (n,)
    the scene each point was measured in (empty without control lines)."""
    scenes: dict[str, SceneModel | RpcScene]
    report: BlockReport
    tie_points: dict
    adjustment: AdjustmentResult
    line_points: dict = field(default_factory=dict)


def _scene_column(names: np.ndarray, ids: np.ndarray, scenes: dict, what: str, kind: str = "point") -> np.ndarray:
    """The scene name of every row (n,) str: '' allowed for a block of one scene; InputError
    naming the unknown scenes (and their ``kind``: points or lines) or the rows without one."""
    names = stripped(names)
    if len(scenes) == 1:
        names = np.where(names == "", next(iter(scenes)), names)
    missing = names == ""
    if missing.any():
        raise InputError(f"{what}: {kind}(s) {listed(np.unique(ids[missing]))} have no scene; in a block of "
                         f"{len(scenes)} scenes ({', '.join(scenes)}) every observation names its scene",
                         parameter=what)
    unknown = ~np.isin(names, list(scenes))
    if unknown.any():
        raise InputError(f"{what}: scene(s) {listed(np.unique(names[unknown]))} of {kind}(s) "
                         f"{listed(np.unique(ids[unknown]))} not in the block (scenes: {', '.join(scenes)})",
                         parameter=what)
    return names


def _block_cameras(table, scene_of: np.ndarray, scenes: dict):
    """``table`` (GCP or tie) with each row's camera resolved in its own scene and renamed to the
    composite's ``<scene>/<camera>``."""
    cameras = np.array(table.camera, dtype=object)
    rows = rows_of_scenes(scene_of, scenes)
    for name, scene in scenes.items():
        m = rows[name]
        if m.size:
            own, index = np.unique(resolve_cameras(table.select(m), scene).camera, return_inverse=True)
            cameras[m] = np.array([block_camera(name, c) for c in own.tolist()], dtype=object)[index]
    return replace(table, camera=cameras.astype(str))


def _check_ties_span_scenes(ties: TieTable, scene_of: np.ndarray) -> None:
    """Every tie point must be seen in two scenes or more (it ties scenes together)."""
    ids, point = np.unique(ties.id, return_inverse=True)
    n_scenes = seen_in(point, scene_of, ids.size)
    lonely = ids[n_scenes < 2]
    if lonely.size:
        where = {i: s for i, s in zip(ties.id, scene_of)}
        raise InputError(f"tie points: point(s) {listed(lonely)} are seen in one scene only "
                         f"({', '.join(sorted({where[i] for i in lonely}))}); a block's tie points tie its scenes "
                         "together: measure them in another scene or leave them out", parameter="ties")


def block_lines(scenes: dict[str, SceneModel | RpcScene], lines: ControlLines) -> ControlLines:
    """``lines`` with every image line's scene resolved (:func:`_scene_column`: '' only in a block
    of one scene) and its camera resolved in that scene and renamed to the composite's
    ``<scene>/<camera>``; the ground lines unchanged (shared by all scenes). InputError
    (parameter 'lines') naming the lines and scenes for: a line without a scene in a block of
    several, a scene not in the block, a camera the scene lacks, a block with RPC products (lines
    need rigorous scene models)."""
    image = lines.image
    scene_of = _scene_column(image.scene, image.line_id, scenes, "lines", kind="line")
    rpc = [name for name, scene in scenes.items() if scene.rpc_images()]
    if rpc:
        on_rpc = np.isin(scene_of, rpc)
        where = (f"line(s) {listed(np.unique(image.line_id[on_rpc]))} are measured in the RPC product(s) "
                 f"{listed(np.unique(scene_of[on_rpc]))}" if on_rpc.any() else
                 f"the block holds the RPC product(s) {', '.join(rpc)}")
        raise InputError(f"lines: {where}; control lines need rigorous (physical) scene models in every scene of the "
                         "block (an RPC product is adjusted by its image-space correction from GCPs and tie points): "
                         "leave the lines out, or adjust the rigorous scenes with their lines without the RPC "
                         "products", parameter="lines")
    cameras = image.camera.astype(object)
    for name, scene in scenes.items():
        rows = scene_of == name
        if not rows.any():
            continue
        names = [c.name for c in scene.cameras]
        cams = np.where(image.camera[rows] == "", names[0], image.camera[rows]) if len(names) == 1 \
            else image.camera[rows]
        unknown = ~np.isin(cams, names)
        if unknown.any():
            raise InputError(f"lines: camera(s) {listed(np.unique(cams[unknown]))} of line(s) "
                             f"{listed(np.unique(image.line_id[rows][unknown]))} are not cameras of scene {name} "
                             f"(cameras: {', '.join(names)})", parameter="lines")
        cameras[rows] = [block_camera(name, c) for c in cams]
    return ControlLines(lines.ground, replace(image, camera=cameras.astype(str), scene=scene_of))


class BlockInputs(NamedTuple):
    """A block's observations checked against its scenes (:func:`block_inputs`)."""
    composite: SceneModel | MixedBlock
    gcps: GcpTable
    ties: TieTable | None
    lines: ControlLines | None


def block_inputs(scenes: dict[str, SceneModel | RpcScene], gcps: GcpTable | None, ties: TieTable | None,
                 lines: ControlLines | None = None) -> BlockInputs:
    """(the composite scene: a :class:`MixedBlock` when the block holds RPC scenes, the GCP table,
    the tie table, the control lines (:func:`block_lines`; None without image lines)) with cameras
    named as in the composite; InputError for a scene listed twice, observations naming a scene
    not in the block, tie points seen in one scene only, lines in a block with RPC products, a
    scene without control, tie or line observations."""
    if not isinstance(scenes, dict) or not scenes:
        raise InputError("a block needs a dict of one or more named scenes", parameter="scenes")
    composite = compose_mixed(scenes)
    if gcps is None:
        none = np.zeros(0)
        gcps = GcpTable(none.astype(str), "control", none.astype(str), *(none,) * 8)
    gcp_scene = _scene_column(gcps.scene, gcps.id, scenes, "gcps")
    gcps = replace(_block_cameras(gcps, gcp_scene, scenes), scene=gcp_scene)
    tie_scene = np.zeros(0, str)
    if ties is not None and len(ties):
        tie_scene = _scene_column(ties.scene, ties.id, scenes, "ties")
        _check_ties_span_scenes(ties, tie_scene)
        ties = replace(_block_cameras(ties, tie_scene, scenes), scene=tie_scene)
    lines = block_lines(scenes, lines) if lines is not None and len(lines.image) else None
    measured = set(np.unique(gcp_scene[gcps.role == "control"]).tolist()) | set(np.unique(tie_scene).tolist()) | \
        set(np.unique(lines.image.scene).tolist() if lines is not None else [])
    alone = [name for name in scenes if name not in measured]
    if alone:
        raise InputError(f"scene(s) {', '.join(map(repr, alone))} have no control point or tie point measured in "
                         "them (nor a control line): nothing ties them to the block; measure tie points, GCPs or "
                         "lines there, or leave them out", parameter="scenes")
    return BlockInputs(composite, gcps, ties, lines)


def adjust_block(scenes: dict[str, SceneModel | RpcScene], gcps: GcpTable | None, ties: TieTable | None,
                 settings: AdjustmentSettings | None = None,
                 progress: Callable[[float, str | None], None] | None = None,
                 is_cancelled: Callable[[], bool] | None = None, lines: ControlLines | None = None) -> BlockResult:
    """Adjust the block ``scenes`` (name -> rigorous or RPC scene) to the GCPs, tie points and
    control lines (each row or image line naming its scene, see the module docstring) with
    ``settings`` (the same for every scene but the sigmas a scene states for itself,
    settings.scene_sigmas: :mod:`core.adjust.scenesigmas`)."""
    settings = settings or AdjustmentSettings()
    check_scene_sigmas(scenes, settings)
    return adjust_checked_block(scenes, block_inputs(scenes, gcps, ties, lines), settings, progress, is_cancelled)


def adjust_checked_block(scenes: dict[str, SceneModel | RpcScene], inputs: BlockInputs,
                         settings: AdjustmentSettings, progress: Callable[[float, str | None], None] | None = None,
                         is_cancelled: Callable[[], bool] | None = None) -> BlockResult:
    """:func:`adjust_block` of inputs already checked: ``settings`` by
    :func:`core.adjust.scenesigmas.check_scene_sigmas` for ``scenes``, the observations by
    :func:`block_inputs` (its result ``inputs``), for a caller that checks them before its own work."""
    composite, gcps, ties, lines = inputs
    log.info("adjusting a block of %d scenes (%s): %d GCP, %d tie observations and %d image lines", len(scenes),
             ", ".join(scenes), len(gcps), 0 if ties is None else len(ties), 0 if lines is None else len(lines.image))
    convergence = rays = None
    if ties is not None and len(ties):  # the onboard rays, made once for the convergence and the intersection
        rays = onboard_rays(composite, camera_indices(composite, ties.camera), ties.col, ties.row)
        convergence = ray_convergence(composite, ties, rays[1])
        weak = convergence[1] < MIN_CONVERGENCE_DEG
        if weak.any():
            log.warning("%d tie point(s) are seen from one direction only (their rays less than %g degree apart): "
                        "their heights are weakly determined: %s", int(weak.sum()), MIN_CONVERGENCE_DEG,
                        listed(convergence[0][weak]))
    out = adjust(composite, gcps, settings, progress, is_cancelled, ties=ties, lines=lines, tie_rays=rays)
    adjusted = split_scenes(out.scene)
    owned, parameters = {}, None  # the scenes share one record: its parameters are parted once
    for name, scene in adjusted.items():
        if "adjustment" in scene.info:
            record = scene.info["adjustment"]
            if record.get("parameters", []) is not parameters:
                parameters = record.get("parameters", [])
                owned = own_parameters(parameters, scenes)
            scene.info["adjustment"] = {**record, "parameters": owned[name],
                                        "block": {"scene": name, "scenes": list(scenes)}}
    line_points = scene_line_points(out.lines)
    report = block_report(scenes, composite, out, gcps, ties, settings, line_points)
    tie_points = tie_point_ground(out, ties)
    if convergence is not None:
        tie_points["convergence_deg"] = convergence[1]
    return BlockResult(adjusted, report, tie_points, out, line_points)


def scene_line_points(points: dict) -> dict:
    """The engine's per line point arrays (:attr:`AdjustmentResult.lines`, cameras named
    ``<scene>/<camera>``) with ``camera`` the scene's own camera name and ``scene`` (n,) str."""
    if not points:
        return {}
    scene, _, camera = (np.char.partition(np.asarray(points["camera"], dtype=str), SEPARATOR)[:, k] for k in range(3))
    return {**points, "camera": camera, "scene": scene}


def own_parameters(parameters: list[dict], scenes) -> dict[str, list[dict]]:
    """{scene: the parameters its adjusted scene carries}: its own and those of no scene (shared by the
    block), in their order, not every other scene's (a region's thousand scenes would each carry the whole
    block's: files, and the time to write them, growing with the square of the scenes). A parameter is a
    scene's when its name begins with the scene's name and SEPARATOR (an RPC image's correction, a camera's
    interior) or a dot (a rigorous scene's platform)."""
    rows: dict = {name: [] for name in scenes}
    shared = []
    for k, p in enumerate(parameters):
        whose = owner(p["name"], scenes)
        (shared if whose is None else rows[whose]).append(k)
    return {name: [parameters[k] for k in sorted(rows[name] + shared)] for name in scenes}


def owner(parameter: str, scenes) -> str | None:
    """The scene of ``scenes`` a composite's parameter belongs to (:func:`own_parameters`); None: the block's."""
    for mark in (SEPARATOR, "."):
        head, found, _ = parameter.partition(mark)
        if found and head in scenes:
            return head
    return None


def ray_convergence(scene: SceneModel, ties: TieTable, directions: np.ndarray | None = None) \
        -> tuple[np.ndarray, np.ndarray]:
    """(ids (m,), angle (m,) deg): per tie point the largest angle between one of its onboard lines
    of sight in ``scene`` (camera names of the scene) and its first one; near 0 when all rays are
    parallel and the point's height is undetermined. ``directions``: the observations' (n, 3) unit ECEF
    directions of sight when the caller has them (:func:`core.model.intersection.onboard_rays`)."""
    ids, point = np.unique(ties.id, return_inverse=True)
    u = directions if directions is not None else \
        onboard_rays(scene, camera_indices(scene, ties.camera), ties.col, ties.row)[1]
    first = np.unique(point, return_index=True)[1]
    angle = np.degrees(np.arccos(np.clip(np.einsum("ni,ni->n", u, u[first][point]), -1.0, 1.0)))
    out = np.zeros(ids.size)
    np.maximum.at(out, point, angle)
    return ids, out


def tie_point_ground(out: AdjustmentResult, ties: TieTable | None) -> dict:
    """Per tie point: id, adjusted lon, lat, h, rays (observations used) and scenes (seen in)."""
    if ties is None or not len(ties):
        return {k: np.zeros(0) for k in ("id", "lon", "lat", "h", "rays", "scenes", "convergence_deg")}
    ids, point = np.unique(ties.id, return_inverse=True)
    first = np.unique(point, return_index=True)[1]
    used = np.isfinite(out.tie_points["res_col"])
    return {"id": ids, **{k: out.tie_points[k][first] for k in ("lon", "lat", "h")},
            "rays": np.bincount(point[used], minlength=ids.size),
            "scenes": seen_in(point, ties.scene, ids.size)}


def seen_in(point: np.ndarray, scene: np.ndarray, n_points: int) -> np.ndarray:
    """(n_points,) how many different scenes see each point, of observations of points ``point`` (n,)
    index in scenes ``scene`` (n,) str."""
    names, index = np.unique(scene, return_inverse=True)
    pairs = np.unique(point.astype(np.int64) * max(names.size, 1) + index)  # (point, scene) as one integer
    return np.bincount(pairs // max(names.size, 1), minlength=n_points)
