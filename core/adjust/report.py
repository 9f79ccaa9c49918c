"""Adjustment reports for machines and for the log: the report as strict JSON, and the
sentences the run leaves in the log (how the result is to be trusted, what was decided, tie
points, control lines), each with whether it is a warning.

The HTML page for people is :mod:`core.adjust.report_html`. The JSON file is written completely
or not at all (:func:`core.files.write_text`).
"""
from __future__ import annotations

import json
import logging
import math
from collections.abc import Mapping

import numpy as np

from ..files import OutputSet, write_text
from ..log import LogLine
from .checkpoints import model_error_message, summary_lines
from .datumdirections import beyond_prior

log = logging.getLogger(__name__)


# --- JSON ---------------------------------------------------------------------------------------
def plain(value):
    """JSON-ready copy of ``value``: numpy scalars and arrays become Python numbers and lists,
    NaN and infinities become None, dict keys strings, a report (:mod:`core.adjust.report_types`) its
    JSON; other objects (paths, enums) their str()."""
    if isinstance(value, Mapping):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return plain(value.tolist())
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    if value is None or isinstance(value, str):
        return value
    return str(value)


def report_to_json(report: Mapping) -> str:
    """The report as strict JSON text (numpy types converted, NaN and infinities as null)."""
    return json.dumps(plain(report), indent=1, allow_nan=False)


def write_report_json(report: Mapping, path, files: OutputSet | None = None) -> None:
    """Write the report as JSON to ``path``, completely or not at all (with ``files``, as part of
    that set)."""
    write_text(path, report_to_json(report), files)
    log.info("wrote the adjustment report %s", path)


# --- sentences for the log ------------------------------------------------------------------
LEFT_OUT_REASONS = {"single_ray": "seen by one camera only (one ray fixes no ground position)",
                    "not_intersected": "their onboard rays could not be intersected"}


def datum_sentence(rep: Mapping, article: str = "") -> str:
    """How the datum of an adjustment ``report`` is held, in one sentence: with tie points as its
    ``datum`` says (held by what, and the note), without them by the control points or lines.
    article: put before what holds it ('the ' in a block report, whose JSON has said so)."""
    held = rep.get("datum")
    if held is None:  # no tie points: each scene held by its own control, points or lines
        if "lines" not in rep:
            return f"datum held by {article}control points (no tie points)"
        points = rep["observations"]["control_points"]
        return f"datum held by {article}control lines{' and points' if points else ''} (no tie points)"
    return f"datum held by {article}{held['held_by']}" + (f": {held['note']}" if held.get("note") else "")


def tie_point_lines(ties: dict) -> list[tuple[str, bool]]:
    """The tie-point figures of ``report["tie_points"]`` as (sentence, is_warning): points and
    observations used, those left out and why, flagged observations, image residual RMS per camera,
    and their heights held to a reference DEM (how many, how many left free off it, their fit)."""
    lines = [(f"tie points: {ties['points']} points, {ties['observations']} of {ties['input_observations']} "
              f"observations used; {ties['flagged']} observations flagged as gross errors", False)]
    for reason, left in ties.get("left_out", {}).items():
        named = ", ".join(left["ids"][:10]) + (" ..." if left["points"] > 10 else "")
        lines.append((f"tie points left out: {left['points']} {LEFT_OUT_REASONS.get(reason, reason)}: {named}", True))
    weak = ties.get("from_height", {})
    if weak.get("points"):
        named = ", ".join(weak["ids"][:10]) + (" ..." if weak["points"] > 10 else "")
        lines.append((f"tie points started from a height instead of an intersection: {weak['points']} whose rays "
                      f"meet at less than {weak['min_convergence_deg']:g}° (seen along one line, e.g. by "
                      f"consecutive products of one strip), on their first ray at {weak['height']}; "
                      + ("the reference DEM holds their heights" if weak.get("held_by_dem") else
                         "nothing holds their heights (their adjusted heights are undetermined; DEM with "
                         "TIE_HEIGHT_SIGMA holds them), their rays still tie the products")
                      + f": {named}", True))
    res = ties["residuals"]
    if res.get("count"):
        per = "; ".join(f"{cam} {r['rmse_col']:.3f} / {r['rmse_row']:.3f} px ({r['count']})"
                        for cam, r in ties["residuals_per_camera"].items() if r.get("count"))
        lines.append((f"tie residuals RMSE col / row {res['rmse_col']:.3f} / {res['rmse_row']:.3f} px "
                       f"(largest {res['max']:.2f} px, flagged left out); per camera: {per}", False))
    heights = ties.get("heights")
    if heights:  # held to a reference DEM (core.adjust.tieheights); points off it or on its holes are free
        lines.append((heights["sentence"], bool(heights["off_dem"] + heights["on_holes"])))
    return lines


