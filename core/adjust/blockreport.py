"""A block adjustment's own report (:class:`core.adjust.report_types.BlockReport`): per scene and
for the block the image residual RMS of control, check and tie observations, each scene's move from
its input geolocation (onboard or vendor RPC) against its stated accuracy, control line figures, and
the warnings for scenes no control point holds that moved beyond that accuracy; built once from the
block's adjustment (:func:`core.adjust.block.adjust_block`)."""
from __future__ import annotations

import logging

import numpy as np

from ..model.block import scene_cameras
from ..model.mixedblock import MixedBlock
from ..model.sensor import SceneModel
from ..observations.gcps import GcpTable
from ..observations.tables import rows_of_scenes
from ..observations.tiepoints import TieTable
from .report_accuracy import absolute_accuracy
from .report_types import BlockReport
from .results import AdjustmentResult
from .scenesigmas import stated_sigmas
from .settings import AdjustmentSettings

log = logging.getLogger(__name__)

GRID = 3  # image points per axis at which each camera's move from its onboard geolocation is measured
DRIFT_SIGMAS = 3.0  # a scene held by its onboard or vendor sigmas alone that moves farther is named


def _rms_px(res_col: np.ndarray, res_row: np.ndarray) -> float | None:
    """Root mean square length (px) of finite residual vectors (None without any)."""
    ok = np.isfinite(res_col) & np.isfinite(res_row)
    return float(np.sqrt(np.mean(res_col[ok] ** 2 + res_row[ok] ** 2))) if ok.any() else None


def _lattice(cam) -> tuple[np.ndarray, np.ndarray]:
    """(col, row) (GRID^2,) px of a GRID x GRID lattice over a camera's image."""
    return tuple(a.ravel() for a in np.meshgrid(np.linspace(0, cam.cols, GRID), np.linspace(0, cam.rows, GRID)))


def ground_move(before, after, cameras: list[int]) -> float:
    """The largest distance (m) between the ground seen through ``before`` and ``after``
    (composites) at a GRID x GRID lattice of each of their ``cameras``, at the mean height of
    ``before``."""
    height = float(np.mean(before.height_range))
    moved = 0.0
    for c in cameras:
        col, row = _lattice(before.cameras[c])
        g0, g1 = before.image_to_ground(col, row, height, c), after.image_to_ground(col, row, height, c)
        moved = max(moved, float(np.nanmax(np.linalg.norm(g1 - g0, axis=1))))
    return moved


def onboard_move(before: SceneModel, after: SceneModel, cameras: list[int],
                 settings: AdjustmentSettings, scene: str = "") -> dict:
    """How far the adjustment moved a rigorous scene's ground from where its onboard model puts it
    (:func:`ground_move`); and the onboard sigma (m) of that ground, sqrt(position_sigma^2 +
    (attitude_sigma * range)^2) with range (m) the largest satellite-to-ground distance at the
    lattice (None when a sigma is not stated), with block scene ``scene``'s own sigmas where it
    states them (settings.scene_sigmas)."""
    height = float(np.mean(before.height_range))
    ranges = []
    for c in cameras:
        col, row = _lattice(before.cameras[c])
        ground = before.image_to_ground(col, row, height, c)
        ranges.append(float(np.linalg.norm(before.line_of_sight(col, row, c)[1] - ground, axis=1).max()))
    ps, at = settings.sigma("position_sigma", scene), settings.sigma("attitude_sigma", scene)
    sigma = None if ps is None or at is None else float(np.hypot(ps, at * max(ranges)))
    return {"moved_m": ground_move(before, after, cameras), "onboard_sigma_m": sigma}


def vendor_move(before: MixedBlock, after: MixedBlock, camera: int, out: AdjustmentResult,
                settings: AdjustmentSettings, scene: str = "") -> dict:
    """How far the adjustment moved an RPC image's ground from where its vendor RPC (with its
    input correction) puts it (:func:`ground_move`); the vendor's stated accuracy in metres on the
    ground (the rpc_sigma of block scene ``scene``, its own or the global one, times the ground
    sample distance at the image centre; None without it); and its adjusted correction terms (value
    and posterior sigma, px and px per px)."""
    cam = before.cameras[camera]
    centre = before.image_to_ground([cam.cols / 2, cam.cols / 2 + 1], [cam.rows / 2] * 2,
                                    float(np.mean(before.height_range)), camera)
    gsd = float(np.linalg.norm(centre[1] - centre[0]))
    prefix = f"{cam.name}."
    terms = {p["name"][len(prefix):]: {"value": p["value"], "sigma": p["sigma"], "unit": p["unit"]}
             for p in out.report["parameters"] if p["name"].startswith(prefix) and p["mode"] != "fixed"}
    stated = settings.sigma("rpc_sigma", scene)
    return {"moved_m": ground_move(before, after, [camera]),
            "vendor_sigma_m": None if stated is None else stated * gsd,
            "correction": terms}


def _move(composite, out: AdjustmentResult, name: str, member, settings: AdjustmentSettings) -> dict:
    """Block scene ``name``'s move from its input geolocation: :func:`vendor_move` for an RPC image,
    :func:`onboard_move` for a rigorous scene; with its ``model`` ('rpc' or 'rigorous') and the
    sigmas it was adjusted with (``sigmas``, :func:`core.adjust.scenesigmas.stated_sigmas`)."""
    cameras = scene_cameras(composite, name)
    if member.rpc_images():
        return {"model": "rpc", **vendor_move(composite, out.scene, cameras[0], out, settings, name),
                "sigmas": stated_sigmas(settings, name, True)}
    return {"model": "rigorous", **onboard_move(composite, out.scene, cameras, settings, name),
            "sigmas": stated_sigmas(settings, name, False)}


