"""Fit RPC00B rational polynomial models to a scene model and check them; the refined RPC of an
adjusted RPC scene. Writing them: :mod:`core.formats.rpcfiles`.

Conventions (as everywhere in the core):
- Image coordinates are GDAL (col, row): (0, 0) is the upper-left corner of the upper-left
  pixel, whose centre is (0.5, 0.5).
- RPC00B model coordinates (sample, line), as GDAL reads them from a GeoTIFF's RPC tag, an
  ``<image>_RPC.TXT`` or an ``<image>.RPB``, are 0 at the CENTRE of the first pixel:
  sample = col - 0.5, line = row - 0.5 (:class:`core.model.rpc.RpcModel` with ``origin`` = 0). This is
  what GDAL's RPC transformer applies (checked in tests/unit/products/test_rpcfit.py by running
  ``gdal.Transformer(..., ['METHOD=RPC', 'RPC_HEIGHT=h'])`` on a fitted model).
- Ground: longitude, latitude (degrees, WGS84) and ellipsoidal height (m).

The fit (Tao & Hu 2001, "A comprehensive study of the rational function model for
photogrammetric processing", PE&RS 67(12)) solves each ratio r = P(x)/Q(x) (Q's constant term 1)
through the linear form r*Q - P = 0, iteratively reweighted by 1/Q^2 of the previous solution,
with a small Tikhonov (ridge) term on the column-normalised normal equations that keeps the
denominator tame when the height range is thin. Everything is vectorised: one 39x39 solve
per iteration and coordinate.
"""
from __future__ import annotations

import logging
import math
from dataclasses import replace

import numpy as np

from ..dem import no_height_words, surface_name
from ..errors import InputError
from ..geodesy import ecef_to_geodetic
from ..model.rpc import RpcModel, rpc_terms
from ..model.rpcscene import RpcScene
from .footprint import rays_without_height

log = logging.getLogger(__name__)

DEFAULT_GRID = (31, 31, 7)
DEFAULT_REGULARISATION = 1e-12
MAX_REGULARISATION = 1e-4  # beyond it the ridge itself bends the fit by a good fraction of a pixel
DEFAULT_CHECK_GRID = (40, 40)


