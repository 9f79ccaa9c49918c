"""The adjustment report for people: one self-contained HTML page.

The page leads with the figures that decide whether to trust the result (sigma0 and its
test, control residuals, check points before and after), then the settings, what the
adjustment decided (non-determinable parameters fixed, gross errors flagged), the interior
and installation parameters with their sigmas, three plots as inline PNG
(:mod:`core.adjust.report_plots`), high correlations, variance components and iterations.

The page is written completely or not at all (:func:`core.files.write_text`).
"""
from __future__ import annotations

import html
import logging

from ..files import OutputSet, write_text
from ..rotations import ARCSEC_PER_RAD
from .checkpoints import model_error_message, without_label
from .datumdirections import beyond_prior
from .report import (control_residual_sentence, datum_sentence, ground_taken_sentence, joint_sentence, joint_sets,
                     plain, robust_limit_sentence, tie_point_lines)
from .report_types import AdjustmentReport, BlockReport
from .report_plots import chip_figure, residual_vector_figure, trajectory_figure
from .scenesigmas import sigmas_text

log = logging.getLogger(__name__)

MAX_LISTED_TRAJECTORY = 24  # trajectory coefficients listed one per row up to this many, else summarised


_STYLE = ("body{font-family:sans-serif;max-width:1150px;margin:2em auto;color:#222;line-height:1.4}"
          "table{border-collapse:collapse;margin:.5em 0 1.5em}td,th{border:1px solid #ccc;padding:3px 8px;"
          "text-align:right}th{background:#f2f2f2}td.l,th.l{text-align:left}.bad{color:#b00}.ok{color:#070}"
          ".big{font-size:1.25em}figure{margin:1em 0 2em}figcaption{font-size:.9em;color:#444;max-width:60em}"
          "img{max-width:100%}")


def write_report_html(report: AdjustmentReport, points: dict, path, title: str = "Bundle adjustment report",
                      files: OutputSet | None = None, preface: str = "") -> None:
    """Write one self-contained HTML page (plots as inline PNG) of an adjustment's ``report`` and
    per-GCP ``points`` (see :class:`core.adjust.engine.AdjustmentResult`) to ``path``,
    completely or not at all (with ``files``, as part of that set). ``preface``: HTML put under
    the title (e.g. :func:`block_section`)."""
    rep = plain(report)
    body = [f"<h1>{html.escape(title)}</h1>", preface, _reliability_section(rep), _headline_section(rep),
            _tie_point_section(rep), _lines_section(rep), _settings_section(rep), _decisions_section(rep),
            _parameters_section(rep),
            "<h2>Plots</h2>",
            residual_vector_figure(points), trajectory_figure(rep["trajectory"]) if rep["trajectory"] else "",
            chip_figure(rep["control_residuals_per_chip"]), _correlations_section(rep),
            _variance_components_section(rep), _iterations_section(rep)]
    page = (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
            f"<style>{_STYLE}</style></head><body>\n" + "\n".join(body) + "\n</body></html>\n")
    write_text(path, page, files)
    log.info("wrote the adjustment report %s", path)