def beyond_stated(per_scene: dict, controlled: bool) -> list[str]:
    """Warnings for the scenes of a block held by no control point that moved more than DRIFT_SIGMAS
    times their stated (onboard or vendor) accuracy from where their input model put them: the tie
    points pull them along what only those sigmas hold, the sign of an error the adjustment does
    not model (lens terms left out of a tri-stereo: 450 m, 8 sigmas)."""
    if controlled:
        return []
    out = []
    for name, entry in per_scene.items():
        sigma = entry.get("onboard_sigma_m", entry.get("vendor_sigma_m"))
        if sigma and entry["moved_m"] > DRIFT_SIGMAS * sigma:
            moved = entry["moved_m"]
            out.append(f"scene {name} moved {moved:.0f} m from its input geolocation, {moved / sigma:.1f} times its "
                       f"stated accuracy ({sigma:.0f} m), with no control point to hold it: the tie points pull it, a "
                       "sign of an error the adjustment does not model (estimate the interior, INTERIOR=default, or "
                       "add control)")
    return out


def _line_entry(points: dict, rows: np.ndarray) -> dict:
    """Line figures of the line points ``rows`` (n,) bool of :func:`scene_line_points`: lines and
    points used (not flagged), points flagged, RMS (m) of their across-line misfit after and
    before (rays through the adjusted and the input scene meeting the line's height)."""
    used = rows & ~points["flagged"]
    rms = lambda a: float(np.sqrt(np.mean(a * a))) if a.size else None  # noqa: E731
    return {"lines": int(np.unique(points["line_id"][used]).size), "points": int(used.sum()),
            "points_flagged": int((rows & points["flagged"]).sum()),
            "across_rmse_m": rms(points["across_m"][used]),
            "across_rmse_before_m": rms(points["across_before_m"][used])}


def block_report(scenes: dict, composite: SceneModel | MixedBlock, out: AdjustmentResult,
                 gcps: GcpTable, ties: TieTable | None, settings: AdjustmentSettings,
                 line_points: dict | None = None) -> BlockReport:
    """Per scene and block figures: image residual RMS (px) of control observations, tie
    observations (after; before: through the onboard scenes with the onboard intersection) and
    check points (the adjusted scene's ground -> image of their stated ground), the move from the
    onboard geolocation (:func:`onboard_move`) and the sigmas the scene was adjusted with, with
    control lines their lines and points used and across-line RMS (m, :func:`_line_entry`; per
    line in the engine's report["lines"]); sigma0; without control points the absolute accuracy the
    statistics predict (``accuracy``, :func:`core.adjust.report_accuracy.absolute_accuracy`); the
    scenes held by no control point that moved beyond their stated accuracy (:func:`beyond_stated`);
    and the engine's whole report (``adjustment``), whence the datum sentence, ``datum_directions``,
    the engine's warnings and the written-vs-fitted figures (:class:`core.adjust.report_types.BlockReport`)."""
    rep, pts = out.report, out.points
    control, check = pts["role"] == "control", pts["role"] == "check"
    tie_res = (out.tie_points["res_col"], out.tie_points["res_row"]) if ties is not None and len(ties) else None
    before = None
    if tie_res is not None:  # the engine's start: the onboard intersection
        before = np.stack([out.tie_points["res_col_before"], out.tie_points["res_row_before"]], axis=1)
    per_scene = {}
    tie_rows = rows_of_scenes(ties.scene, scenes) if tie_res is not None else {}
    for name in scenes:
        g, t = gcps.scene == name, tie_rows.get(name)
        entry = {"cameras": [c.name for c in scenes[name].cameras],
                 "control": {"observations": int((g & control).sum()),
                             "rmse_px": _rms_px(pts["res_col"][g & control], pts["res_row"][g & control])},
                 "check_points": {"observations": int((g & check).sum()),
                                  "rmse_px": _rms_px(pts["res_col"][g & check], pts["res_row"][g & check])},
                 **_move(composite, out, name, scenes[name], settings)}
        if tie_res is not None:
            entry["ties"] = {"observations": int(t.size), "rmse_px": _rms_px(tie_res[0][t], tie_res[1][t]),
                             "rmse_before_px": _rms_px(before[t, 0], before[t, 1])}
        if line_points:
            entry["lines"] = _line_entry(line_points, line_points["scene"] == name)
        per_scene[name] = entry
    block = {"scenes": len(scenes), "sigma0": rep["sigma0"],
             "control_rmse_px": _rms_px(pts["res_col"][control], pts["res_row"][control]),
             "check_rmse_px": _rms_px(pts["res_col"][check], pts["res_row"][check]),
             "tie_points": rep["observations"]["tie_points"],
             "tie_rmse_px": None if tie_res is None else _rms_px(*tie_res),
             "tie_rmse_before_px": None if before is None else _rms_px(before[:, 0], before[:, 1]),
             "lines": _line_entry(line_points, np.ones(line_points["scene"].size, bool)) if line_points else None}
    controlled = bool((gcps.role == "control").any())
    block["accuracy"] = absolute_accuracy(per_scene, rep, controlled)
    report = BlockReport(block, per_scene, beyond_stated(per_scene, controlled), rep)
    for warning in report.scene_warnings:  # the adjustment's own: logged by the engine
        log.warning("%s", warning)
    log.info("%s", report.summary_sentence())
    return report
