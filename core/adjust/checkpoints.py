"""Check-point figures beyond the monoplotted ones: 3D intersection accuracy and the test that
tells blunders in the check data from a model error.

3D (seed 001 Tables 3-5, seed 003 Tables 3 and 5): a check point measured in two or more
cameras is intersected with a scene model (:func:`core.intersection.intersect`) and compared with
its known ground position in the local east/north/up frame at that position. Figures are per
point: RMSE east, north, plan (sqrt of the mean of east² + north²) and height, the largest plan
and height errors, CE90 (90th percentile of the plan error) and LE90 (90th percentile of the
absolute height error). Points seen in one camera only are counted, not intersected.

Blunders or model error: a check observation whose residual exceeds the critical value of its
own sigmas is a blunder candidate. Without blunders and model error, such exceedances happen
with probability about 2 alpha (two axes). Hand-measured check data may hold a few per cent of
blunders; many more is evidence that the model does not fit (over-parameterised against sparse
control, an unmodelled distortion), and leaving them out would hide exactly that. The test is
one-sided binomial: the count of exceeding observations against a share of
MODEL_ERROR_SHARE + 2 alpha, rejected at alpha.
"""
from __future__ import annotations

import logging

import numpy as np
from scipy import stats

from ..observations.gcps import GcpTable
from ..geodesy import enu_rotations, geodetic_to_ecef, up_vector
from ..model.intersection import intersect
from ..model.sensor import SceneModel
from .problem import image_group
from .robust import critical

log = logging.getLogger(__name__)

MODEL_ERROR_SHARE = 0.05  # share of check observations that blunders in the check data may explain


def blunder_test(exceeding: int, observations: int, alpha: float) -> dict:
    """Whether ``exceeding`` of ``observations`` check observations beyond the critical value are
    more than blunders explain (see the module docstring). Returns the counts, the shares
    (observed, expected without blunders, tolerated), the p-value and ``model_error``."""
    expected = 1.0 - (1.0 - alpha) ** 2  # either of the two image axes beyond its critical value
    tolerated = MODEL_ERROR_SHARE + expected
    p = float(stats.binom.sf(exceeding - 1, observations, tolerated)) if observations else 1.0
    return {"observations": int(observations), "exceeding": int(exceeding),
            "share": exceeding / observations if observations else 0.0, "expected_share": expected,
            "tolerated_share": tolerated, "p_value": p, "model_error": bool(p < alpha)}


