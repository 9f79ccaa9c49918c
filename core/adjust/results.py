"""What an adjustment returns: :class:`AdjustmentResult` (the adjusted scene, its report, per-observation
arrays of control and check points, tie points and line points) built once from the final solution,
its statistics and what the stages around it returned (:class:`core.adjust.report_types.StageOutcomes`)."""
from __future__ import annotations

import logging
from dataclasses import asdict, dataclass, field

import numpy as np

from ..geodesy import ecef_to_geodetic, geodetic_to_ecef
from ..model.block import chip_label
from ..model.sensor import SceneModel, rows_by
from ..observations.gcps import GcpTable
from ..observations.tables import listed
from .datumdirections import with_directions
from .checkpoints import accuracy, check_point_report, intersection_accuracy, log_check_points
from .estimation import Estimate
from .linepoints import directions, per_line, ray_offsets
from .problem import Problem
from .breakdown import breakdown
from .robust import component_report, critical, sigma0_test, stated_sigma0
from .report import datum_sentence
from .report_types import AdjustmentReport, StageOutcomes
from .statistics import Statistics, correlated_pairs, correlation
from .parameters import ParameterSet, trajectory_groups
from .ties import yaw_hold, yaw_sentence

log = logging.getLogger(__name__)

@dataclass
class AdjustmentResult:
    """scene: the adjusted scene; report: its figures (:class:`AdjustmentReport`); points: per input row
    (control and check) arrays: id, role, camera, col, row, res_col, res_row (px,
    predicted - measured), res_px, w_col, w_row (normalised residuals), redundancy, weight
    (final weight factor), flagged (bool), res_col_stated, res_row_stated (px: the adjusted
    scene's ground -> image of the point's stated ground coordinates minus measured: for a
    control point its image residual plus what its ground unknowns took, with fixed ground its
    residual); for check points the residuals are those of the adjusted scene's ground -> image.
    tie_points: per input tie observation (input order)
    arrays: id, camera, col, row, res_col, res_row (px), w_col, w_row, weight, flagged, and the
    adjusted ground position of its point lon, lat (deg), h (ellipsoidal m); NaN for the
    observations of points left out (empty without tie points); res_col_before, res_row_before
    (px: through the input scene at the forward intersection of the point's rays there, the
    adjustment's start; NaN where it has none). lines: per line point (one per
    image-line vertex) arrays: line_id, camera, col, row, res_col, res_row (px), w_col, w_row,
    weight, across_m / height_m (m: where the point's ray through the adjusted scene meets its
    line's height, across the line and in height), across_before_m (the same through the input
    scene), flagged (the point or its line), line_flagged, lon, lat, h of its adjusted ground
    point; per line in report["lines"]["per_line"] (empty without lines)."""
    scene: SceneModel
    report: AdjustmentReport
    points: dict = field(default_factory=dict)
    tie_points: dict = field(default_factory=dict)
    lines: dict = field(default_factory=dict)