# --- fit ----------------------------------------------------------------------------------
def fit_rpc(scene, camera=0, height_range=None, grid=DEFAULT_GRID, regularisation: float = DEFAULT_REGULARISATION,
            check_grid=DEFAULT_CHECK_GRID, max_iter: int = 20, progress=None) -> tuple[RpcModel, dict]:
    """RPC00B model of one camera of ``scene`` (core.model.sensor.SceneModel), fitted to its rigorous
    image -> ground over the whole image and ``height_range`` (lo, hi) ellipsoidal metres
    (default: the scene's own height range), and the report of an independent check.

    grid: (nx, ny, nz) fit nodes across, along and in height (image corners and the height-range
    ends included). regularisation: Tikhonov weight relative to the mean diagonal of the
    column-normalised normal equations; raised 100-fold at a time (up to 1e-4) while the
    denominator vanishes at a fit node or the check's largest error exceeds twice the fit's (a
    pole between the nodes); the model with the smallest check maximum is kept.
    check_grid: (nx, ny) check nodes, placed between the fit nodes, at heights between the fit
    levels and at both ends of the height range.

    Report (JSON-ready dict): camera, height_range, grid, iterations, fit residuals, and
    ``check``: rms/max (px, overall and per axis), per CCD chip (``chips``), at the height-range
    ends (``heights``), plus a ``note`` when the camera has several chips. A staggered array
    (chips imaging a row at different instants, each with its own alignment) makes steps at the
    chip seams that one smooth RPC cannot follow: the per-chip figures show where the error is.
    """
    report_progress = progress or (lambda fraction, message=None: None)
    k = scene.camera_index(camera)
    cam = scene.cameras[k]
    lo, hi = _height_range(scene if height_range is None else None, height_range)
    nx, ny, nz = (int(v) for v in grid)
    if nx < 4 or ny < 4 or nz < 4:
        raise InputError(f"RPC fit grid {tuple(grid)} is too coarse: a cubic RPC needs at least 4 nodes across, "
                         f"along and in height (e.g. {DEFAULT_GRID})")
    if not (np.isfinite(regularisation) and regularisation >= 0):
        raise InputError(f"regularisation must be a finite number >= 0 (got {regularisation})")

    # fit nodes: the image edges included, heights from lo to hi
    report_progress(0.0, f"camera {cam.name}: rigorous image -> ground on a {nx}x{ny}x{nz} grid")
    cols = np.linspace(0.0, cam.cols, nx)
    rows = np.linspace(0.0, cam.rows, ny)
    heights = np.linspace(lo, hi, nz)
    col, row, h = (a.ravel() for a in np.meshgrid(cols, rows, heights, indexing="ij"))
    lon, lat, hh = _ground(scene, k, col, row, h)
    ok = np.isfinite(lon) & np.isfinite(lat)
    if ok.sum() < 0.9 * ok.size:
        raise InputError(f"camera {cam.name!r}: {int((~ok).sum())} of {ok.size} lines of sight do not meet the "
                         f"heights {lo:.0f}..{hi:.0f} m (rays that miss the Earth); no RPC can be fitted")
    col, row, lon, lat, hh = col[ok], row[ok], lon[ok], lat[ok], hh[ok]
    lon = _unwrap_longitudes(lon)

    norm = _normalisation(cam, lon, lat, (lo, hi))
    x = (lon - norm["lon_off"]) / norm["lon_scale"]
    y = (lat - norm["lat_off"]) / norm["lat_scale"]
    z = (hh - norm["height_off"]) / norm["height_scale"]
    t = rpc_terms(x, y, z)
    line = (row - 0.5 - norm["line_off"]) / norm["line_scale"]
    samp = (col - 0.5 - norm["samp_off"]) / norm["samp_scale"]
    report_progress(0.4, "solving the rational functions")
    # A pole of the denominator, at a fit node or between the nodes (where only the independent
    # check sees it), means data the cubic ratio cannot follow there: raise the regularisation
    # until the check agrees with the fit, keeping the best checked model.
    best = None
    reg = float(regularisation)
    while True:
        try:
            rpc, report = _fit_and_check(scene, k, cam, t, line, samp, norm, (col, row, lon, lat, hh), (lo, hi),
                                         (nx, ny, nz), reg, check_grid, max_iter)
        except _VanishingDenominator:
            report = None
        if report is not None:
            if best is None or report["check"]["max_px"] < best[1]["check"]["max_px"]:
                best = rpc, report
            if report["check"]["max_px"] <= 2.0 * report["fit"]["max_px"] + 0.05:
                break
        if reg >= MAX_REGULARISATION:
            break
        reg = max(reg * 100.0, 1e-14)
    if best is None:
        raise InputError(f"RPC fit: the denominator vanishes inside the fit grid even with regularisation {reg:g}; "
                         "the scene geometry cannot be represented by an RPC")
    rpc, report = best
    report["regularisation"] = float(regularisation)
    report_progress(1.0, None)
    return rpc, report


def _fit_and_check(scene, k, cam, t, line, samp, norm, fit_points, height_range, grid, regularisation, check_grid,
                   max_iter) -> tuple[RpcModel, dict]:
    """One fit of both ratios at one regularisation, its residuals at the fit nodes and its
    independent check (the report of :func:`fit_rpc`). _VanishingDenominator when the
    denominator vanishes at a fit node."""
    col, row, lon, lat, hh = fit_points
    line_num, line_den, it_l = _solve_ratio(t, line, regularisation, max_iter)
    samp_num, samp_den, it_s = _solve_ratio(t, samp, regularisation, max_iter)
    rpc = RpcModel(line_num=line_num, line_den=line_den, samp_num=samp_num, samp_den=samp_den, origin=0.0, **norm)
    fc, fr = rpc.ground_to_image(lon, lat, hh)
    fit_err = np.hypot(fc - col, fr - row)
    report = {
        "camera": cam.name, "camera_index": k, "cols": cam.cols, "rows": cam.rows,
        "height_range": [float(v) for v in height_range], "grid": list(grid),
        "iterations": {"line": it_l, "samp": it_s}, "regularisation_used": float(regularisation),
        "fit": {"points": int(col.size), "rms_px": _rms(fit_err), "max_px": float(np.max(fit_err))},
        "convention": "GDAL RPC00B: sample = col - 0.5, line = row - 0.5 (0 = centre of the first pixel)",
    }
    report["check"] = check_rpc(scene, rpc, k, height_range, check_grid, fit_grid=grid)
    return rpc, report