def block_section(block_report: BlockReport) -> str:
    """HTML of a block adjustment's own figures (:class:`core.adjust.report_types.BlockReport`): how the
    datum is held, then per scene and for the block the image residual RMS (px) of control, check
    and tie observations (ties before: the onboard scenes with their onboard intersection) and how
    far each scene's ground moved from its onboard geolocation (an RPC product's: its vendor RPC)
    against its onboard sigma (the vendor's stated accuracy) (m)."""
    rep = plain(block_report)
    block = rep["block"]
    rows = [[html.escape(name), ", ".join(map(html.escape, s["cameras"])),
             f"{s['control']['observations']}", _fmt(s["control"]["rmse_px"]),
             f"{s['check_points']['observations']}", _fmt(s["check_points"]["rmse_px"]),
             f"{s.get('ties', {}).get('observations', 0)}", _fmt(s.get("ties", {}).get("rmse_before_px")),
             _fmt(s.get("ties", {}).get("rmse_px")), _fmt(s["moved_m"], ".1f"),
             _fmt(s.get("vendor_sigma_m") if s.get("model") == "rpc" else s.get("onboard_sigma_m"), ".1f"),
             html.escape(sigmas_text(s["sigmas"])) if "sigmas" in s else "–"]
            for name, s in rep["scenes"].items()]
    rows.append(["<b>block</b>", f"{block['scenes']} scenes", "", _fmt(block["control_rmse_px"]), "",
                 _fmt(block["check_rmse_px"]), "", _fmt(block["tie_rmse_before_px"]), _fmt(block["tie_rmse_px"]),
                 "", "", ""])
    header = ["scene", "cameras", "control obs.", "control RMS px", "check obs.", "check RMS px", "tie obs.",
              "tie RMS before px", "tie RMS after px", "moved m", "onboard / vendor sigma m", "stated sigmas"]
    warnings = "".join(f"<p class='bad'>{html.escape(w)}</p>" for w in block_report.own_warnings())
    return (f"<h2>Block of {block['scenes']} scenes</h2><p class='big'>{html.escape(rep['datum'])}; sigma0 "
            f"{_fmt(block['sigma0'])}.</p>" + warnings + _table(header, rows, left=2) + _block_lines(rep)
            + "".join(f"<p>{html.escape(text)}.</p>" for text in (block.get("accuracy") or {}).get("sentences", []))
            + "<p>Each scene's move is the largest distance between the ground its onboard (or vendor RPC) and its "
              "adjusted model see over its images; the onboard sigma is what POSITION_SIGMA and ATTITUDE_SIGMA "
              "allow, an RPC product's the vendor's stated accuracy (RPC_SIGMA) on the ground; the stated "
              "sigmas are those each scene's pseudo-observations carried, '(own)' where SCENE_SIGMAS gave the scene "
              "its own. The sections below are the adjustment of the whole block (cameras named "
              "&lt;scene&gt;/&lt;camera&gt;).</p>")


def _block_lines(rep: dict) -> str:
    """HTML table of a block's control lines per scene and for the block (lines and points used,
    points flagged, across-line RMS before and after, m); '' without lines."""
    if not rep["block"].get("lines"):
        return ""
    entries = [(html.escape(name), s["lines"]) for name, s in rep["scenes"].items()]
    entries.append(("<b>block</b>", rep["block"]["lines"]))
    rows = [[name, f"{e['lines']}", f"{e['points']}", f"{e['points_flagged']}", _fmt(e["across_rmse_before_m"], ".2f"),
             _fmt(e["across_rmse_m"], ".2f")] for name, e in entries]
    return _table(["scene", "control lines", "line points used", "points flagged", "across-line RMS before m",
                   "across-line RMS after m"], rows)


def _fmt(value, spec: str = ".3f") -> str:
    """``value`` formatted with ``spec``; a dash when it is missing (None)."""
    return "–" if value is None else format(value, spec)


def _table(header: list[str], rows: list[list[str]], left: int = 1) -> str:
    """An HTML table; the first ``left`` columns left-aligned (text), the others right (numbers).
    Cells are HTML already: escape text before passing it."""
    def cells(tag: str, row: list[str]) -> str:
        return "".join(f"<{tag} class='l'>{c}</{tag}>" if i < left else f"<{tag}>{c}</{tag}>"
                       for i, c in enumerate(row))
    return ("<table><tr>" + cells("th", header) + "</tr>"
            + "".join("<tr>" + cells("td", r) + "</tr>" for r in rows) + "</table>")


def _reliability_section(rep: dict) -> str:
    """What makes the result unreliable or the flags incomplete, first of all (empty when nothing)."""
    rel = rep.get("reliability") or {"reliable": True, "problems": []}
    items = [f"<li>{html.escape(p['message'])}</li>" for p in rel["problems"]]
    if rep["robust"].get("stopped_at_limit"):
        items.append(f"<li>{html.escape(robust_limit_sentence(rep))}.</li>")
    items += [f"<li>{html.escape(text)}.</li>" for text in beyond_prior((rep.get("datum") or {}).get("directions", []))]
    if not items:
        return ""
    head = ("<p class='big bad'><b>The result is not reliable</b>: the robust estimation broke down (more "
            "than 40 % of a CCD chip's observations flagged, flagged residuals pointing the same way, or one "
            "chip's residuals much larger than the other chips').</p>" if not rel["reliable"] else
            "<p class='big bad'><b>Warnings</b></p>")
    return head + "<ul class='bad'>" + "".join(items) + "</ul>"


def _sentence_case(text: str) -> str:
    """``text`` with its first letter upper case (the rest as it is)."""
    return text[:1].upper() + text[1:]


