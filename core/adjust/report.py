"""Adjustment reports: JSON for machines, one self-contained HTML page for people.

The HTML page leads with the figures that decide whether to trust the result (sigma0 and its
test, control residuals, check points before and after), then what the adjustment decided
(non-determinable parameters fixed, gross errors flagged), the interior parameters with
their sigmas, and three plots as inline PNG: image residual vectors over the image (seed 000
Fig. 6), trajectory corrections against time (Fig. 7-11) and residuals per CCD chip.
Both files are written completely or not at all (temporary file, then rename).
"""
from __future__ import annotations

import base64
import html
import io
import json
import math
from pathlib import Path

import numpy as np

MAX_ARROWS = 5000


def _plain(value):
    """JSON-ready copy: numpy scalars and arrays to Python, NaN and infinities to None."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, (np.bool_, bool)):
        return bool(value)
    if isinstance(value, (np.integer, int)):
        return int(value)
    if isinstance(value, (np.floating, float)):
        return float(value) if math.isfinite(value) else None
    return value


def report_to_json(report: dict) -> str:
    return json.dumps(_plain(report), indent=1, allow_nan=False)


def _write_atomically(path, text: str) -> None:
    path = Path(path)
    tmp = path.with_name(path.name + ".part")
    try:
        tmp.write_text(text, encoding="utf-8")
        tmp.replace(path)
    finally:
        tmp.unlink(missing_ok=True)


def write_report_json(report: dict, path) -> None:
    """The report as JSON (NaN as null)."""
    _write_atomically(path, report_to_json(report))


# --- HTML --------------------------------------------------------------------------------------
def write_report_html(report: dict, points: dict, path, title: str = "Bundle adjustment report") -> None:
    """One self-contained HTML page (plots inline) of an adjustment's report and points."""
    import matplotlib
    matplotlib.use("Agg")
    rep = _plain(report)
    body = [f"<h1>{html.escape(title)}</h1>", _headline(rep), _decisions(rep), _parameter_table(rep),
            _figure("Image residual vectors of the control points", _residual_plot(points)),
            _figure("Trajectory corrections against time", _trajectory_plot(rep["trajectory"])),
            _figure("Residuals per CCD chip", _chip_plot(rep["control_residuals_per_chip"])),
            _correlations(rep), _components(rep), _iterations(rep), _settings(rep)]
    page = ("<!DOCTYPE html><html><head><meta charset='utf-8'><title>" + html.escape(title) + "</title><style>"
            "body{font-family:sans-serif;max-width:1100px;margin:2em auto;color:#222}"
            "table{border-collapse:collapse;margin:.5em 0 1.5em}td,th{border:1px solid #ccc;padding:3px 8px;"
            "text-align:right}th{background:#f2f2f2}td.l,th.l{text-align:left}.bad{color:#b00}.ok{color:#070}"
            "img{max-width:100%}</style></head><body>" + "\n".join(body) + "</body></html>")
    _write_atomically(path, page)


def _num(v, spec: str = ".3f") -> str:
    return "–" if v is None else format(v, spec)


def _table(header: list[str], rows: list[list[str]], left: int = 1) -> str:
    th = "".join(f"<th class='l'>{h}</th>" if i < left else f"<th>{h}</th>" for i, h in enumerate(header))
    trs = "".join("<tr>" + "".join(f"<td class='l'>{c}</td>" if i < left else f"<td>{c}</td>"
                                   for i, c in enumerate(r)) + "</tr>" for r in rows)
    return f"<table><tr>{th}</tr>{trs}</table>"


