"""Inputs checked before anything is solved: the settings, the GCPs (finite, positive sigmas, in
this scene's images, seen by it, spread over it), tie points and control lines, and how the datum
of a block with tie points is held."""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..model.block import is_block
from ..model.sensor import SceneModel
from ..observations.gcps import GcpTable
from ..observations.tables import resolve_cameras
from ..observations.tiepoints import TieTable
from .linepoints import ControlLines, check_lines, datum_lines
from .problem import Problem
from .settings import AdjustmentSettings
from .ties import check_ties, datum

# No measurement is stated this precisely (the best image matching reaches about 0.01 px, the best
# ground survey a millimetre): a smaller sigma is a unit or typing error, and its weight (1/sigma^2)
# would overflow the normal equations.
MIN_SIGMA_PX = 1e-4       # px
MIN_SIGMA_GROUND = 1e-4   # m


def check_sigma_floor(table: GcpTable, weighted_ground: bool) -> None:
    """InputError naming the GCPs (up to 10) whose image sigma is below MIN_SIGMA_PX, or (weighted
    ground) whose ground sigmas are below MIN_SIGMA_GROUND."""
    checks = [("sigma_px", table.sigma_px, MIN_SIGMA_PX, "px")]
    if weighted_ground:
        checks += [("sigma_xy", table.sigma_xy, MIN_SIGMA_GROUND, "m"),
                   ("sigma_z", table.sigma_z, MIN_SIGMA_GROUND, "m")]
    for name, values, floor, unit in checks:
        low = values < floor
        if low.any():
            raise InputError(f"GCPs {', '.join(table.id[low][:10])}{' …' * int(low.sum() > 10)} have {name} below "
                             f"{floor:g} {unit} (smallest {values.min():.3g}): no measurement is that precise; "
                             "check the sigma field and its unit", parameter="gcps")


def check_inputs(scene: SceneModel, table: GcpTable, settings: AdjustmentSettings,
                 ties: TieTable | None = None, lines: ControlLines | None = None) -> GcpTable:
    """Cameras resolved and the GCPs (and tie points) checked before anything is solved:
    finite values, points in this scene's images, enough of them, and spread over the image.
    Without tie points at least 3 control points are needed; with tie points fewer (0, 1, 2)
    when the onboard pseudo-observations hold what they leave of the datum (see
    :func:`core.adjust.ties.datum`); with control lines (checked against the scene) fewer too:
    lines in several directions hold the datum as points do (the report's lines/directions
    says when they do not)."""
    settings.validate()
    if settings.scene_sigmas and not is_block(scene):
        raise InputError("SCENE_SIGMAS: per-scene sigmas are for a block of scenes (SCENES); one scene takes "
                         "POSITION_SIGMA, ATTITUDE_SIGMA and RPC_SIGMA",
                         parameter="settings.scene_sigmas")
    table = resolve_cameras(table, scene)
    bad = ~np.all(np.isfinite(np.stack([table.col, table.row, table.lon, table.lat, table.h, table.sigma_px,
                                        table.sigma_xy, table.sigma_z])), axis=0)
    if bad.any():
        raise InputError(f"GCPs {', '.join(table.id[bad][:10])} have NaN or missing coordinates or sigmas",
                         parameter="gcps")
    if np.any(table.sigma_px <= 0) or (settings.ground == "weighted" and
                                       (np.any(table.sigma_xy <= 0) or np.any(table.sigma_z <= 0))):
        raise InputError("GCP sigmas must be positive (sigma_px, and sigma_xy, sigma_z for weighted ground)",
                         parameter="gcps")
    check_sigma_floor(table, settings.ground == "weighted")
    control = table.role == "control"
    with_ties = ties is not None and len(ties) > 0
    if with_ties:
        check_ties(scene, ties, table.id)
    with_lines = lines is not None and len(lines.image) > 0
    if with_lines:
        if scene.rigorous_part() is None:
            raise InputError("control lines need a rigorous (physical) scene model; an RPC scene's correction is "
                             "adjusted from GCPs", parameter="lines")
        check_lines(scene, lines)
    sparse_control = with_ties or with_lines
    if len(table) and not control.any() and not sparse_control:
        raise InputError(f"all {np.unique(table.id).size} points are check points (role 'check'): check points never "
                         "enter the adjustment, so none controls it; give control points (role 'control'), or tie "
                         "points or control lines", parameter="gcps")
    inside = np.zeros(len(table), bool)
    for c, cam in enumerate(scene.cameras):
        m = table.camera == cam.name
        inside[m] = cam.in_image(table.col[m], table.row[m])
    if not inside[control].any() and not (sparse_control and not control.any()):
        raise InputError("no control point lies inside this scene's images: is the GCP layer from another scene?",
                         parameter="gcps")
    if (~inside[control]).sum() > 0.5 * control.sum():
        raise InputError(f"{int((~inside[control]).sum())} of {int(control.sum())} control points lie outside the "
                         "scene's images: is the GCP layer from another scene?", parameter="gcps")
    if control.any():
        _check_seen_by_scene(scene, table.select(control))
    if not sparse_control or np.unique(table.id[control]).size >= 3:
        _check_spread(scene, table, control)
    block_datum(table, settings, ties, lines, scene)
    return table