def intersection_accuracy(scene: SceneModel, table: GcpTable, rows: np.ndarray,
                          flagged: np.ndarray | None = None) -> dict:
    """3D accuracy of ``scene`` at the check points of ``table`` rows ``rows`` (n,) index (cameras
    resolved to the scene's names): the points (rows sharing an id) seen in two or more different
    cameras are intersected and compared with their known positions (the first row's lon, lat,
    h) in east/north/up metres.

    flagged (n,) bool, per row: observations beyond their critical value; with it the figures
    are given again without the points that have any flagged observation.

    Returns counts of points (``points``, ``intersected``, ``single_camera``, ``failed``: two
    cameras but no finite intersection), ``median_condition`` (m per px of image error, the
    intersection geometry), ``converged``, the figures of :func:`figures_3d` over the
    intersected points, ``blunder_points`` and ``without_blunders`` (with ``flagged``), and
    ``errors`` (intersected, 3) east/north/up m for tests.
    """
    if rows.size == 0:
        return {"points": 0, "intersected": 0}
    sub = table.select(rows)
    ids, first, point = np.unique(sub.id, return_index=True, return_inverse=True)
    m = ids.size
    names = np.array([c.name for c in scene.cameras])
    order = np.argsort(names)
    camera = order[np.searchsorted(names[order], sub.camera)]
    pairs = np.unique(point * names.size + camera)
    cameras = np.bincount(pairs // names.size, minlength=m)
    seen = cameras >= 2
    use = seen[point]
    ground = np.full((m, 3), np.nan)
    condition = np.full(m, np.inf)
    converged = True
    if use.any():
        out = intersect(scene, camera[use], sub.col[use], sub.row[use], point[use], m)
        ground, condition, converged = out.ground, out.condition, out.converged
    ok = seen & np.all(np.isfinite(ground), axis=1)
    known = geodetic_to_ecef(sub.lon[first], sub.lat[first], sub.h[first])
    errors = np.einsum("mij,mj->mi", enu_rotations(sub.lon[first][ok], sub.lat[first][ok]), ground[ok] - known[ok])
    result = {"points": int(m), "intersected": int(ok.sum()), "single_camera": int((~seen).sum()),
              "failed": int((seen & ~ok).sum()),
              "median_condition": float(np.median(condition[ok])) if ok.any() else None,
              "converged": bool(converged), **figures_3d(errors), "errors": errors}
    if flagged is not None:
        bad = (np.bincount(point, weights=np.asarray(flagged, dtype=float), minlength=m) > 0)[ok]
        result["blunder_points"] = int(bad.sum())
        result["without_blunders"] = figures_3d(errors[~bad])
    return result


def figures_3d(errors: np.ndarray) -> dict:
    """RMSE east, north, plan and height, max plan and height, CE90 and LE90 (m) of point errors
    (m, 3) east/north/up m; None each when there are no points."""
    keys = ("rmse_east", "rmse_north", "rmse_plan", "rmse_height", "max_plan", "max_height", "ce90", "le90")
    if errors.shape[0] == 0:
        return dict.fromkeys(keys)
    plan = np.hypot(errors[:, 0], errors[:, 1])
    height = np.abs(errors[:, 2])
    rms = np.sqrt(np.mean(errors ** 2, axis=0))
    values = (rms[0], rms[1], np.sqrt(np.mean(plan ** 2)), rms[2], plan.max(), height.max(),
              np.percentile(plan, 90), np.percentile(height, 90))
    return {k: float(v) for k, v in zip(keys, values)}


# --- text for the log and the reports ------------------------------------------------------------
def model_error_message(after: dict) -> str:
    """The sentence that says a model error shows in the check points of :func:`accuracy`'s
    ``after`` figures (empty when there is none)."""
    if not after.get("model_error"):
        return ""
    t = after["blunder_test"]
    return (f"model error: {after['blunder_points']} of {after['points']} check points ({t['exceeding']} of "
            f"{t['observations']} observations, {100 * t['share']:.0f} %) have residuals beyond what their sigmas "
            f"allow, far more than blunders in the check data explain (at most {100 * t['tolerated_share']:.0f} %, "
            f"binomial test p = {t['p_value']:.1g}); the model does not fit the check points (too many free "
            "parameters for the control, or an unmodelled error). The figures over all check points are the "
            "accuracy; figures without them would hide the error")


def without_label(points: int) -> str:
    """The label of the figures without the points that have a blunder."""
    return f"after, without the {points} point{'s' * (points != 1)} with blunders"


def summary_lines(before: dict, after: dict) -> list[str]:
    """Log lines of the check figures: monoplotted per observation and 3D per point, before and
    after, and without the points with blunders unless that would hide a model error."""
    if not after.get("points"):
        return ["no check points: the accuracy of the result is not measured independently"]
    clean = after.get("blunders") and not after.get("model_error")
    rows = [("before", before, before["observations"] - before.get("not_imaged", 0)),
            ("after", after, after["observations"] - after.get("not_imaged", 0))]
    if clean:
        rows.append((without_label(after["blunder_points"]), after["without_blunders"],
                     rows[1][2] - after["blunders"]))
    lines = [f"monoplotted, per observation, {label}: RMSE {c['image']['rmse']:.3f} px, {c['ground']['rmse']:.2f} m "
             f"(CE90 {c['ground']['ce90']:.2f} m) over {n} observations" for label, c, n in rows if c.get("ground")]
    lines += [f"{c['not_imaged']} check observation(s) left out {label}: the model does not image their ground "
              f"(far outside its domain: a wrong coordinate?): {', '.join(c['not_imaged_ids'][:10])}"
              for label, c, _ in rows[:2] if c.get("not_imaged")]
    inter = after.get("intersection") or {}
    if inter.get("intersected"):
        rows = [("before", before["intersection"], inter["intersected"]), ("after", inter, inter["intersected"])]
        if clean and inter.get("blunder_points"):
            rows.append((without_label(inter["blunder_points"]),
                         inter["without_blunders"], inter["intersected"] - inter["blunder_points"]))
        lines += [f"3D intersection, {label}: RMSE east {f['rmse_east']:.2f} m, north {f['rmse_north']:.2f} m, "
                  f"plan {f['rmse_plan']:.2f} m, height {f['rmse_height']:.2f} m; CE90 {f['ce90']:.2f} m, "
                  f"LE90 {f['le90']:.2f} m; max plan {f['max_plan']:.2f} m, height {f['max_height']:.2f} m "
                  f"over {n} points" for label, f, n in rows]
    if inter.get("points"):
        lines.append(f"3D intersection: {inter['intersected']} of {inter['points']} check points intersected (seen "
                     f"in two or more cameras); {inter['single_camera']} seen in one camera only"
                     + (f", {inter['failed']} failed" if inter.get("failed") else "")
                     + (f"; median geometry {inter['median_condition']:.2f} m per px of image error"
                        if inter.get("median_condition") is not None else ""))
    return lines


# --- monoplotted check-point figures ------------------------------------------------------------------
def accuracy(scene: SceneModel, table: GcpTable, rows: np.ndarray, alpha: float,
             scale: dict[str, float] | None = None, ground_sigmas: bool = True) -> dict:
    """Check-point accuracy of a scene: ground -> image residuals (px) and image -> ground at
    the known height in a local east-north frame (m): RMSE per axis, max, CE90.

    The figures are per observation (a point seen in three cameras counts three times), each
    monoplotted on its own. ``points``: distinct check point ids; ``observations``: rows.

    Figures over all check observations, and again without the blunders: observations whose
    image residual exceeds the critical value (at ``alpha``) of what their own sigmas allow
    (image sigma, planimetric ground sigma over the GSD and the image shift of a height error of
    sigma_z, per axis), each times its group's variance component factor in ``scale`` (the
    check points are measured as the control points are: the factors estimated on those make
    the test independent of the stated sigmas' scale). Without ``ground_sigmas`` (an adjustment
    that held the control points' ground fixed: its image factor took the ground errors too)
    the image sigma alone. ``blunders`` counts those observations,
    ``blunder_points`` the points with any. A model error makes many exceed it:
    ``blunder_test`` (:func:`core.adjust.checkpoints.blunder_test`) decides, and with
    ``model_error`` the figures without them are not meaningful.
    """
    scale = scale or {}
    if rows.size == 0:
        return {"points": 0}
    res = np.full((rows.size, 2), np.nan)
    en = np.full((rows.size, 2), np.nan)
    allowed = np.full(rows.size, np.nan)
    sub = table.select(rows)
    ground = sub.ecef()
    crit = critical(alpha)
    for c, cam in enumerate(scene.cameras):
        m = sub.camera == cam.name
        if not m.any():
            continue
        col, row = scene.ground_to_image_near(ground[m], c, sub.col[m], sub.row[m])
        res[m] = np.stack([col - sub.col[m], row - sub.row[m]], axis=1)
        seen = scene.image_to_ground(sub.col[m], sub.row[m], sub.h[m], c)
        en[m] = np.einsum("nij,nj->ni", enu_rotations(sub.lon[m], sub.lat[m]), seen - ground[m])[:, :2]
        # a height error moves the image point by its relief displacement only
        sigma_z = sub.sigma_z[m] * scale.get("ground_z", 1.0) * ground_sigmas
        up = ground[m] + sigma_z[:, None] * up_vector(sub.lon[m], sub.lat[m])
        relief = np.hypot(*(a - b for a, b in zip(scene.ground_to_image_near(up, c, col, row), (col, row))))
        sigma_px = sub.sigma_px[m] * scale.get(image_group(cam.name), 1.0)
        sigma_xy = sub.sigma_xy[m] * scale.get("ground_xy", 1.0) * ground_sigmas
        allowed[m] = crit * np.sqrt(sigma_px ** 2 + (sigma_xy / _gsd(scene, c)) ** 2 + relief ** 2)
    # A check point the model does not image (an RPC far outside its ground domain: a wrong coordinate)
    # has no figure: it is counted and left out, never a NaN in the figures.
    imaged = np.isfinite(res).all(axis=1) & np.isfinite(en).all(axis=1)
    flagged = imaged & ~(np.abs(res) <= allowed[:, None]).all(axis=1)
    test = blunder_test(int(flagged.sum()), int(imaged.sum()), alpha)
    return {"points": int(np.unique(sub.id).size), "observations": int(rows.size),
            "not_imaged": int((~imaged).sum()), "not_imaged_ids": [str(i) for i in np.unique(sub.id[~imaged])[:1000]],
            **_figures(res[imaged], en[imaged]),
            "blunders": int(flagged.sum()), "blunder_points": int(np.unique(sub.id[flagged]).size),
            "blunder_test": test, "model_error": test["model_error"],
            "without_blunders": _figures(res[imaged & ~flagged], en[imaged & ~flagged]),
            "residuals": res, "en": en, "is_flagged": flagged}


def _figures(res: np.ndarray, en: np.ndarray) -> dict:
    """RMSE per axis, max and CE90 of image residuals (n,2) px and ground errors (n,2) m."""
    if res.shape[0] == 0:
        return {"image": None, "ground": None}
    horizontal = np.hypot(en[:, 0], en[:, 1])
    px = np.hypot(res[:, 0], res[:, 1])
    rms = lambda a: float(np.sqrt(np.mean(a * a)))  # noqa: E731
    return {"image": {"rmse_col": rms(res[:, 0]), "rmse_row": rms(res[:, 1]), "rmse": rms(px), "max": float(px.max())},
            "ground": {"rmse_east": rms(en[:, 0]), "rmse_north": rms(en[:, 1]), "rmse": rms(horizontal),
                       "max": float(horizontal.max()), "ce90": float(np.percentile(horizontal, 90))}}


def _gsd(scene: SceneModel, camera: int) -> float:
    """Ground sample distance (m): the distance between neighbouring pixels at the image centre."""
    cam = scene.cameras[camera]
    c, r = np.array([cam.cols / 2, cam.cols / 2 + 1]), np.array([cam.rows / 2, cam.rows / 2])
    g = scene.image_to_ground(c, r, float(np.mean(scene.height_range)), camera)
    return float(np.linalg.norm(g[1] - g[0]))


def check_point_report(figures: dict) -> dict:
    """The JSON part of :func:`accuracy`'s figures (with their ``intersection``): no per-row arrays."""
    out = {k: v for k, v in figures.items() if k not in ("residuals", "en", "is_flagged")}
    out["intersection"] = {k: v for k, v in figures["intersection"].items() if k != "errors"}
    return out


def log_check_points(before: dict, after: dict) -> None:
    """The check figures, and a model error where it is found."""
    if after.get("model_error"):
        log.warning("%s", model_error_message(after))
    for line in summary_lines(before, after):
        log.info("check points %s", line)

