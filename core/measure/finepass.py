"""The fine pass of image matching (:mod:`core.measure.matching`), one batch of grid points at a time.

1. **Correlation.** Each grid point's predicted chip (the reference in the raw image's geometry,
   ``window`` px) is correlated with the raw image within +-``fine_radius`` px of the offset the
   pyramid predicts (:mod:`core.measure.pyramid`): normalised cross-correlation by FFT, the peak
   refined by a paraboloid.
2. **Least-squares refinement** (:mod:`core.measure.lsm`, Gruen 1985): from the peak, the raw image
   fitted to the chip through an affine map of positions and a gain and offset of grey values; its
   centre is the match, its precision the match's sigma.
3. **Backward check.** The raw image's chip at the match is correlated back with the reference in
   the raw image's geometry within +-BACKWARD_RADIUS px of the grid point: a true match finds the
   grid point again (within BACKWARD_PX), a chance peak of the forward search (repeated texture,
   a cloud's edge, a changed field) most often does not.

Every failed test is a reason (indices into REASONS of core.measure.matching).
"""
from __future__ import annotations

import numpy as np

from ..products.rawimage import RawImage
from .correlation import Peaks, find_peaks, ncc, sample
from .lsm import refine

BACKWARD_RADIUS = 2       # px searched around the grid point by the backward check
BACKWARD_PX = 0.5         # px: the backward match this far from the forward one disagrees
PEAK_EXCLUSION = 2        # px around the peak not searched for a second one
INNER_RADIUS = 3          # px around the predicted offset searched first
LSM_MARGIN = 4            # px of raw image read around the search areas for the refinement's taps
SIGMA_FLOOR = 0.07        # px per axis: the error floor bench_matchgcps.py measures (RMSE 0.073 px per axis of the
                          # matches within 1 px of the truth: resampling, the reference's blur and noise), which the
                          # least-squares fit's own sigma (0.01-0.03 px) does not see

# indices into core.measure.matching.REASONS
OUTSIDE, OUTSIDE_REFERENCE, LOW_TEXTURE, LOW_CORRELATION, AMBIGUOUS, BORDER = 1, 3, 4, 5, 6, 7
FIT_FAILED, BACKWARD = 10, 11


def fine_batch(px, py, col, row, shift_c, shift_r, ref, raw: RawImage, nodata, settings, workers: int) -> dict:
    """Match one batch (module docstring): the reference's array positions (px, py) (b, s, s) of
    the raw pixels around each grid point (col, row) (b,), s = window + 2 BACKWARD_RADIUS, and the
    integer shifts (shift_c, shift_r) the pyramid predicts. Returns per grid point the match (col,
    row; GDAL px), correlation, peak ratio, sigma (px), the fit's gain and the reason index (-1:
    passed)."""
    w, r = settings.window, settings.fine_radius
    inner = slice(BACKWARD_RADIUS, BACKWARD_RADIUS + w)
    win, wx, wy = ref.window(px, py, 3)
    around = sample(win, wx, wy, px, py, ref.nodata)                  # (b, w + 2B, w + 2B)
    templates = around[:, inner, inner]
    s = w + 2 * r
    # raw search areas: upper-left pixel index of each, and the raw block holding them (with a margin)
    sc = (np.floor(col) + shift_c - (s - 1) / 2).astype(int)
    sr = (np.floor(row) + shift_r - (s - 1) / 2).astype(int)
    outside = (sc < 0) | (sr < 0) | (sc + s > raw.cols) | (sr + s > raw.rows)
    scc, src = np.clip(sc, 0, raw.cols - s), np.clip(sr, 0, raw.rows - s)
    bx0, by0 = max(int(scc.min()) - LSM_MARGIN, 0), max(int(src.min()) - LSM_MARGIN, 0)
    bx1, by1 = min(int(scc.max()) + s + LSM_MARGIN, raw.cols), min(int(src.max()) + s + LSM_MARGIN, raw.rows)
    block = raw.window(by0, by1, bx0, bx1)[0].astype(np.float32)
    if nodata is not None:
        block[block == nodata] = np.nan
    k = np.arange(s)
    search = block[(src - by0)[:, None, None] + k[None, :, None], (scc - bx0)[:, None, None] + k[None, None, :]]
    outside |= ~np.isfinite(search).all(axis=(1, 2))
    search = np.nan_to_num(search)
    no_ref = ~np.isfinite(templates).all(axis=(1, 2))
    templates = np.where(np.isfinite(templates), templates, 0.0)
    centre = search[:, r:r + w, r:r + w]
    texture = np.minimum(centre.std(axis=(1, 2)), templates.std(axis=(1, 2)))
    p = nearest_peaks(ncc(templates, search, workers), r)
    peak_fails = reasons(outside, no_ref, texture, p, np.zeros_like(outside), np.zeros_like(outside), settings)
    # the refinement from the peak (the chips whose peak passes its tests): array positions of the
    # template's centre in the raw block; the others keep the peak's position
    mc, mr = scc + p.dx + (w - 1) / 2 + 0.5, src + p.dy + (w - 1) / 2 + 0.5
    sigma, gain = np.full(col.size, SIGMA_FLOOR), np.full(col.size, np.nan)
    failed, backward = np.zeros_like(outside), np.zeros_like(outside)
    go = np.nonzero(peak_fails < 0)[0]
    if go.size:
        fit = refine(templates[go], block, bx0, by0, mc[go] - 0.5, mr[go] - 0.5)
        mc[go], mr[go], gain[go] = fit.x + 0.5, fit.y + 0.5, fit.gain
        failed[go] = ~fit.converged
        sigma[go] = np.sqrt(0.5 * (fit.sigma ** 2).sum(axis=1))
        backward[go] = backward_disagrees(around[go], block, bx0, by0, col[go], row[go], mc[go], mr[go], w)
    return {"col": mc, "row": mr, "value": p.value, "ratio": p.ratio,
            "sigma": np.maximum(np.where(np.isfinite(sigma), sigma, SIGMA_FLOOR), SIGMA_FLOOR),
            "gain": gain, "reasons": np.where(peak_fails < 0, reasons(outside, no_ref, texture, p, failed, backward,
                                                                      settings), peak_fails)}