def block_datum(table: GcpTable, settings: AdjustmentSettings, ties: TieTable | None,
                lines: ControlLines | None = None, scene=None) -> dict | None:
    """How the datum of a block with tie points (and control lines) is held (None without tie
    points; InputError naming a datum defect). ``scene``: a block with RPC images
    (:class:`core.model.mixedblock.MixedBlock`) has onboard pseudo-observations only with rigorous
    scenes, and its RPC images the prior settings.rpc_sigma."""
    if ties is None or len(ties) == 0:
        return None
    trajectories = scene.rigorous_part() is not None
    images = len(scene.rpc_images())
    return datum(np.unique(table.id[table.role == "control"]).size,
                 settings.position_sigma if trajectories else None, settings.attitude_sigma if trajectories else None,
                 *datum_lines(lines), rpc_images=images, rpc_sigma=settings.rpc_sigma if images else None,
                 tie_height_sigma=settings.tie_height_sigma)


def _check_seen_by_scene(scene: SceneModel, control: GcpTable) -> None:
    """Most control points' ground positions must project into the scene's images: onboard
    errors move them by hundreds of pixels, another scene by its whole size. An evenly spaced
    sample of 5000 points decides."""
    control = control.select(np.unique(np.linspace(0, len(control) - 1, min(len(control), 5000)).astype(int)))
    seen = np.zeros(len(control), bool)
    for c, cam in enumerate(scene.cameras):
        m = control.camera == cam.name
        if m.any():
            col, row = scene.ground_to_image_near(control.select(m).ecef(), c, control.col[m], control.row[m])
            seen[m] = (col > -0.5 * cam.cols) & (col < 1.5 * cam.cols) & (row > -0.5 * cam.rows) & \
                (row < 1.5 * cam.rows)
    if seen.mean() < 0.5:
        raise InputError(f"the ground positions of {int((~seen).sum())} of {len(control)} control points are far "
                         "outside this scene's images (more than half an image away): is the GCP layer from "
                         "another scene?", parameter="gcps")


def _check_spread(scene: SceneModel, table: GcpTable, control: np.ndarray) -> None:
    """Control points on a line or bunched in a corner cannot fix a trajectory."""
    cam = scene.cameras[0]
    xy = np.stack([table.col[control] / cam.cols, table.row[control] / cam.rows], axis=1)
    if xy.shape[0] < 3:
        raise InputError(f"too few control points: {xy.shape[0]} (at least 3, better many more, are needed)",
                         parameter="gcps")
    span = xy.max(axis=0) - xy.min(axis=0)
    sv = np.linalg.svd(xy - xy.mean(axis=0), compute_uv=False)
    if sv[1] < 0.01 * sv[0]:
        raise InputError("the control points lie on a line; the scene's rotation about it cannot be determined. "
                         "Add points off that line.", parameter="gcps")
    if span[0] < 0.1 and span[1] < 0.1:
        raise InputError(f"the control points cover only {100 * span[0]:.0f}% x {100 * span[1]:.0f}% of the image "
                         "(one corner); spread them over the scene", parameter="gcps")


def check_redundancy(problem: Problem) -> None:
    """More equations than unknowns, or an InputError naming what to change."""
    n_eq, n_unknowns = problem.counts()
    if n_eq <= n_unknowns:
        raise InputError(f"too few GCPs for the chosen model: {len(problem.obs)} image observations give {n_eq} "
                         f"equations for {n_unknowns} unknowns; add GCPs or choose a simpler trajectory model "
                         "(lower order, longer interval) or fewer interior parameters", parameter="gcps")