def _sigma0_sentence(rep: dict) -> str:
    """sigma0 (unitless: 1 when the residuals match the stated sigmas) and its test."""
    test = rep["sigma0_test"]
    lo, hi = test["ratio_bounds_95"]
    verdict = ("<span class='ok'>passed: the residuals agree with the stated sigmas</span>"
               if test["passed"] else
               "<span class='bad'>failed: the residuals do not agree with the stated sigmas</span>")
    known = (f", the stated sigmas taken as known to {test['stated_dof']} degrees of freedom (about 10 %)"
             if test.get("stated_dof") else "")
    return (f"<p class='big'><b>sigma0 = {_fmt(rep['sigma0'])}</b> (95 % acceptance interval "
            f"{_fmt(lo)}–{_fmt(hi)}{known}): {verdict}.</p>")


def _check_point_row(label: str, figures: dict, count) -> list[str]:
    """One row of the monoplotted check table: image RMSE (px) and ground RMSE, CE90 (m)."""
    img, gnd = figures.get("image") or {}, figures.get("ground") or {}
    return [html.escape(label), str(count), _fmt(img.get("rmse_col")), _fmt(img.get("rmse_row")),
            _fmt(img.get("rmse")), _fmt(img.get("max"), ".2f"), _fmt(gnd.get("rmse_east"), ".2f"),
            _fmt(gnd.get("rmse_north"), ".2f"), _fmt(gnd.get("rmse"), ".2f"), _fmt(gnd.get("ce90"), ".2f"),
            _fmt(gnd.get("max"), ".2f")]


def _intersection_row(label: str, figures: dict, count) -> list[str]:
    """One row of the 3D intersection table (m)."""
    keys = ("rmse_east", "rmse_north", "rmse_plan", "rmse_height", "max_plan", "max_height", "ce90", "le90")
    return [html.escape(label), str(count)] + [_fmt(figures.get(k), ".2f") for k in keys]


def _model_error_note(after: dict) -> str:
    """Why the check points that exceed their sigmas are not left out (empty without a model error)."""
    text = model_error_message(after)
    return f"<p class='big bad'><b>{html.escape(text[:1].upper() + text[1:])}.</b></p>" if text else ""


def _blunder_note(after: dict) -> str:
    """How many check points were left out of the 'without blunders' rows, and why."""
    if not after.get("blunders") or after.get("model_error"):
        return ""
    return (f"<p>{after['blunder_points']} of {after['points']} check points ({after['blunders']} observations) "
            "have residuals beyond what their own sigmas allow: blunders in the check data (few enough not to "
            "point to a model error). The rows 'without' leave those points out; compare them with the rows "
            "over all points.</p>")


def _intersection_section(before: dict, after: dict) -> str:
    """3D check figures: points seen in two or more cameras, intersected (empty when there are none)."""
    inter, prior = after.get("intersection") or {}, before.get("intersection") or {}
    if not inter.get("points"):
        return ""
    n = inter["intersected"]
    notes = []
    if inter.get("single_camera"):
        notes.append(f"{inter['single_camera']} of {inter['points']} check points are seen in one camera only "
                     "and are not intersected")
    if inter.get("failed"):
        notes.append(f"{inter['failed']} could not be intersected")
    if not n:
        return f"<p>3D intersection: no check point is intersected ({'; '.join(notes)}).</p>"
    out = [f"<h3>3D intersection ({n} points in &gt;= 2 cameras)</h3>"]
    rows = [_intersection_row("before (input scene)", prior, prior.get("intersected")),
            _intersection_row("after adjustment", inter, n)]
    if inter.get("blunder_points") and not after.get("model_error"):
        rows.append(_intersection_row(without_label(inter["blunder_points"]),
                                      inter["without_blunders"], n - inter["blunder_points"]))
    out.append(_table(["", "points", "RMSE east m", "RMSE north m", "RMSE plan m", "RMSE height m", "max plan m",
                       "max height m", "CE90 m", "LE90 m"], rows))
    out.append("<p>Each point intersected from all its cameras with the model, compared with its known position "
               "in a local east/north/up frame; one value per point. Plan error = horizontal distance; CE90 / "
               "LE90: 90 % of the points have a smaller plan / absolute height error. Intersection geometry: "
               f"median {_fmt(inter.get('median_condition'), '.2f')} m of point error per px of image error"
               + "".join(f"; {x}" for x in notes) + ".</p>")
    return "\n".join(out)