def result_of(problem: Problem, table: GcpTable, adjusted: SceneModel, est: Estimate,
              stages: StageOutcomes) -> AdjustmentResult:
    """The adjustment's result from its final ``problem`` and estimate ``est``: the adjusted scene
    ``adjusted`` (which gets its record of the adjustment, :meth:`AdjustmentReport.scene_record`),
    the report of the solution's figures and the ``stages``' outcomes, and the per-observation
    arrays (see :class:`AdjustmentResult`)."""
    crit = critical(problem.settings.alpha)
    result, st = est.result, est.st
    params = problem.params
    free = params.free
    sigma = np.full(len(params.params), np.nan)
    sigma[free] = st.sigma0 * np.sqrt(st.Q.diagonal())
    corr_matrix = correlation(st.Q)
    parameters = []
    for i, p in enumerate(params.params):
        parameters.append({"name": p.name, "block": p.block, "value": p.value, "sigma": None if np.isnan(sigma[i])
                           else float(sigma[i]), "unit": p.unit, "mode": p.mode,
                           "significant": None if np.isnan(sigma[i]) or p.block in ("position", "attitude")
                           else bool(abs(p.value) > 1.96 * sigma[i])})
    pairs = correlated_pairs(corr_matrix, [params.params[i] for i in free])
    for pair in pairs:
        if pair["trajectory"]:
            log.warning("%s and %s are correlated %.4f: the GCPs hardly separate them (their sigmas say by how "
                        "much); onboard sigmas (pseudo-observations) would", pair["a"], pair["b"], pair["r"])
    # flagged: beyond the critical value now, or held flagged by the robust loop (core.adjust.robust, Convergence)
    flagged = (np.abs(st.w).max(axis=1) > crit) | (est.held if est.held.size else False)
    gcp = ~(problem.is_tie | problem.is_line)
    rows = problem.rows[gcp]
    n = len(table)
    points = {"id": table.id, "role": table.role, "camera": table.camera, "col": table.col, "row": table.row,
              "res_col": np.full(n, np.nan), "res_row": np.full(n, np.nan), "w_col": np.full(n, np.nan),
              "w_row": np.full(n, np.nan), "redundancy": np.full(n, np.nan), "weight": np.full(n, np.nan),
              "flagged": np.zeros(n, bool)}
    points["res_col"][rows], points["res_row"][rows] = st.v[gcp, 0], st.v[gcp, 1]
    points["w_col"][rows], points["w_row"][rows] = st.w[gcp, 0], st.w[gcp, 1]
    points["redundancy"][rows] = st.redundancy[gcp].mean(axis=1)
    points["weight"][rows] = problem.factor[gcp, 0]
    points["flagged"][rows] = flagged[gcp]
    checks = np.nonzero(table.role == "check")[0]
    after = accuracy(adjusted, table, checks, problem.settings.alpha, problem.scale, problem.weighted)
    before = accuracy(problem.scene, table, checks, problem.settings.alpha, problem.scale, problem.weighted)
    if checks.size:
        points["res_col"][checks], points["res_row"][checks] = after["residuals"][:, 0], after["residuals"][:, 1]
        points["flagged"][checks] = after["is_flagged"]
    after["intersection"] = intersection_accuracy(adjusted, table, checks, after.get("is_flagged"))
    before["intersection"] = intersection_accuracy(problem.scene, table, checks)
    log_check_points(before, after)
    points["res_px"] = np.hypot(points["res_col"], points["res_row"])
    stated = _at_stated_ground(adjusted, table)
    points["res_col_stated"], points["res_row_stated"] = stated[:, 0], stated[:, 1]
    # Robust runs leave their flagged observations out of the residual figures; plain ones keep all.
    good = ~flagged if problem.settings.robust != "none" else np.ones_like(flagged)
    # sigma0 of the stated sigmas: over the inliers (with their redundancy) when the variance
    # components are estimated, else over all observations as weighted.
    sigma0, dof = stated_sigma0(est.components, est.kappa) if problem.settings.variance_components else \
        (st.sigma0, st.dof)
    problems = breakdown(problem, st, flagged, est.inlier)
    reliable = all(p["reliable"] for p in problems)
    for p in problems:
        log.warning("%s%s", p["message"], "" if p["reliable"] else "; the result is not reliable")
    tie_ids = problem.ties.table.id[problem.rows[problem.is_tie]]
    figures = {
        "settings": asdict(problem.settings),
        "observations": {"control_points": problem.n_control, "image_observations": int(gcp.sum()),
                         "check_points": int(checks.size), "unknowns": int(free.size),
                         "ground_unknowns": int(3 * problem.estimated.size),
                         "tie_points": problem.ties.counts(), "tie_observations": int(problem.is_tie.sum()),
                         "line_points": int(problem.is_line.sum()),
                         "degrees_of_freedom": st.dof},
        "iterations": result["iterations"],
        "robust": {"method": problem.settings.robust, "passes": est.passes, "critical_w": crit,
                   "stopped_at_limit": est.at_limit, "flagged": int(flagged.sum()), "held_flagged": int(est.held.sum()),
                   "flagged_ids": [str(i) for i in table.id[rows][flagged[gcp]][:1000]],
                   "flagged_tie_ids": [str(i) for i in tie_ids[flagged[problem.is_tie]][:1000]]},
        "reliability": {"reliable": reliable, "problems": problems},
        "sigma0": sigma0,
        "sigma0_adjusted": st.sigma0,
        "sigma0_test": sigma0_test(sigma0, dof),
        "variance_components": component_report(problem, est.components, est.kappa, est.joint),
        "determinability": stages.determinability,
        "parameters": parameters,
        "high_correlations": pairs,
        "control_residuals": _residual_summary(st.v[good & gcp]),
        "control_ground": _ground_taken(problem, good & gcp, st.v, stated[problem.rows[good & gcp]]),
        "control_residuals_per_chip": _per_chip(problem, st.v, np.nonzero(good & gcp)[0]),
        "check_points": check_point_report(after),
        "check_points_before": check_point_report(before),
        "trajectory": _trajectory_curves(problem.params.trajectories) if problem.params.position_basis is not None
        else None,
    }
    figures["tie_points"], ties = _tie_points(problem, st, flagged, good) if len(problem.ties.table) else (None, {})
    figures["lines"], lines = _line_results(problem, adjusted, st, flagged) if len(problem.lines) else (None, {})
    report = AdjustmentReport(**figures, interior_selection=stages.interior_selection,
                              rpc_correction=stages.rpc_correction, trajectory_prior=stages.trajectory_prior,
                              written_vs_fitted=stages.written_vs_fitted, datum=_datum(stages.held, problem, est))
    if report.datum is not None:
        log.info("%s", datum_sentence(report))
    adjusted.info["adjustment"] = report.scene_record()
    return AdjustmentResult(adjusted, report, points, ties, lines)


