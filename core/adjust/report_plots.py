"""The plots of the adjustment report (:mod:`core.adjust.report_html`), as inline PNG figures:
image residual vectors over the image (seed 000 Fig. 6), trajectory corrections against time
(Fig. 7-11) and residual RMSE per CCD chip.

The plots are drawn on bare matplotlib ``Figure`` objects with the Agg canvas: no pyplot, so no
global backend switch inside QGIS and no figure registry to leak.
"""
from __future__ import annotations

import base64
import html
import io
import math

import numpy as np

from ..rotations import ARCSEC_PER_RAD

MAX_ARROWS = 5000  # residual vectors drawn at most; more are subsampled (stated in the caption)
PNG_DPI = 90


def _new_figure(width: float, height: float):
    """A matplotlib Figure (inches) on an Agg canvas, outside pyplot."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _png(fig) -> bytes:
    """The figure rendered as PNG bytes; its memory is released."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=PNG_DPI)
    fig.clear()
    return buf.getvalue()


def _figure_html(png: bytes, alt: str, caption: str) -> str:
    """An inline PNG (base64 data URI) with an escaped alt text and caption."""
    data = base64.b64encode(png).decode("ascii")
    return (f"<figure><img alt='{html.escape(alt)}' src='data:image/png;base64,{data}'>"
            f"<figcaption>{html.escape(caption)}</figcaption></figure>")


def _subsample(index: np.ndarray, limit: int) -> np.ndarray:
    """At most ``limit`` entries of ``index``, a reproducible uniform random choice, in order."""
    if index.size <= limit:
        return index
    return np.sort(np.random.default_rng(0).choice(index, limit, replace=False))


def _exaggeration(dc: np.ndarray, dr: np.ndarray, extent: float) -> float:
    """Factor that draws the 95th-percentile residual vector (px) as 2.5 % of the image extent (px)."""
    typical = float(np.percentile(np.hypot(dc, dr), 95)) if dc.size else 0.0
    return 0.025 * extent / max(typical, 1e-6)


def _nice_length(value: float) -> float:
    """1, 2 or 5 times a power of ten, not above ``value`` (> 0): a readable scale-arrow length."""
    power = 10.0 ** math.floor(math.log10(value))
    return max(m * power for m in (1, 2, 5) if m * power <= value)


def _vector_panel(ax, col: np.ndarray, row: np.ndarray, dc: np.ndarray, dr: np.ndarray, good: np.ndarray,
                  flagged: np.ndarray, colour: str, name: str, limits: tuple) -> float:
    """One panel of residual vectors: the ``good`` points (indices) as arrows exaggerated by the
    panel's own factor (returned), the ``flagged`` ones as red crosses; image axes (y down)."""
    extent = max(limits[1] - limits[0], limits[3] - limits[2], 1.0)
    scale = _exaggeration(dc[good], dr[good], extent)
    if good.size:
        arrows = ax.quiver(col[good], row[good], dc[good] * scale, dr[good] * scale, angles="xy",
                           scale_units="xy", scale=1, color=colour, width=0.0025, label=f"{name} ({good.size})")
        key = _nice_length(0.1 * extent / scale)
        ax.quiverkey(arrows, 0.84, 0.04, key * scale, f"{key:g} px", labelpos="W", coordinates="axes", color="k",
                     fontproperties={"size": "small"})
    if flagged.size:
        ax.plot(col[flagged], row[flagged], "x", color="#d00", ms=5, mew=1.2,
                label=f"flagged ({flagged.size}), not drawn as vectors")
    ax.set_xlim(limits[0] - 0.02 * extent, limits[1] + 0.02 * extent)
    ax.set_ylim(limits[3] + 0.02 * extent, limits[2] - 0.02 * extent)  # image y down
    ax.set_aspect("equal" if limits[3] - limits[2] < 4 * max(limits[1] - limits[0], 1.0) else "auto")
    ax.set_xlabel("column (px)")
    ax.set_title(f"{name}: exaggerated {scale:.3g}×", loc="left")
    if good.size or flagged.size:
        ax.legend(loc="lower left", fontsize="small", framealpha=0.9)
    return scale