def joint_sets(components: dict) -> list[list[str]]:
    """The groups of ``report["variance_components"]`` that share one factor, each set once."""
    out = []
    for group, c in components.items():
        members = [group, *c.get("joint_with", [])]
        if len(members) > 1 and not any(group in m for m in out):
            out.append(members)
    return out


def joint_sentence(members: list[str]) -> str:
    """Why the groups ``members`` share one variance component factor."""
    names = ", ".join(members[:-1]) + " and " + members[-1]
    return (f"the variance components of {names} cannot be told apart (their residuals are nearly proportional, "
            "e.g. points seen in one image split their misfit between image and ground in the ratio of the stated "
            "sigmas): one factor is estimated for them, their split kept as stated")


def residual_text(summary: dict, none: str) -> str:
    """'RMSE col x px, row y px' of a residual summary (``{"count", "rmse_col", "rmse_row", ...}``),
    or ``none`` when it counts nothing: never a NaN."""
    if not summary.get("count"):
        return none
    return f"RMSE col {summary['rmse_col']:.3f} px, row {summary['rmse_row']:.3f} px"


def control_residual_sentence(rep: Mapping) -> str:
    """The control residuals of ``report`` in words: their RMSE, or that there are no control points
    (a block held by tie points and priors), or that none was left (all flagged)."""
    n = rep["observations"]["control_points"]
    none = "no control points" if not n else f"none left of the {n} control points (all flagged)"
    text = residual_text(rep["control_residuals"], none)
    return f"control residuals {text}" if rep["control_residuals"].get("count") else f"control residuals: {text}"


def ground_taken_sentence(ground: dict) -> str:
    """What the control points' ground unknowns took of their misfit (``report["control_ground"]``)."""
    at = residual_text(ground["at_stated_ground"], "none (no control point is imaged at its stated ground)")
    share = ground.get("ground_share")
    took = f" took {100 * share:.1f} % of the misfit" if share is not None else ""
    return (f"control points: their ground unknowns{took} (shifts RMSE {ground['shift_rmse_horizontal_m']:.3f} m "
            f"horizontal, {ground['shift_rmse_vertical_m']:.3f} m vertical); residuals at the stated ground "
            f"coordinates {at}")


ONBOARD_SIGMA_PARAMETERS = (("POSITION_SIGMA", "position_sigma", "GNSS position"),
                            ("ATTITUDE_SIGMA", "attitude_sigma", "attitude"))


def onboard_advice(settings: dict) -> str:
    """What holds two correlated trajectory corrections apart, from the run's ``settings``: the
    onboard sigmas given, and which to give (those left empty: no pseudo-observations)."""
    given = [name for name, key, _ in ONBOARD_SIGMA_PARAMETERS if settings.get(key) is not None]
    missing = [(name, what) for name, key, what in ONBOARD_SIGMA_PARAMETERS if settings.get(key) is None]
    held = f"their split rests on {' and '.join(given)}" if given else "nothing but the GCPs holds their split"
    if not missing:
        return held
    return (f"{held}; give {' and '.join(name for name, _ in missing)} (the onboard "
            f"{' and '.join(what for _, what in missing)} accuracy) to hold it")


def robust_limit_sentence(rep: Mapping) -> str:
    """The warning of a robust estimation stopped at its pass limit (``report["robust"]``)."""
    return (f"robust estimation stopped at its limit of {len(rep['robust']['passes'])} passes; the flags may be "
            "incomplete")


def report_warnings(rep: Mapping) -> list[str]:
    """The warnings of an adjustment ``report``, for its JSON (``warnings``) and a block's: the robust
    estimation stopped at its pass limit, the reliability problems, and the datum directions the tie
    points moved along beyond the priors' sigma (:func:`core.adjust.datumdirections.beyond_prior`)."""
    out = [robust_limit_sentence(rep)] if rep["robust"]["stopped_at_limit"] else []
    out += [p["message"] + ("" if p["reliable"] else "; the result is not reliable")
            for p in rep["reliability"]["problems"]]
    return out + beyond_prior((rep.get("datum") or {}).get("directions", []))


def log_lines(report: Mapping, tie_observations: int | None = None) -> list[LogLine]:
    """What the log says after an adjustment, from its ``report`` (:class:`core.adjust.report_types.
    AdjustmentReport`): the outcome (correlations, fixed parameters, variance components, robust
    estimation, reliability, sigma0, control and check point figures), then the tie points
    (``tie_observations``: how many were given; None without tie points) and the control lines."""
    return [*outcome_lines(report), *tie_lines(report, tie_observations), *control_line_lines(report.get("lines"))]