def _tie_points(problem: Problem, st: Statistics, flagged: np.ndarray, good: np.ndarray) -> tuple[dict, dict]:
    """The tie points' report entry and per input observation arrays (see AdjustmentResult).

    Their adjusted ground positions are no absolute accuracy (no known truth; with few GCPs
    they share the datum's error): the relative accuracy is told by the image residuals."""
    tie = problem.is_tie
    table = problem.ties.table
    n = len(table)
    rows = problem.rows[tie]
    out = {"id": table.id, "camera": table.camera, "col": table.col, "row": table.row,
           "res_col_before": problem.ties.before[:, 0], "res_row_before": problem.ties.before[:, 1]}
    for name, values in (("res_col", st.v[tie, 0]), ("res_row", st.v[tie, 1]), ("w_col", st.w[tie, 0]),
                         ("w_row", st.w[tie, 1]), ("weight", problem.factor[tie, 0])):
        out[name] = np.full(n, np.nan)
        out[name][rows] = values
    out["flagged"] = np.zeros(n, bool)
    out["flagged"][rows] = flagged[tie]
    lon, lat, h = (np.full(n, np.nan) for _ in range(3))
    point = problem.obs.point[tie]
    lon[rows], lat[rows], h[rows] = ecef_to_geodetic(problem.ground[point])
    out.update(lon=lon, lat=lat, h=h)
    cams = problem.scene.cameras
    report = {**problem.ties.counts(),
              "flagged": int(flagged[tie].sum()),
              "span": problem.ties.span(problem.scene),
              "residuals": _residual_summary(st.v[tie & good]),
              "residuals_per_camera": _per_camera(cams, problem.obs.camera, st.v, np.nonzero(tie & good)[0]),
              "relative_accuracy": "image residuals of the tie observations (px, flagged ones left out) measure the "
                                   "block's relative accuracy; the tie points' adjusted ground positions carry the "
                                   "datum's error as well and are no absolute accuracy figure"}
    heights = problem.tie_heights()
    if heights is not None:  # held to a reference DEM (core.adjust.tieheights)
        counts = heights.counts()
        report["heights"] = {**counts, "dem": problem.ties.heights.surface.path,
                             "sentence": problem.ties.heights.sentence(counts)}
    return report, out