def _headline_section(rep: dict) -> str:
    """sigma0 and its test, the control residuals and the check points before and after (px and m):
    monoplotted per observation, and intersected in 3D per point."""
    obs, ctl = rep["observations"], rep["control_residuals"]
    left_out = ", flagged observations left out" if rep["robust"]["method"] != "none" else ""
    out = [_sigma0_sentence(rep),
           f"<p>{obs['control_points']} control points ({obs['image_observations']} image observations), "
           f"{obs['check_points']} check points, {obs['unknowns']} adjusted parameters, "
           f"{_fmt(obs['degrees_of_freedom'], '.0f')} degrees of freedom.</p>",
           "<h2>Control point residuals</h2>",
           f"<p class='big'>RMSE col {_fmt(ctl.get('rmse_col'))} px, row {_fmt(ctl.get('rmse_row'))} px; "
           f"largest {_fmt(ctl.get('max'), '.2f')} px ({ctl.get('count', 0)} observations{left_out}).</p>"
           if ctl.get("count") else
           f"<p class='big'>{html.escape(_sentence_case(control_residual_sentence(rep)))}.</p>"]
    if rep.get("control_ground"):
        text = ground_taken_sentence(rep["control_ground"])
        out.append(f"<p>{html.escape(_sentence_case(text))}. The image residuals above are what the ground "
                   "unknowns left; the residuals at the stated ground coordinates are what the adjusted model "
                   "misses by, comparable with the check points'.</p>")
    before, after = rep["check_points_before"], rep["check_points"]
    out.append("<h2>Check points (independent accuracy)</h2>")
    if not after.get("points"):
        out.append("<p>No check points: the accuracy of the result is not measured independently.</p>")
        return "\n".join(out)
    out.append(_model_error_note(after))
    out.append(_intersection_section(before, after))
    n_obs = after.get("observations", after["points"]) - after.get("not_imaged", 0)
    rows = [_check_point_row("before (input scene)", before,
                             before.get("observations", 0) - before.get("not_imaged", 0)),
            _check_point_row("after adjustment", after, n_obs)]
    if after.get("blunders") and not after.get("model_error"):
        rows.append(_check_point_row(without_label(after["blunder_points"]),
                                     after["without_blunders"], n_obs - after["blunders"]))
    out.append(f"<h3>Monoplotted, per observation ({after['points']} points, {n_obs} observations)</h3>")
    out.append(_table(["", "observations", "RMSE col px", "RMSE row px", "RMSE px", "max px", "RMSE east m",
                       "RMSE north m", "RMSE m", "CE90 m", "max m"], rows))
    out.append("<p>Each observation on its own: image residual of the known ground point (px), and the image "
               "position projected to the ground at the known height (m, plan only).</p>")
    out += [f"<p class='bad'>{c['not_imaged']} check observation(s) left out {label}: the model does not image their "
            f"ground (far outside its domain: a wrong coordinate?): {html.escape(', '.join(c['not_imaged_ids'][:10]))}"
            "</p>" for label, c in (("before", before), ("after", after)) if c.get("not_imaged")]
    out.append(_blunder_note(after))
    return "\n".join(x for x in out if x)


def _tie_point_section(rep: dict) -> str:
    """Tie points used and left out, their image residuals per camera and how the datum is held
    (empty without tie points)."""
    ties = rep.get("tie_points")
    if not ties:
        return ""
    items = [f"<li>{html.escape(text)}</li>" for text, _ in tie_point_lines(ties)]
    if rep.get("datum"):
        items.append(f"<li>{html.escape(datum_sentence(rep))}</li>")
    rows = [[html.escape(cam), str(r.get("count", 0)), _fmt(r.get("rmse_col")), _fmt(r.get("rmse_row")),
             _fmt(r.get("max"), ".2f")] for cam, r in ties["residuals_per_camera"].items()]
    return ("<h2>Tie points</h2><ul>" + "".join(items) + "</ul>"
            + _table(["camera", "observations", "RMSE col px", "RMSE row px", "max px"], rows)
            + f"<p>{html.escape(ties['relative_accuracy'])}.</p>")


MAX_LISTED_LINES = 200  # per-line rows listed at most (the rest counted; all are in OUTPUT_LINE_RESIDUALS)


