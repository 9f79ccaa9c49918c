"""The chip maths of image matching: cubic convolution samples of an image at any positions,
normalised cross-correlation of batches of chips by FFT, sub-pixel correlation peaks, and block
means for coarse chips.

Array positions (x = column, y = row) have pixel centres at integers.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.fft


def _keys(t: np.ndarray) -> list[np.ndarray]:
    """Keys cubic convolution weights (a = -0.5) of the taps -1, 0, 1, 2 at fractions t."""
    t2, t3 = t * t, t * t * t
    return [(-t3 + 2 * t2 - t) / 2, (3 * t3 - 5 * t2 + 2) / 2, (-3 * t3 + 4 * t2 + t) / 2, (t3 - t2) / 2]


def sample(image: np.ndarray, x0: int, y0: int, x: np.ndarray, y: np.ndarray, nodata=None) -> np.ndarray:
    """Cubic convolution samples (Keys) of ``image`` (origin (x0, y0)) at array positions (x, y);
    NaN where a position lies outside the image or one of its 4 x 4 taps is ``nodata`` or NaN.
    A local kernel, so no prefilter of the image: the cost is per sample, not per image."""
    h, w = image.shape
    if h < 4 or w < 4:
        return np.full(np.shape(x), np.nan)
    u, v = np.asarray(x, np.float64) - x0, np.asarray(y, np.float64) - y0
    iu, iv = np.floor(u), np.floor(v)
    inside = (iu >= 1) & (iv >= 1) & (iu <= w - 3) & (iv <= h - 3)
    iu, iv = np.where(inside, iu, 1).astype(np.intp), np.where(inside, iv, 1).astype(np.intp)
    wu, wv = _keys((u - iu).astype(np.float32)), _keys((v - iv).astype(np.float32))
    flat = image.ravel()
    base = iv * w + iu
    out = np.zeros(u.shape, np.float32)
    for a in range(4):
        row = np.zeros(u.shape, np.float32)
        for b in range(4):
            tap = flat[base + (a - 1) * w + (b - 1)]
            if nodata is not None:
                inside &= tap != nodata
            row += wu[b] * tap
        out += wv[a] * row
    return np.where(inside & np.isfinite(out), out, np.nan)


# --- correlation ---------------------------------------------------------------------------------
def _window_sums(a: np.ndarray, w: int) -> np.ndarray:
    """Sums of a (b, s, s) over every w x w window: (b, s-w+1, s-w+1), by integral images."""
    c = np.zeros((a.shape[0], a.shape[1] + 1, a.shape[2] + 1))
    c[:, 1:, 1:] = a.cumsum(1).cumsum(2)
    return c[:, w:, w:] - c[:, :-w, w:] - c[:, w:, :-w] + c[:, :-w, :-w]


def ncc(templates: np.ndarray, search: np.ndarray, workers: int = 1) -> np.ndarray:
    """Normalised cross-correlation (b, n, n), n = s - w + 1, of templates (b, w, w) at every
    offset inside search images (b, s, s): entry [i, j] compares the template with the search
    window whose upper-left pixel is (row i, col j). Flat windows give 0."""
    b, w, _ = templates.shape
    s = search.shape[1]
    t = templates - templates.mean(axis=(1, 2), keepdims=True)
    t /= np.maximum(np.sqrt((t * t).sum(axis=(1, 2), keepdims=True)), 1e-12)
    size = scipy.fft.next_fast_len(s, real=True)
    ft = scipy.fft.rfft2(t, s=(size, size), workers=workers)
    fs = scipy.fft.rfft2(search, s=(size, size), workers=workers)
    corr = scipy.fft.irfft2(fs * np.conj(ft), s=(size, size), workers=workers)[:, :s - w + 1, :s - w + 1]
    total = _window_sums(search, w)
    energy = _window_sums(search * search, w) - total * total / (w * w)
    return np.where(energy > 1e-9, corr / np.sqrt(np.maximum(energy, 1e-9)), 0.0)


# least-squares paraboloid z = a + b x + c y + d x^2 + e xy + f y^2 on the 3 x 3 neighbourhood
_GX, _GY = np.meshgrid([-1.0, 0.0, 1.0], [-1.0, 0.0, 1.0])
_PARABOLOID = np.linalg.pinv(np.stack([np.ones(9), _GX.ravel(), _GY.ravel(), _GX.ravel() ** 2,
                                       (_GX * _GY).ravel(), _GY.ravel() ** 2], axis=1))


@dataclass
class Peaks:
    """Per chip: sub-pixel peak position (dx, dy) in offset units, its correlation, the second
    peak's ratio to it and whether the integer peak lies on the border of the surface."""
    dx: np.ndarray
    dy: np.ndarray
    value: np.ndarray
    ratio: np.ndarray
    border: np.ndarray


def find_peaks(c: np.ndarray, exclusion: int) -> Peaks:
    """Peaks of correlation surfaces c (b, n, n): integer maximum refined by a paraboloid; the
    second peak is the largest value farther than ``exclusion`` from the first."""
    b, n, _ = c.shape
    flat = c.reshape(b, -1)
    k = np.argmax(flat, axis=1)
    i, j = np.divmod(k, n)
    value = flat[np.arange(b), k]
    border = (i == 0) | (j == 0) | (i == n - 1) | (j == n - 1)
    ii, jj = np.clip(i, 1, n - 2), np.clip(j, 1, n - 2)
    rows = ii[:, None, None] + np.arange(-1, 2)[None, :, None]
    cols = jj[:, None, None] + np.arange(-1, 2)[None, None, :]
    z = c[np.arange(b)[:, None, None], rows, cols].reshape(b, 9)
    _, gb, gc, gd, ge, gf = (_PARABOLOID @ z.T)
    det = 4 * gd * gf - ge * ge
    ok = (det > 1e-12) & (gd < 0) & (gf < 0)
    sx = np.where(ok, (-2 * gf * gb + ge * gc) / np.where(ok, det, 1.0), 0.0)
    sy = np.where(ok, (-2 * gd * gc + ge * gb) / np.where(ok, det, 1.0), 0.0)
    sx, sy = np.clip(sx, -1.0, 1.0), np.clip(sy, -1.0, 1.0)
    yy, xx = np.mgrid[0:n, 0:n]
    far = (np.abs(yy[None] - i[:, None, None]) > exclusion) | (np.abs(xx[None] - j[:, None, None]) > exclusion)
    second = np.where(far, c, -np.inf).reshape(b, -1).max(axis=1)
    ratio = np.where(value > 0, np.maximum(second, 0.0) / np.maximum(value, 1e-12), 1.0)
    return Peaks(jj + sx, ii + sy, value, ratio, border | ~ok)


def block_mean(a: np.ndarray, f: int) -> np.ndarray:
    """Means of the f x f blocks of a (h, w), both multiples of f."""
    return a.reshape(a.shape[0] // f, f, a.shape[1] // f, f).mean(axis=(1, 3))