def _headline(rep: dict) -> str:
    test = rep["sigma0_test"]
    verdict = ("<span class='ok'>consistent with the stated sigmas</span>" if test["passed"] else
               "<span class='bad'>not consistent with the stated sigmas (95 % bounds "
               f"{test['ratio_bounds_95'][0]:.3f}–{test['ratio_bounds_95'][1]:.3f})</span>")
    obs = rep["observations"]
    ctl = rep["control_residuals"]
    rows = []
    for label, key in (("before (input scene)", "check_points_before"), ("after", "check_points")):
        c = rep[key]
        img, gnd = c.get("image") or {}, c.get("ground") or {}
        rows.append([label, _num(img.get("rmse_col")), _num(img.get("rmse_row")), _num(img.get("max")),
                     _num(gnd.get("rmse_east"), ".2f"), _num(gnd.get("rmse_north"), ".2f"),
                     _num(gnd.get("ce90"), ".2f"), _num(gnd.get("max"), ".2f")])
    clean = rep["check_points"].get("without_blunders") or {}
    if rep["check_points"].get("blunders"):
        img, gnd = clean.get("image") or {}, clean.get("ground") or {}
        rows.append([f"after, without {rep['check_points']['blunders']} blunders", _num(img.get("rmse_col")),
                     _num(img.get("rmse_row")), _num(img.get("max")), _num(gnd.get("rmse_east"), ".2f"),
                     _num(gnd.get("rmse_north"), ".2f"), _num(gnd.get("ce90"), ".2f"), _num(gnd.get("max"), ".2f")])
    return (f"<p><b>sigma0 = {rep['sigma0']:.3f}</b>, {verdict}; {obs['control_points']} control points, "
            f"{obs['image_observations']} image observations, {obs['check_points']} check points, "
            f"{obs['unknowns']} parameters, {obs['degrees_of_freedom']:.0f} degrees of freedom.</p>"
            f"<p>Control residuals: RMSE col {_num(ctl.get('rmse_col'))} px, row {_num(ctl.get('rmse_row'))} px, "
            f"max {_num(ctl.get('max'), '.2f')} px ({ctl.get('count', 0)} observations"
            f"{', flagged ones left out' if rep['robust']['method'] != 'none' else ''}).</p>"
            "<h2>Check points</h2>"
            + _table(["", "RMSE col px", "RMSE row px", "max px", "RMSE east m", "RMSE north m", "CE90 m", "max m"],
                     rows))


def _decisions(rep: dict) -> str:
    out = []
    for d in rep["determinability"]:
        out.append(f"<li class='bad'>Not determinable together: {html.escape(', '.join(d['parameters']))}; "
                   f"<b>{html.escape(d['fixed'])}</b> was fixed.</li>")
    rob = rep["robust"]
    if rob["method"] != "none":
        out.append(f"<li>Gross errors ({html.escape(rob['method'])}): {rob['flagged']} image observations flagged "
                   f"(|w| &gt; {rob['critical_w']:.2f}) in {len(rob['passes'])} passes; they stay in the GCP layer, "
                   "marked.</li>")
    return "<h2>Decisions</h2><ul>" + ("".join(out) or "<li>None needed.</li>") + "</ul>"


def _parameter_table(rep: dict) -> str:
    rows = []
    trajectory = {"position": [], "attitude": []}
    for p in rep["parameters"]:
        if p["block"] in trajectory:
            trajectory[p["block"]].append(p)
            continue
        if p["mode"] == "fixed" and not p["value"]:
            continue
        sig = "" if p["significant"] is None else ("yes" if p["significant"] else "no")
        rows.append([html.escape(p["name"]), p["mode"], f"{p['value']:.6g}", _num(p["sigma"], ".3g"),
                     html.escape(p["unit"]), sig])
    summary = "".join(
        f"<li>{block}: {len(ps)} coefficients, largest |value| {max(abs(p['value']) for p in ps):.4g} "
        f"{html.escape(ps[0]['unit'])}</li>" for block, ps in trajectory.items() if ps)
    table = _table(["parameter", "mode", "value", "sigma", "unit", "significant"], rows) if rows else \
        "<p>No interior or installation parameter was estimated.</p>"
    return f"<h2>Interior and installation parameters</h2>{table}<p>Trajectory corrections:</p><ul>{summary}</ul>"


def _correlations(rep: dict) -> str:
    rows = [[html.escape(c["a"]), html.escape(c["b"]), f"{c['r']:.4f}"] for c in rep["high_correlations"][:20]]
    return "<h2>High correlations (|r| &gt; 0.9)</h2>" + (_table(["parameter", "parameter", "r"], rows, 2)
                                                          if rows else "<p>None.</p>")


def _components(rep: dict) -> str:
    rows = [[html.escape(k), _num(v["sigma0"]), _num(v["redundancy"], ".1f")]
            for k, v in rep["variance_components"].items()]
    return "<h2>Variance components</h2>" + _table(["group", "sigma0", "redundancy"], rows)


def _iterations(rep: dict) -> str:
    rows = [[str(i["iteration"]), f"{i['cost']:.6g}", f"{i['max_image_change_px']:.3g}"] for i in rep["iterations"]]
    return "<h2>Iterations (last pass)</h2>" + _table(["#", "weighted squared residuals", "largest change px"], rows)