def outcome_lines(rep: Mapping) -> list[LogLine]:
    """The RPC correction chosen by default (RPC_CORRECTION=auto), correlations the control hardly
    separates, parameters fixed as not determinable, variance components, observations held flagged
    and a robust estimation stopped at its limit, reliability problems, sigma0 and the control
    residuals, and the check point figures before and after."""
    out = [LogLine(rep["rpc_correction"]["sentence"])] if rep.get("rpc_correction") else []
    out += [LogLine(f"{c['a']} and {c['b']} are correlated {c['r']:.4f}: the GCPs hardly separate them; "
                    f"{onboard_advice(rep.get('settings', {}))}", True)
            for c in rep["high_correlations"] if c["trajectory"]]
    out += [LogLine(f"not determinable together from these GCPs: {', '.join(d['parameters'])}; {d['fixed']} was "
                    "fixed at its input value (ON_SINGULAR)", True) for d in rep["determinability"]]
    for group, c in rep["variance_components"].items():
        if c["apriori_sigma"] is not None and c["estimated_sigma"] is not None:
            joint = c.get("joint_with")
            how = (f"; one factor with {', '.join(joint)}" if joint else "") if c["estimated"] else \
                ", holds the datum: not estimated" if c.get("holds_datum") else ", too small: not used"
            out.append(LogLine(f"variance component {group}: stated sigma {c['apriori_sigma']:.4g} {c['unit']}, "
                               f"estimated {c['estimated_sigma']:.4g} {c['unit']} (redundancy "
                               f"{c['redundancy']:.1f}{how})"))
    out += [LogLine(joint_sentence(members)) for members in joint_sets(rep["variance_components"])]
    if rep["robust"].get("held_flagged"):
        out.append(LogLine(f"{rep['robust']['held_flagged']} observations near the critical value were flagged, "
                           "released and flagged again by the robust passes: they were held flagged (the loop would "
                           "otherwise swing between two sets of flags)"))
    if rep["robust"]["stopped_at_limit"]:
        out.append(LogLine(robust_limit_sentence(rep), True))
    out += [LogLine(p["message"] + ("" if p["reliable"] else "; the result is not reliable"), True)
            for p in rep["reliability"]["problems"]]
    out.append(LogLine(f"{sigma0_sentence(rep)}; {control_residual_sentence(rep)}; {rep['robust']['flagged']} "
                       "observations flagged as gross errors"))
    if rep.get("control_ground"):
        out.append(LogLine(ground_taken_sentence(rep["control_ground"])))
    before, after = rep["check_points_before"], rep["check_points"]
    if after.get("model_error"):
        out.append(LogLine(model_error_message(after), True))
    out += [LogLine(f"check points {line}") for line in summary_lines(before, after)]
    return out


def sigma0_sentence(rep: Mapping) -> str:
    """'sigma0 0.912 (passes the 95 % test)'; without redundancy to estimate it, says so."""
    sigma0 = rep.get("sigma0")
    if sigma0 is None or not math.isfinite(sigma0):
        return "sigma0 not estimated (no redundancy left among the observations kept)"
    return f"sigma0 {sigma0:.3f} ({'passes' if rep['sigma0_test']['passed'] else 'fails'} the 95 % test)"


def tie_lines(rep: Mapping, tie_observations: int | None) -> list[LogLine]:
    """The tie-point figures (:func:`tie_point_lines`) and how the datum is held; a warning when
    tie points were given (``tie_observations`` of them) but none entered the adjustment."""
    out = []
    if tie_observations is not None and not rep.get("tie_points"):
        out.append(LogLine(f"none of the {tie_observations} tie observations entered the adjustment (no point is "
                           "seen in two or more cameras); the GCPs alone adjusted the block", True, "ties"))
    out += [LogLine(text, warning) for text, warning in tie_point_lines(rep["tie_points"])] \
        if rep.get("tie_points") else []
    if rep.get("datum"):
        out.append(LogLine(datum_sentence(rep)))
        out += [LogLine(text, True) for text in beyond_prior(rep["datum"].get("directions", []))]
    return out


def control_line_lines(rep: dict | None) -> list[LogLine]:
    """The control lines' figures (``report["lines"]``, None without lines): lines, points and the
    across-line RMSE before and after, lines released as a whole, undetermined directions."""
    if rep is None:
        return []
    across = "no line point left (all flagged)" if rep["across_rmse_m"] is None else \
        f"{rep['across_rmse_m']:.2f} m (before {rep['across_rmse_before_m']:.1f} m)"
    out = [LogLine(f"control lines: {rep['lines']} lines, {rep['points']} points (2 constraints each); across-line "
                   f"RMSE {across}, {rep['flagged_points']} points flagged")]
    if rep["flagged_lines"]:
        out.append(LogLine(f"{rep['flagged_lines']} control line(s) do not fit as a whole (a wrong road or a shifted "
                           "map line) and were released: " + ", ".join(rep["flagged_line_ids"][:50]), True))
    if not rep["directions"]["determined"]:
        out.append(LogLine(f"control lines: {rep['directions']['message']}", True))
    return out