def check_rpc(scene, rpc: RpcModel, camera=0, height_range=None, check_grid=DEFAULT_CHECK_GRID,
              fit_grid=DEFAULT_GRID) -> dict:
    """Differences (px) between an RPC and the rigorous model of one camera on a grid independent
    of the fit: image nodes between the fit grid's (and on both sides of each chip seam),
    seen by the rigorous model at heights between the fit levels and at the range ends, then
    projected by the RPC. Returns overall, per-chip and per-height-end RMS/max figures."""
    k = scene.camera_index(camera)
    cam = scene.cameras[k]
    lo, hi = _height_range(scene if height_range is None else None, height_range)
    nx, ny = (max(int(v), 2) for v in check_grid)
    nz = max(int(fit_grid[2]), 2)
    # columns: offset from the fit nodes (a fraction of a step that no fit grid hits), plus both
    # sides of every chip seam, where staggered arrays step
    cols = (np.arange(nx) + 0.37) * cam.cols / nx
    seams = np.array([cam.chip_range(j)[0] for j in range(1, len(cam.chips))], dtype=float)
    cols = np.unique(np.concatenate([cols, seams - 0.5, seams + 0.5]))
    rows = (np.arange(ny) + 0.61) * cam.rows / ny
    levels = np.linspace(lo, hi, nz)
    heights = np.unique(np.concatenate([[lo, hi], 0.5 * (levels[1:] + levels[:-1])]))
    col, row, h = (a.ravel() for a in np.meshgrid(cols, rows, heights, indexing="ij"))
    lon, lat, hh = _ground(scene, k, col, row, h)
    ok = np.isfinite(lon) & np.isfinite(lat)
    col, row, h, lon, lat, hh = col[ok], row[ok], h[ok], lon[ok], lat[ok], hh[ok]
    lon = _unwrap_longitudes(lon, rpc.lon_off)
    pc, pr = rpc.ground_to_image(lon, lat, hh)
    dc, dr = pc - col, pr - row
    err = np.hypot(dc, dr)
    chip = cam.chip_index(col)
    out = _figures(err, dc, dr)
    out.update({"points": int(err.size), "heights_checked": [float(v) for v in heights]})
    out["chips"] = []
    for j in range(len(cam.chips)):
        m = chip == j
        c0, c1 = cam.chip_range(j)
        entry = {"chip": j, "name": cam.chips[j].name or f"CCD{j + 1}", "cols": [float(c0), float(c1)]}
        entry.update(_figures(err[m], dc[m], dr[m]) if m.any() else {"rms_px": None, "max_px": None})
        out["chips"].append(entry)
    out["heights"] = {}
    for name, value in (("low", lo), ("high", hi)):
        m = h == value
        out["heights"][name] = {"height_m": float(value), **_figures(err[m], dc[m], dr[m])}
    if len(cam.chips) > 1:
        near = np.zeros(col.shape, dtype=bool)
        for s in seams:
            near |= np.abs(col - s) <= 0.5 + 1e-9
        out["seams"] = _figures(err[near], dc[near], dr[near])
        # the rigorous model's step across each seam (1 px apart, same rows and heights): the
        # RPC moves smoothly by ~1 px there, so the jump of the residual is the step it cannot follow
        out["seam_steps"] = []
        for j, s in enumerate(seams):
            left, right = col == s - 0.5, col == s + 0.5
            if left.sum() == right.sum() and left.any():
                step = np.hypot(dc[right] - dc[left], dr[right] - dr[left])
                out["seam_steps"].append({"between_chips": [j, j + 1], "col": float(s),
                                          "mean_px": float(np.mean(step)), "max_px": float(np.max(step))})
        out["interior"] = _figures(err[~near], dc[~near], dr[~near])
        out["note"] = (f"camera {cam.name!r} has {len(cam.chips)} CCD chips; one RPC is a smooth function over the "
                       f"whole image and cannot model the steps that separately aligned (staggered) chips make at "
                       f"their seams: see the per-chip and seam figures")
    return out


def _figures(err, dc, dr) -> dict:
    return {"rms_px": _rms(err), "max_px": float(np.max(err)), "rms_col_px": _rms(dc), "rms_row_px": _rms(dr),
            "mean_col_px": float(np.mean(dc)), "mean_row_px": float(np.mean(dr))}