def _line_results(problem: Problem, adjusted, st: Statistics, flagged: np.ndarray) -> tuple[dict, dict]:
    """The report entry and per line point arrays of the lines (see AdjustmentResult.lines)."""
    lines = problem.lines
    rows = problem.line_obs
    crit = critical(problem.settings.alpha)
    offsets = ray_offsets(adjusted, lines)
    before = ray_offsets(problem.scene, lines)
    lon, lat, h = ecef_to_geodetic(problem.line_ground())
    line_flag = problem.line_flagged[lines.obs.key]
    points = {"line_id": lines.line_ids(), "camera": lines.obs.camera, "col": lines.obs.col, "row": lines.obs.row,
              "res_col": st.v[rows, 0], "res_row": st.v[rows, 1], "w_col": st.w[rows, 0], "w_row": st.w[rows, 1],
              "w_across": st.lines.w, "weight": problem.factor[rows, 0], "across_m": offsets[:, 0],
              "height_m": offsets[:, 1], "across_before_m": before[:, 0],
              "flagged": flagged[rows] | (np.abs(st.lines.w) > crit) | line_flag, "line_flagged": line_flag,
              "lon": lon, "lat": lat, "h": h}
    table = per_line(lines, offsets[:, 0], points["flagged"], problem.line_flagged)
    wrong = table["line_id"][table["flagged"]]
    if wrong.size:
        log.warning("%d control line(s) do not fit as a whole (wrong road or shifted in the map); their across-line "
                    "constraints were released: %s", wrong.size, listed(wrong))
    good = ~points["flagged"]
    rms = lambda a: float(np.sqrt(np.mean(a * a))) if a.size else None  # noqa: E731
    direction = directions(lines, problem.n_control)
    if not direction["determined"]:
        log.warning("control lines: %s", direction["message"])
    report = {"lines": int(table["line_id"].size), "points": len(lines), "constraints_per_point": 2,
              "flagged_lines": int(wrong.size), "flagged_line_ids": [str(i) for i in wrong[:1000]],
              "flagged_points": int((~good).sum()),
              "across_rmse_m": rms(offsets[good, 0]), "height_rmse_m": rms(offsets[good, 1]),
              "across_rmse_before_m": rms(before[good, 0]),
              "image_residuals_px": {"rmse_col": rms(points["res_col"][good]),
                                     "rmse_row": rms(points["res_row"][good])},
              "directions": direction, "per_line": {k: v.tolist() for k, v in table.items()}}
    return report, points



def _datum(held: dict | None, problem: Problem, est: Estimate) -> dict | None:
    """The report's datum entry: how it is held before the solution (``held``, None without tie
    points) with the posterior sigma of the block's yaw (:func:`yaw_hold`, its sentence appended
    to the note) and the datum directions (:func:`core.adjust.datumdirections.with_directions`)."""
    if held is None:
        return None
    yaw = yaw_hold(problem.params, est.st.sigma0 ** 2 * est.st.Q)
    with_yaw = {**held, "yaw": yaw, "note": "; ".join(filter(None, (held.get("note"), yaw_sentence(yaw))))}
    return with_directions(with_yaw, problem, est.result)


def _at_stated_ground(scene, table: GcpTable) -> np.ndarray:
    """(n, 2) px: ``scene``'s ground -> image of every point's stated ground minus its measured
    (col, row)."""
    out = np.full((len(table), 2), np.nan)
    ground = geodetic_to_ecef(table.lon, table.lat, table.h).reshape(-1, 3)
    for c, cam in enumerate(scene.cameras):
        m = (table.camera == cam.name) | ((table.camera == "") & (len(scene.cameras) == 1))
        if m.any():
            col, row = scene.ground_to_image_near(ground[m], c, table.col[m], table.row[m])
            out[m] = np.stack([col - table.col[m], row - table.row[m]], axis=1)
    return out