def residual_vector_figure(points: dict) -> str:
    """Plot (a): image residual vectors (predicted - measured, px) at the measured positions, one
    panel for the control points and one for the check points, each exaggerated by its own
    factor (the 95th percentile of its unflagged vectors drawn as 2.5 % of the image): control
    residuals are what the adjustment left, often far smaller than the check points', and one
    factor for both would swamp the plot with check vectors. The control points' vectors are
    their residuals at the stated ground coordinates (``res_col_stated``, when given: the image
    residual plus what the ground unknowns took), so that both panels show how far the adjusted
    model misses the stated points. Flagged observations are red crosses (their vectors would
    swamp the others). Subsampled to MAX_ARROWS points."""
    col, row = np.asarray(points["col"], dtype=float), np.asarray(points["row"], dtype=float)
    role, flagged = np.asarray(points["role"]), np.asarray(points["flagged"], dtype=bool)
    check = role == "check"
    dc, dr = (np.where(check, np.asarray(points[k], dtype=float),
                       np.asarray(points.get(f"{k}_stated", points[k]), dtype=float)) for k in ("res_col", "res_row"))
    usable = np.isfinite(dc) & np.isfinite(dr) & np.isfinite(col) & np.isfinite(row)
    if not usable.any():
        return "<p>No image residuals to plot.</p>"
    shown = _subsample(np.nonzero(usable)[0], MAX_ARROWS)
    limits = (col[usable].min(), col[usable].max(), row[usable].min(), row[usable].max())
    panels = [(name, colour, shown[(check[shown] == is_check)])
              for name, colour, is_check in (("control points", "#1f5fa8", False), ("check points", "#e08a00", True))]
    panels = [p for p in panels if p[2].size]
    fig = _new_figure(7.5 * len(panels) + 1, 8)
    axes = fig.subplots(1, len(panels), sharey=True, squeeze=False)[0]
    scales = []
    for ax, (name, colour, idx) in zip(axes, panels):
        scales.append((name, _vector_panel(ax, col, row, dc, dr, idx[~flagged[idx]], idx[flagged[idx]], colour,
                                           name, limits)))
    axes[0].set_ylabel("row (px, down)")
    total = int(usable.sum())
    sampled = (f" {shown.size} of the {total} points are drawn (a uniform random subsample)."
               if shown.size < total else "")
    factors = "; ".join(f"{name} {scale:.3g} times" for name, scale in scales)
    stated = " at their stated ground coordinates (image residual plus what the ground unknowns took)" \
        if "res_col_stated" in points else ""
    caption = (f"Image residual vectors, predicted − measured, each panel exaggerated by its own factor ({factors}; "
               f"scale arrow at the lower right of each panel): control points{stated}, check points from the "
               f"adjusted model. Flagged observations as red crosses.{sampled}")
    return _figure_html(_png(fig), "image residual vectors", caption)


def trajectory_figure(trajectory: dict) -> str:
    """Plot (b): position corrections (m, ECEF X/Y/Z) and attitude corrections (arcsec, roll/pitch/
    yaw) against time (s), knot times (for polynomials the reference time t0) as grey lines."""
    t = np.asarray(trajectory["time"], dtype=float)
    # one set of curves, or one per camera (a trajectory correction per camera), told by line style
    sets = trajectory.get("per_camera") or {"": trajectory}
    fig = _new_figure(10, 7)
    axes = fig.subplots(2, 1, sharex=True)
    for ax, key, scale, names, knots in (
            (axes[0], "position", 1.0, ("X", "Y", "Z"), trajectory["position_knots"]),
            (axes[1], "attitude", ARCSEC_PER_RAD, ("roll", "pitch", "yaw"), trajectory["attitude_knots"])):
        for k, knot in enumerate(knots):
            ax.axvline(knot, color="#aaa", lw=0.8, ls="--", zorder=0, label="knots" if k == 0 else None)
        for c, (camera, curves) in enumerate(sets.items()):
            values = np.asarray(curves[key], dtype=float).reshape(-1, 3) * scale
            times = np.asarray(curves.get("time", t), dtype=float)  # a block scene's own time span
            for a, name in enumerate(names):
                ax.plot(times, values[:, a], lw=1.5, ls=("-", "--", ":", "-.")[c % 4], color=f"C{a}",
                        label=f"{camera} {name}".strip())
        ax.grid(alpha=0.3)
        ax.legend(loc="best", fontsize="small", ncol=4)
    axes[0].set_ylabel("position correction (m, ECEF)")
    axes[1].set_ylabel("attitude correction (arcsec)")
    axes[1].set_xlabel("time (s)")
    axes[0].set_title("trajectory corrections (adjusted − input)")
    caption = ("Corrections to the input trajectory against time: position in metres along the ECEF axes, "
               "attitude (roll, pitch, yaw) in arcseconds. Dashed grey lines: knot times of the trajectory "
               "model (for polynomials the reference time t0).")
    return _figure_html(_png(fig), "trajectory corrections", caption)


def chip_figure(per_chip: dict) -> str:
    """Plot (c): control residual RMSE (px) in col and row per CCD chip, with the observation counts."""
    names = [k for k, v in per_chip.items() if v.get("count")]
    if not names:
        return "<p>No control residuals per chip to plot.</p>"
    x = np.arange(len(names))
    fig = _new_figure(max(6.0, 1.1 * len(names) + 2), 4.5)
    ax = fig.add_subplot()
    ax.bar(x - 0.2, [per_chip[n]["rmse_col"] for n in names], 0.4, label="col (across track)", color="#1f5fa8")
    ax.bar(x + 0.2, [per_chip[n]["rmse_row"] for n in names], 0.4, label="row (along track)", color="#e08a00")
    ax.set_xticks(x, [f"{n}\n{per_chip[n]['count']} obs" for n in names], fontsize="small")
    ax.set_xlabel("camera / CCD chip")
    ax.set_ylabel("control residual RMSE (px)")
    ax.grid(axis="y", alpha=0.3)
    ax.legend(fontsize="small")
    caption = ("Control point residual RMSE per CCD chip, column and row, in pixels (flagged observations left "
               "out in robust runs). A chip clearly above the others points to an unmodelled chip offset or "
               "rotation.")
    return _figure_html(_png(fig), "residual RMSE per CCD chip", caption)