def _lines_section(rep: dict) -> str:
    """Control lines (Tommaselli & Marcato Junior 2012): lines and points used, across-line RMSE
    before and after, lines named wrong as a whole, whether the lines' directions determine both
    horizontal directions, and per line its figures (empty without lines)."""
    lines = rep.get("lines")
    if not lines:
        return ""
    directions = lines["directions"]
    wrong = lines["flagged_line_ids"]
    items = [f"{lines['lines']} lines, {lines['points']} line points (each {lines['constraints_per_point']} "
             f"constraints: across the line and in height); {lines['flagged_points']} points flagged",
             f"across-line RMSE {_fmt(lines['across_rmse_before_m'], '.2f')} m before (onboard model), "
             f"{_fmt(lines['across_rmse_m'], '.2f')} m after; height RMSE {_fmt(lines['height_rmse_m'], '.2f')} m "
             "(points not flagged)",
             f"{lines['flagged_lines']} lines do not fit as a whole (wrong road or shifted in the map; their "
             "constraints released)" + (": " + ", ".join(wrong[:30]) + (" …" if len(wrong) > 30 else "")
                                        if wrong else "")]
    note = (f"directions: lines run along {_fmt(directions['azimuth_deg'], '.0f')}° with a spread of "
            f"{_fmt(directions['spread_deg'], '.1f')}°" + ("; both horizontal directions determined"
                                                           if directions["determined"] else
                                                           f" — {directions['message']}"))
    per = lines["per_line"]
    order = sorted(range(len(per["line_id"])), key=lambda i: (not per["flagged"][i], str(per["line_id"][i])))
    rows = [[html.escape(str(per["line_id"][i])), str(per["points"][i]), _fmt(per["rms_across_m"][i], ".2f"),
             _fmt(per["max_across_m"][i], ".2f"), str(per["points_flagged"][i]),
             "<b>wrong</b>" if per["flagged"][i] else ""] for i in order[:MAX_LISTED_LINES]]
    more = (f"<p>{len(order) - MAX_LISTED_LINES} more lines not listed (all are in the line residuals "
            "output).</p>" if len(order) > MAX_LISTED_LINES else "")
    warn = "" if directions["determined"] else " class='bad'"
    return ("<h2>Control lines</h2><ul>" + "".join(f"<li>{html.escape(t)}</li>" for t in items)
            + f"<li{warn}>{html.escape(note)}</li></ul>"
            + _table(["line", "points", "RMS across m", "max across m", "points flagged", ""], rows) + more)


def _settings_section(rep: dict) -> str:
    """The adjustment settings as given."""
    rows = [[html.escape(str(k)), html.escape("–" if v is None else str(v))] for k, v in rep["settings"].items()]
    return "<h2>Settings</h2>" + _table(["setting", "value"], rows, left=2)


def _decisions_section(rep: dict) -> str:
    """Non-determinable parameter sets and the parameter fixed in each; gross error detection."""
    items = [f"<li>Not determinable together: {html.escape(', '.join(d['parameters']))}; "
             f"<b>{html.escape(d['fixed'])}</b> was fixed.</li>" if d.get("fixed") else
             f"<li>Not determinable together: {html.escape(', '.join(d['parameters']))}; "
             "nothing was fixed.</li>" for d in rep["determinability"]]
    items += _selection_items(rep.get("interior_selection"))
    rob = rep["robust"]
    if rob["method"] == "none":
        items.append("<li>No gross error detection (robust = none): every observation kept its full weight.</li>")
    else:
        ids = ", ".join(rob["flagged_ids"][:30]) + (", …" if rob["flagged"] > 30 else "")
        limit = " (stopped at the pass limit: the flags may be incomplete)" if rob.get("stopped_at_limit") else ""
        items.append(f"<li>Gross errors ({html.escape(rob['method'])}): {rob['flagged']} image observations "
                     f"flagged (normalised residual |w| &gt; {_fmt(rob['critical_w'], '.2f')}, against the sigmas "
                     f"rescaled by the variance components) in {len(rob['passes'])} passes{limit}; they stay in "
                     "the GCP layer" + (" and the tie-point output" if rep.get("tie_points") else "") + ", marked"
                     + (f": {html.escape(ids)}" if ids else "") + ".</li>")
    if rep.get("datum"):
        d = rep["datum"]
        lines = f", {d['control_lines']} control lines" if d.get("control_lines") else ""
        items.append(f"<li>Datum held by {html.escape(d['held_by'])} ({d['control_points']} control points{lines})"
                     + (f": {html.escape(d['note'])}" if d.get("note") else "") + ".</li>")
    return "<h2>Decisions</h2><ul>" + "".join(items) + "</ul>"