def _rms(v) -> float:
    return float(np.sqrt(np.mean(np.square(v))))


def _height_range(scene, height_range) -> tuple[float, float]:
    lo, hi = (scene.height_range if height_range is None else height_range)
    lo, hi = float(lo), float(hi)
    if not (np.isfinite(lo) and np.isfinite(hi)) or hi < lo:
        raise InputError(f"height range must be two finite heights lo <= hi (got {lo}, {hi})")
    if hi - lo < 1.0:  # a flat range still needs a height scale: widen symmetrically
        lo, hi = lo - 50.0, hi + 50.0
    return lo, hi


def _ground(scene, k, col, row, h):
    """(lon, lat, h) of image points at heights h through the rigorous model (NaN where missed)."""
    xyz = scene.image_to_ground(col, row, h, camera=k)
    good = np.all(np.isfinite(xyz), axis=1)
    lon = np.full(col.shape, np.nan)
    lat = np.full(col.shape, np.nan)
    hh = np.full(col.shape, np.nan)
    if good.any():
        lon[good], lat[good], hh[good] = ecef_to_geodetic(xyz[good])
    return lon, lat, hh


def _unwrap_longitudes(lon, centre=None):
    """Longitudes made continuous around ``centre`` (default: the first finite one) across +-180."""
    lon = np.asarray(lon, dtype=float)
    ref = lon[np.isfinite(lon)][0] if centre is None else centre
    return ref + (lon - ref + 180.0) % 360.0 - 180.0


def _normalisation(cam, lon, lat, hrange) -> dict:
    """RPC00B offsets and scales, rounded as the RPC00B fields hold them (NITF widths):
    line/sample and height to whole units, latitude/longitude to 1e-4 degrees; the scales are
    rounded up so that the data stay within [-1, 1]."""
    def off_scale(lo_v, hi_v, step):
        off = round(0.5 * (lo_v + hi_v) / step) * step
        scale = math.ceil(max(hi_v - off, off - lo_v, step) / step) * step
        return float(off), float(scale)

    line_off, line_scale = off_scale(-0.5, cam.rows - 0.5, 1.0)
    samp_off, samp_scale = off_scale(-0.5, cam.cols - 0.5, 1.0)
    lat_off, lat_scale = off_scale(float(np.min(lat)), float(np.max(lat)), 1e-4)
    lon_off, lon_scale = off_scale(float(np.min(lon)), float(np.max(lon)), 1e-4)
    lon_off = (lon_off + 180.0) % 360.0 - 180.0 if abs(lon_off) > 180.0 else lon_off
    h_off, h_scale = off_scale(hrange[0], hrange[1], 1.0)
    return dict(line_off=line_off, line_scale=line_scale, samp_off=samp_off, samp_scale=samp_scale,
                lat_off=lat_off, lat_scale=lat_scale, lon_off=lon_off, lon_scale=lon_scale,
                height_off=h_off, height_scale=h_scale)


class _VanishingDenominator(Exception):
    pass


def _solve_ratio(t: np.ndarray, r: np.ndarray, regularisation: float, max_iter: int):
    """(num (20,), den (20,), iterations) of r ~ (t @ num) / (t @ den), den[0] = 1.

    Linearised r*Q - P = 0 with unknowns (num, den[1:]), reweighted by 1/Q^2 of the previous
    iterate (Tao & Hu 2001, eq. 13-16), ridge ``regularisation`` relative to the mean diagonal of
    the column-normalised normal matrix."""
    m = np.hstack([t, -r[:, None] * t[:, 1:]])
    w = np.ones(r.size)
    best, best_rms, it = None, np.inf, 0
    for it in range(1, max_iter + 1):
        mw = m * w[:, None]
        n = mw.T @ mw
        b = mw.T @ (r * w)
        d = np.sqrt(np.diag(n))
        d[d == 0] = 1.0
        ns = n / np.outer(d, d)
        ns[np.diag_indices_from(ns)] += regularisation
        x = np.linalg.solve(ns, b / d) / d
        q = t @ np.concatenate([[1.0], x[20:]])
        if np.any(np.abs(q) < 1e-3):
            if best is not None:
                break
            raise _VanishingDenominator()
        rms = float(np.sqrt(np.mean(np.square((t @ x[:20]) / q - r))))
        if rms < best_rms:
            improved = rms < (1.0 - 1e-3) * best_rms
            best, best_rms = x, rms
            if not improved:
                break
        else:  # the reweighting no longer helps: keep the best iterate
            break
        w = 1.0 / q
    return best[:20], np.concatenate([[1.0], best[20:]]), it