def _ground_taken(problem: Problem, mask: np.ndarray, v: np.ndarray, stated: np.ndarray) -> dict | None:
    """How much of the control observations' (``mask`` (n,)) misfit the ground unknowns took
    (weighted ground; None with fixed ground): the RMSE of their horizontal and vertical shifts
    (m, per observation), the residuals at the stated ground (``stated`` (k, 2) px, a summary as
    control_residuals'), and the share of that misfit's sum of squares the shifts took (the image
    residuals v (n, 2) px keep the rest)."""
    if not (problem.weighted and problem.n_control) or not mask.any():
        return None
    point = problem.obs.point[mask]
    shift = np.einsum("nij,nj->ni", problem.enu[point], (problem.ground - problem.ground0)[point])
    rms = lambda a: float(np.sqrt(np.mean(a * a)))  # noqa: E731
    total = float(np.nansum(stated ** 2))
    return {"shift_rmse_horizontal_m": rms(np.hypot(shift[:, 0], shift[:, 1])),
            "shift_rmse_vertical_m": rms(shift[:, 2]),
            "at_stated_ground": _residual_summary(stated[np.isfinite(stated).all(axis=1)]),
            "ground_share": 1.0 - float(np.sum(v[mask] ** 2)) / total if total > 0 else None}


def _per_camera(cameras: list, camera: np.ndarray, v: np.ndarray, rows: np.ndarray) -> dict:
    """{camera name: :func:`_residual_summary`} of the residuals ``v`` (n, 2) px at the observations
    ``rows`` (k,) index of each of ``cameras`` (``camera`` (n,): the observations' camera indices)."""
    return {c.name: _residual_summary(v[rows[r]]) for c, r in zip(cameras, rows_by(camera[rows], len(cameras)))}


def _per_chip(problem, v: np.ndarray, rows: np.ndarray) -> dict:
    """{chip label: :func:`_residual_summary`} of the residuals ``v`` (n, 2) px at the observations
    ``rows`` (k,) index, per chip of every camera of the problem's scene (the rows taken once, not a
    mask of every observation per chip: a region's thousand cameras)."""
    camera, chip = problem.obs.camera[rows], problem.obs.chip[rows]
    return {chip_label(c, k): _residual_summary(v[rows[(camera == ci) & (chip == k)]])
            for ci, c in enumerate(problem.scene.cameras) for k in range(len(c.chips))}


def _residual_summary(v: np.ndarray) -> dict:
    if v.size == 0:
        return {"count": 0}
    px = np.hypot(v[:, 0], v[:, 1])
    return {"count": int(v.shape[0]), "rmse_col": float(np.sqrt(np.mean(v[:, 0] ** 2))),
            "rmse_row": float(np.sqrt(np.mean(v[:, 1] ** 2))), "max_col": float(np.max(np.abs(v[:, 0]))),
            "max_row": float(np.max(np.abs(v[:, 1]))), "max": float(px.max())}


def _trajectory_curves(params: ParameterSet, samples: int = 200) -> dict:
    """Corrections against time of the trajectory parameters ``params`` (of its scene), for plots:
    position (m, ECEF) and attitude (rad); with several trajectory corrections (one per camera, or
    per scene of a block), the reference (first) one's there and every one's in ``per_camera``
    (camera or scene name -> {position, attitude, time: over its own trajectory's span})."""
    groups = trajectory_groups(params.scene)

    def curves(o: int) -> dict:
        t = np.linspace(*params.scene.time_span(next(g for g in groups if params.owners[o][0] in g)), samples)
        corr = params.trajectory_correction(int(params.owners[o][0]))
        return {"time": t.tolist(), "position": (corr.position.matrix(t) @ corr.position_coefficients).tolist(),
                "attitude": (corr.attitude.matrix(t) @ corr.attitude_coefficients).tolist()}

    out = {**curves(0), "position_knots": params.position_basis.knot_times().tolist(),
           "attitude_knots": params.attitude_basis.knot_times().tolist()}
    if len(params.owners) > 1:
        out["per_camera"] = {params.owner_name(o): curves(o) for o in range(len(params.owners))}
    return out