def _selection_items(sel: dict | None) -> list[str]:
    """Interior parameter selection: removed parameters and why, kept ones, the guard's verdict."""
    if not sel:
        return []
    items = [f"<li>Interior parameter removed: <b>{html.escape(r['name'])}</b> "
             f"({html.escape('; '.join(r['fails']))}).</li>" for r in sel["removed"]]
    kept = ", ".join(f"{k['name']} (t = {k['t']:.1f})" for k in sel["kept"] if not k.get("held_by_prior")) or "none"
    items.append(f"<li>Interior parameters kept after {sel['rounds']} removal rounds: {html.escape(kept)}.</li>")
    items += [f"<li>Interior parameter held by its prior (kept; the control alone cannot support it): "
              f"<b>{html.escape(k['name'])}</b> ({html.escape(k['held_by_prior'])}).</li>"
              for k in sel["kept"] if k.get("held_by_prior")]
    g = sel["guard"]
    items.append("<li>Self-calibration kept: it fits significantly better than no interior parameters "
                 f"(F = {_fmt(g['F'], '.3g')} &gt; {_fmt(g['F_critical'], '.3g')}).</li>" if g["self_calibration_kept"]
                 else "<li><b>Fell back to the conventional adjustment</b> (no interior parameters): "
                 f"{html.escape(g['reason'])}.</li>")
    return items


def _display_value(value, unit: str, block: str) -> tuple[float | None, str]:
    """A parameter value (SI) in the unit a photogrammetrist reads: angles in arcsec, focal-plane
    shifts (camera and chip blocks) in µm; other units unchanged."""
    if value is None:
        return None, unit
    if unit == "rad":
        return value * ARCSEC_PER_RAD, "arcsec"
    if unit == "m" and block in ("camera", "chip"):
        return value * 1e6, "µm"
    return value, unit


def _parameter_row(p: dict, fixed_by_determinability: set) -> list[str]:
    """One parameter's table row: value and sigma in display units, |value|/sigma, significance."""
    value, unit = _display_value(p["value"], p["unit"], p["block"])
    sigma, _ = _display_value(p["sigma"], p["unit"], p["block"])
    mode = "fixed (not determinable)" if p["name"] in fixed_by_determinability else p["mode"]
    ratio = _fmt(abs(p["value"]) / p["sigma"], ".1f") if p["sigma"] else "–"
    significant = "–" if p["significant"] is None else ("yes" if p["significant"] else "no")
    return [html.escape(p["name"]), html.escape(mode), _fmt(value, ".4g"), _fmt(sigma, ".3g"),
            html.escape(unit), ratio, significant]


def _trajectory_summary_rows(params: list[dict]) -> list[list[str]]:
    """Per trajectory axis (e.g. position.X, or FWD.position.X with a correction per camera):
    coefficient count, largest |value| and largest sigma."""
    axes: dict[str, list[dict]] = {}
    for p in params:
        parts = p["name"].split(".")
        axes.setdefault(".".join(parts[:2] if parts[0] == p["block"] else parts[:3]), []).append(p)
    rows = []
    for axis, ps in axes.items():
        unit = _display_value(0.0, ps[0]["unit"], ps[0]["block"])[1]
        largest = max(abs(_display_value(p["value"], p["unit"], p["block"])[0]) for p in ps)
        sigmas = [_display_value(p["sigma"], p["unit"], p["block"])[0] for p in ps if p["sigma"] is not None]
        rows.append([html.escape(axis), str(len(ps)), _fmt(largest, ".4g"),
                     _fmt(max(sigmas) if sigmas else None, ".3g"), html.escape(unit)])
    return rows