# --- heights from a DEM --------------------------------------------------------------------
def dem_height_range(scene, dem, camera=0, margin: float = 0.1, min_margin: float = 50.0,
                     samples: int = 33) -> tuple[float, float]:
    """(lo, hi) ellipsoidal heights (m) of a DEM (core.dem.Dem or ConstantHeight) over one
    camera's image: the heights where a samples x samples grid of image rays meets it, widened by
    ``margin`` of the span (at least ``min_margin`` m) for relief between the samples; rays that
    meet the DEM only on its nodata holes are left out (a warning counts them). Raises InputError
    naming the camera and the DEM when rays leave the DEM."""
    k = scene.camera_index(camera)
    cam = scene.cameras[k]
    cols = np.linspace(0.0, cam.cols, samples)
    rows = np.linspace(0.0, cam.rows, samples)
    col, row = (a.ravel() for a in np.meshgrid(cols, rows, indexing="ij"))
    xyz = scene.image_to_ground_dem(col, row, dem, camera=k)
    missing = ~np.all(np.isfinite(xyz), axis=1)
    if missing.any():
        _, hole = rays_without_height(scene, k, col[missing], row[missing], dem)
        words = no_height_words(int(missing.sum() - hole.sum()), int(hole.sum()), missing.size,
                                f"points of a {samples} x {samples} grid over its image")
        if not hole.all() or missing.all():
            raise InputError(f"{surface_name(dem)} does not cover camera {cam.name!r} of the scene: it {words}; use "
                             "a DEM covering the whole footprint, or a constant height")
        log.warning("%s, camera %r: it %s; the height range is taken from the others", surface_name(dem), cam.name,
                    words)
        xyz = xyz[~missing]
    _, _, h = ecef_to_geodetic(xyz)
    lo, hi = float(np.min(h)), float(np.max(h))
    pad = max(margin * (hi - lo), min_margin)
    return lo - pad, hi + pad


# --- the refined RPC --------------------------------------------------------------------------
def refined_rpc(scene: RpcScene) -> tuple[RpcModel, str]:
    """An RPC00B model of the corrected scene, GDAL and QGIS use directly, and how it was made:
    'folded' when each image coordinate's correction depends on that coordinate alone (a1 = 0 on
    rows, a2 = b1 = 0: col' = (1 + a1) col + a0 is an exact change of the sample numerator, as a
    multiple of the numerator plus one of the denominator; likewise rows), else 'refitted' (a
    correction mixing rows and columns, e.g. a drift of the columns along the rows, is not a ratio
    with the same denominator: the RPC is fitted anew to the corrected scene over the whole image
    and the RPC's height range, :func:`fit_rpc`, to about 1e-5 px)."""
    (a0, a1, a2), (b0, b1, b2) = scene.correction
    r = scene.rpc
    if a2 == 0.0 and b1 == 0.0:
        def fold(num, den, off, scale, gain, shift):
            # model' = gain * (model - origin + 0.5) + shift + origin - 0.5 with model = num/den * scale + off
            constant = (gain - 1.0) * off + shift - (gain - 1.0) * (r.origin - 0.5)
            return gain * num + constant / scale * den
        return replace(r, samp_num=fold(r.samp_num, r.samp_den, r.samp_off, r.samp_scale, 1.0 + a1, a0),
                       line_num=fold(r.line_num, r.line_den, r.line_off, r.line_scale, 1.0 + b2, b0)), "folded"
    rpc, _ = fit_rpc(scene, 0, scene.height_range)
    return rpc, "refitted"


def refined_rpcs(scenes: dict) -> dict[str, tuple[RpcModel, str]]:
    """Per RPC scene of ``scenes`` (name -> adjusted scene, e.g. a block adjustment's
    :attr:`core.adjust.block.BlockResult.scenes`) its refined RPC and how it was made
    (:func:`refined_rpc`), as a single RPC scene's adjustment writes it; other scenes left out."""
    return {name: refined_rpc(scene) for name, scene in scenes.items() if isinstance(scene, RpcScene)}