def nearest_peaks(c: np.ndarray, r: int) -> Peaks:
    """The peaks of correlation surfaces c (b, 2r + 1, 2r + 1) (offsets -r..r around the predicted
    one): the peak within +-INNER_RADIUS px of the prediction where it lies inside that inner area
    (its second peak sought there too), else the whole surface's. The pyramid predicts the offset
    to a pixel or two (measured on the Giza pair: 95 % within 0.8 px), so a clear peak that close is
    the match, and a similar peak farther off (the next course of a pyramid's stones, a row of
    trees) is no ambiguity; the whole radius serves where the prediction is farther off."""
    p = find_peaks(c, PEAK_EXCLUSION, local=True)
    if r <= INNER_RADIUS:
        return p
    inner = find_peaks(c[:, r - INNER_RADIUS:r + INNER_RADIUS + 1, r - INNER_RADIUS:r + INNER_RADIUS + 1],
                       PEAK_EXCLUSION, local=True)
    use = ~inner.border
    return Peaks(np.where(use, inner.dx + r - INNER_RADIUS, p.dx), np.where(use, inner.dy + r - INNER_RADIUS, p.dy),
                 np.where(use, inner.value, p.value), np.where(use, inner.ratio, p.ratio),
                 np.where(use, inner.border, p.border))


def backward_disagrees(around, block, bx0: int, by0: int, col, row, mc, mr, w: int) -> np.ndarray:
    """(b,) whether the raw chip at the match (its pixel nearest the matched position (mc, mr))
    finds, among the reference chips within +-BACKWARD_RADIUS px of the grid point (``around``:
    the reference in the raw image's geometry, (b, w + 2B, w + 2B) centred on the grid point
    (col, row)), another place than the forward match says: farther than BACKWARD_PX. Chips that
    cannot be compared (NaN, leaving the block) are not judged here (other tests reject them)."""
    b = col.size
    qc, qr = np.floor(mc), np.floor(mr)          # the raw pixel holding the match: its centre is q + 0.5
    ok = np.isfinite(qc) & np.isfinite(qr)
    top = np.where(ok, qr, 0).astype(int) - by0 - (w - 1) // 2
    left = np.where(ok, qc, 0).astype(int) - bx0 - (w - 1) // 2
    ok &= (top >= 0) & (left >= 0) & (top + w <= block.shape[0]) & (left + w <= block.shape[1])
    top, left = np.where(ok, top, 0), np.where(ok, left, 0)
    k = np.arange(w)
    chips = block[top[:, None, None] + k[None, :, None], left[:, None, None] + k[None, None, :]]
    ok &= np.isfinite(chips).all(axis=(1, 2)) & np.isfinite(around).all(axis=(1, 2))
    out = np.zeros(b, bool)
    if not ok.any():
        return out
    p = find_peaks(ncc(chips[ok], around[ok]), PEAK_EXCLUSION, local=True)
    # the raw chip at q + 0.5 meets the reference chip centred BACKWARD_RADIUS - peak px before the grid
    # point; forward, the raw at the match meets the reference at the grid point, so (locally) the raw at
    # q + 0.5 meets it at the grid point plus (q + 0.5 - match)
    ec = p.dx - BACKWARD_RADIUS - (qc[ok] + 0.5 - mc[ok])
    er = p.dy - BACKWARD_RADIUS - (qr[ok] + 0.5 - mr[ok])
    out[ok] = (np.hypot(ec, er) > BACKWARD_PX) | p.border
    return out


def reasons(outside, no_ref, texture, p: Peaks, failed, backward, settings) -> np.ndarray:
    """Index into REASONS of each chip's first failed test; -1 for a match that passes."""
    tests = [(OUTSIDE, outside), (OUTSIDE_REFERENCE, no_ref), (LOW_TEXTURE, texture < settings.min_texture),
             (LOW_CORRELATION, p.value < settings.min_correlation), (AMBIGUOUS, p.ratio > settings.max_peak_ratio),
             (BORDER, p.border), (FIT_FAILED, failed), (BACKWARD, backward)]
    reason = np.full(outside.size, -1)
    for index, failed_test in reversed(tests):
        reason = np.where(failed_test, index, reason)
    return reason