def _parameters_section(rep: dict) -> str:
    """Interior and installation parameters (free, weighted, or fixed by the determinability
    check or at a non-zero value) and the trajectory corrections, listed or summarised per axis."""
    fixed = {d["fixed"] for d in rep["determinability"] if d.get("fixed")}
    interior = [p for p in rep["parameters"] if p["block"] not in ("position", "attitude")
                and (p["mode"] != "fixed" or p["value"] or p["name"] in fixed)]
    trajectory = [p for p in rep["parameters"] if p["block"] in ("position", "attitude")]
    header = ["parameter", "mode", "value", "sigma", "unit", "|value|/sigma", "significant (95 %)"]
    out = ["<h2>Interior and installation parameters</h2>"]
    out.append(_table(header, [_parameter_row(p, fixed) for p in interior], left=2) if interior else
               "<p>No interior or installation parameter was estimated.</p>")
    out.append("<h2>Trajectory corrections</h2>")
    if len(trajectory) <= MAX_LISTED_TRAJECTORY:
        out.append(_table(header[:6], [_parameter_row(p, fixed)[:6] for p in trajectory], left=2))
    else:
        out.append(f"<p>{len(trajectory)} coefficients, summarised per axis (all of them are in the JSON "
                   "report); the curves are plotted below.</p>")
        out.append(_table(["axis", "coefficients", "largest |value|", "largest sigma", "unit"],
                          _trajectory_summary_rows(trajectory)))
    return "\n".join(out)


def _correlations_section(rep: dict) -> str:
    """Pairs of adjusted parameters with high correlation (as selected by the engine)."""
    rows = [[html.escape(c["a"]), html.escape(c["b"]), _fmt(c["r"], ".4f")] for c in rep["high_correlations"]]
    return ("<h2>High correlations</h2><p>|r| &gt; 0.9 where an interior parameter takes part, |r| &gt; 0.999 "
            "between trajectory terms.</p>"
            + (_table(["parameter", "parameter", "r"], rows, left=2) if rows else "<p>None.</p>"))


def _variance_components_section(rep: dict) -> str:
    """Per observation group: stated and estimated sigma, their ratio and its test, redundancy."""
    def row(k: str, v: dict) -> list[str]:
        test = "–" if v.get("passed") is None else ("<span class='ok'>passed</span>" if v["passed"] else
                                                     "<span class='bad'>failed</span>")
        used = ("at the floor 0.01 x stated (far more precise than stated)" if v.get("held_at_floor") else
                "yes" + (f", one factor with {', '.join(v['joint_with'])}" if v.get("joint_with") else "")) \
            if v.get("estimated") else "no (redundancy below 10)"
        return [html.escape(k), str(v.get("observations", "–")), _fmt(v.get("redundancy"), ".1f"),
                _fmt(v.get("apriori_sigma"), ".4g"), _fmt(v.get("estimated_sigma"), ".4g"),
                html.escape(v.get("unit") or ""), _fmt(v.get("sigma0")), test, used]
    rows = [row(k, v) for k, v in rep["variance_components"].items()]
    return ("<h2>Variance components</h2><p>Per observation group, the stated (a-priori, median) sigma and the "
            "sigma the residuals of the inliers imply (Förstner's estimator); their ratio is the group's sigma0. "
            "Estimated factors replace the stated sigmas before the outlier test and in the check-point blunder "
            "test; the test allows the stated sigma 10 % of its own (F test, 50 degrees of freedom).</p>"
            + "".join(f"<p>{html.escape(joint_sentence(m)[:1].upper() + joint_sentence(m)[1:])}.</p>"
                      for m in joint_sets(rep["variance_components"]))
            + _table(["group", "observations", "redundancy", "stated sigma", "estimated sigma", "unit",
                      "ratio", "test (95 %)", "used"], rows))


def _iterations_section(rep: dict) -> str:
    """The robust passes (if any) and the Gauss-Newton iterations of the last pass."""
    out = []
    passes = rep["robust"]["passes"]
    if passes:
        out.append("<h2>Robust passes</h2>" + _table(
            ["pass", "sigma0", "down-weighted observations", "largest weight change", "largest component change"],
            [[str(p["pass"]), _fmt(p["sigma0"]), str(p["down_weighted"]), _fmt(p["largest_change"], ".3g"),
              _fmt(p.get("component_change"), ".3g")] for p in passes]))
    out.append("<h2>Iterations (last pass)</h2>" + _table(
        ["#", "weighted squared residuals", "largest image change px", "damping"],
        [[str(i["iteration"]), _fmt(i["cost"], ".6g"), _fmt(i["max_image_change_px"], ".3g"),
          _fmt(i.get("damping"), ".3g")] for i in rep["iterations"]]))
    return "\n".join(out)