def _settings(rep: dict) -> str:
    rows = [[html.escape(str(k)), html.escape(str(v))] for k, v in rep["settings"].items()]
    return "<h2>Settings</h2>" + _table(["setting", "value"], rows, 2)


def _figure(caption: str, png: bytes | None, note: str = "") -> str:
    if png is None:
        return ""
    data = base64.b64encode(png).decode("ascii")
    return f"<h2>{html.escape(caption)}</h2><img alt='{html.escape(caption)}' src='data:image/png;base64,{data}'>"


def _png(fig) -> bytes:
    import matplotlib.pyplot as plt
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    plt.close(fig)
    return buf.getvalue()


def _residual_plot(points: dict) -> bytes | None:
    import matplotlib.pyplot as plt
    ctl = np.asarray(points["role"]) == "control"
    ok = ctl & np.isfinite(np.asarray(points["res_col"], dtype=float))
    if not ok.any():
        return None
    idx = np.nonzero(ok)[0]
    if idx.size > MAX_ARROWS:
        idx = idx[np.linspace(0, idx.size - 1, MAX_ARROWS).astype(int)]
    col, row = np.asarray(points["col"])[idx], np.asarray(points["row"])[idx]
    dc, dr = np.asarray(points["res_col"])[idx], np.asarray(points["res_row"])[idx]
    flagged = np.asarray(points["flagged"])[idx]
    good = ~flagged
    extent = max(np.ptp(col), np.ptp(row), 1.0)
    scale = 0.03 * extent / max(float(np.percentile(np.hypot(dc[good], dr[good]), 95)) if good.any() else 1.0, 1e-9)
    fig, ax = plt.subplots(figsize=(10, 7))
    if good.any():
        ax.quiver(col[good], row[good], dc[good] * scale, dr[good] * scale, angles="xy", scale_units="xy", scale=1,
                  color="#1f5fa8", width=0.0015, label="control")
    if flagged.any():  # gross errors would swamp the plot as arrows at this exaggeration
        ax.plot(col[flagged], row[flagged], "x", color="#c00", ms=4, label=f"flagged ({int(flagged.sum())})")
    ax.set_xlabel("column (px)")
    ax.set_ylabel("row (px)")
    ax.invert_yaxis()
    ax.set_aspect("equal" if np.ptp(row) < 5 * np.ptp(col) else "auto")
    shown = f"{idx.size} of {int(ok.sum())} control observations" if idx.size < ok.sum() else \
        f"{idx.size} control observations"
    ax.set_title(f"residual vectors (predicted − measured), exaggerated {scale:.0f}×; {shown}")
    ax.legend(loc="upper right")
    return _png(fig)


def _trajectory_plot(tr: dict) -> bytes:
    import matplotlib.pyplot as plt
    t = np.asarray(tr["time"])
    fig, axes = plt.subplots(2, 1, figsize=(10, 7), sharex=True)
    pos, att = np.asarray(tr["position"]), np.degrees(np.asarray(tr["attitude"])) * 3600
    for a, name in enumerate("XYZ"):
        axes[0].plot(t, pos[:, a], label=name)
    for a, name in enumerate(("roll", "pitch", "yaw")):
        axes[1].plot(t, att[:, a], label=name)
    for ax, knots in ((axes[0], tr["position_knots"]), (axes[1], tr["attitude_knots"])):
        for k in knots:
            ax.axvline(k, color="#bbb", lw=0.6, zorder=0)
        ax.legend(loc="upper right")
    axes[0].set_ylabel("position correction (m, ECEF)")
    axes[1].set_ylabel("attitude correction (arcsec)")
    axes[1].set_xlabel("time (s from the scene epoch); grey lines: knots / orientation images")
    return _png(fig)


def _chip_plot(per_chip: dict) -> bytes | None:
    import matplotlib.pyplot as plt
    names = [k for k, v in per_chip.items() if v.get("count")]
    if not names:
        return None
    x = np.arange(len(names))
    fig, ax = plt.subplots(figsize=(max(5, 1.2 * len(names)), 4))
    ax.bar(x - 0.2, [per_chip[n]["rmse_col"] for n in names], 0.4, label="col (across track)")
    ax.bar(x + 0.2, [per_chip[n]["rmse_row"] for n in names], 0.4, label="row (along track)")
    ax.set_xticks(x, names)
    ax.set_ylabel("residual RMSE (px)")
    ax.legend()
    return _png(fig)
