"""The chip maths of image matching: cubic convolution samples of an image at any positions,
normalised cross-correlation of batches of chips by FFT, masked normalised cross-correlation of two
whole images with holes (Padfield 2012), sub-pixel correlation peaks, and block means for coarse
chips.

Array positions (x = column, y = row) have pixel centres at integers.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.fft
from scipy.ndimage import maximum_filter


def _keys(t: np.ndarray) -> list[np.ndarray]:
    """Keys cubic convolution weights (a = -0.5) of the taps -1, 0, 1, 2 at fractions t."""
    t2, t3 = t * t, t * t * t
    return [(-t3 + 2 * t2 - t) / 2, (3 * t3 - 5 * t2 + 2) / 2, (-3 * t3 + 4 * t2 + t) / 2, (t3 - t2) / 2]


_TAPS = np.arange(-1, 3)[:, None]   # a cubic sample's tap offsets -1..2, as a column


def sample(image: np.ndarray, x0: int, y0: int, x: np.ndarray, y: np.ndarray, nodata=None) -> np.ndarray:
    """Cubic convolution samples (Keys), float32, of ``image`` (origin (x0, y0)) at array positions
    (x, y); NaN where a position lies outside the image or one of its 4 x 4 taps is ``nodata`` or
    NaN. A local kernel, so no prefilter of the image: the cost is per sample, not per image (the
    16 taps of every sample gathered at once, weighted by two small matrix products)."""
    h, w = image.shape
    if h < 4 or w < 4:
        return np.full(np.shape(x), np.nan, np.float32)
    u, v = np.asarray(x, np.float64) - x0, np.asarray(y, np.float64) - y0
    iu, iv = np.floor(u), np.floor(v)
    inside = (iu >= 1) & (iv >= 1) & (iu <= w - 3) & (iv <= h - 3)
    iu, iv = np.where(inside, iu, 1).astype(np.intp), np.where(inside, iv, 1).astype(np.intp)
    wu = np.stack(_keys((u - iu).astype(np.float32)), axis=-1)[..., :, None]      # (..., 4, 1)
    wv = np.stack(_keys((v - iv).astype(np.float32)), axis=-1)[..., None, :]      # (..., 1, 4)
    taps = image.ravel()[(iv * w + iu)[..., None, None] + _TAPS * w + _TAPS.T]   # (..., 4, 4): [row, col]
    if nodata is not None:
        inside &= ~(taps == nodata).any(axis=(-2, -1))
    out = (wv @ (taps.astype(np.float32) @ wu))[..., 0, 0]
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


def find_peaks(c: np.ndarray, exclusion: int, local: bool = False) -> Peaks:
    """Peaks of correlation surfaces c (b, n, m): integer maximum refined by a paraboloid; the
    second peak is the largest value farther than ``exclusion`` from the first, or with ``local``
    the largest local maximum (of its 3 x 3 neighbourhood) there. The plain second value also
    rejects a broad peak (a clicked point on an edge or on smooth ground, whose position the peak
    hardly fixes); a local maximum is another place the chip could match, while on smooth,
    oversampled images (0.5 m Pleiades, sand) the flank of a single broad peak stays above 85 % of
    it for several pixels: the matcher, whose least-squares fit and backward check judge a broad
    peak, asks for local maxima (measured on the Giza pair: 56 % of the grid points matched with
    the plain value, 74 % with local maxima, the same share flagged by the adjustment)."""
    b, n, m = c.shape
    flat = c.reshape(b, -1)
    k = np.argmax(flat, axis=1)
    i, j = np.divmod(k, m)
    value = flat[np.arange(b), k]
    border = (i == 0) | (j == 0) | (i == n - 1) | (j == m - 1)
    ii, jj = np.clip(i, 1, n - 2), np.clip(j, 1, m - 2)
    rows = ii[:, None, None] + np.arange(-1, 2)[None, :, None]
    cols = jj[:, None, None] + np.arange(-1, 2)[None, None, :]
    z = c[np.arange(b)[:, None, None], rows, cols].reshape(b, 9)
    _, gb, gc, gd, ge, gf = (_PARABOLOID @ z.T)
    det = 4 * gd * gf - ge * ge
    ok = (det > 1e-12) & (gd < 0) & (gf < 0)
    sx = np.where(ok, (-2 * gf * gb + ge * gc) / np.where(ok, det, 1.0), 0.0)
    sy = np.where(ok, (-2 * gd * gc + ge * gb) / np.where(ok, det, 1.0), 0.0)
    sx, sy = np.clip(sx, -1.0, 1.0), np.clip(sy, -1.0, 1.0)
    yy, xx = np.mgrid[0:n, 0:m]
    far = (np.abs(yy[None] - i[:, None, None]) > exclusion) | (np.abs(xx[None] - j[:, None, None]) > exclusion)
    if local:
        far &= c >= maximum_filter(c, size=(1, 3, 3), mode="nearest")
    second = np.where(far, c, -np.inf).reshape(b, -1).max(axis=1)
    ratio = np.where(value > 0, np.maximum(second, 0.0) / np.maximum(value, 1e-12), 1.0)
    return Peaks(jj + sx, ii + sy, value, ratio, border | ~ok)


def block_mean(a: np.ndarray, f: int) -> np.ndarray:
    """Means of the f x f blocks of a (h, w), both multiples of f: the sum of the f^2 strided views
    (far faster than a mean over two axes of a reshaped array)."""
    out = np.zeros((a.shape[0] // f, a.shape[1] // f), np.result_type(a.dtype, np.float32))
    for i in range(f):
        for j in range(f):
            out += a[i::f, j::f]
    return out / (f * f)


STRIP_ROWS = 1024  # rows of an image converted to float at a time when block-averaged


def strip_block_mean(a: np.ndarray, f: int, nodata) -> np.ndarray:
    """Means (float32) of the f x f blocks of the image a (h, w; any type) that fit in it, its
    ``nodata`` pixels NaN (a block holding one is NaN), converted STRIP_ROWS rows at a time so that
    no float copy of a large image is ever held."""
    rows, cols = a.shape[0] // f, a.shape[1] // f
    out = np.empty((rows, cols), np.float32)
    step = max(1, STRIP_ROWS // f)
    for i in range(0, rows, step):
        strip = a[i * f:min(i + step, rows) * f, :cols * f].astype(np.float32)
        if nodata is not None:
            strip[strip == nodata] = np.nan
        out[i:i + step] = block_mean(strip, f)
    return out


class BlockMeans:
    """An image's (cols x rows px) block means by powers of two, each made once: level 2 from the
    image itself (``read(factor)``: float32, nodata NaN) when it fits in ``budget`` bytes, the others
    from the finest made that divides them (a level of a level is the level of the image: means of
    equal blocks), so the image is read once however many levels are made. Level pixel [i, j] is
    the mean of image pixels [i f:(i+1) f, j f:(j+1) f]: image array position x is level position
    (x - (f - 1) / 2) / f."""

    def __init__(self, read, cols: int, rows: int, budget: float):
        self.read, self.levels = read, {}
        self.first = 2 if (cols // 2) * (rows // 2) * 4 <= budget else None

    def level(self, factor: int) -> np.ndarray:
        if factor not in self.levels:
            if self.first is not None and factor > self.first and factor % self.first == 0:
                self.level(self.first)
            finer = [g for g in self.levels if factor % g == 0]
            if finer:
                g = max(finer)
                k = factor // g
                a = self.levels[g]
                self.levels[factor] = block_mean(a[:a.shape[0] // k * k, :a.shape[1] // k * k], k)
            else:
                self.levels[factor] = self.read(factor)
        return self.levels[factor]


def masked_ncc(template: np.ndarray, image: np.ndarray, min_overlap: int) -> tuple[np.ndarray, np.ndarray]:
    """Normalised cross-correlation (H - h + 1, W - w + 1) of ``template`` (h, w) placed at every
    position inside ``image`` (H, W), both with NaN holes (nodata, outside a model's reach): each
    placement correlates only the pixels both hold (masked NCC in the Fourier domain, Padfield
    2012). Entry [i, j] puts the template's upper-left pixel on image pixel (row i, col j); and the
    overlap (pixels both hold) of each placement. Placements overlapping by fewer than
    ``min_overlap`` pixels (tiny overlaps correlate by chance), or flat there, give -1."""
    h, w = template.shape
    H, W = image.shape
    mt, mi = np.isfinite(template), np.isfinite(image)
    t, a = np.where(mt, template, 0.0), np.where(mi, image, 0.0)
    shape = (scipy.fft.next_fast_len(H, real=True), scipy.fft.next_fast_len(W, real=True))

    def spectrum(x):
        return scipy.fft.rfft2(x.astype(np.float64), s=shape)

    def correlate(fa, fb):
        return scipy.fft.irfft2(fa * np.conj(fb), s=shape)[:H - h + 1, :W - w + 1]

    f_mi, f_a, f_aa = spectrum(mi), spectrum(a), spectrum(a * a)
    f_mt, f_t, f_tt = spectrum(mt), spectrum(t), spectrum(t * t)
    n = np.rint(correlate(f_mi, f_mt))
    safe = np.maximum(n, 1.0)
    s_a, s_t = correlate(f_a, f_mt), correlate(f_mi, f_t)
    var_a = correlate(f_aa, f_mt) - s_a * s_a / safe
    var_t = correlate(f_mi, f_tt) - s_t * s_t / safe
    cov = correlate(f_a, f_t) - s_a * s_t / safe
    # the variances' floor: rounding of the FFT sums, relative to the energies summed
    floor = 1e-9 * np.maximum(float(np.max(np.abs(f_aa[..., :1]))), 1.0)
    ok = (n >= max(min_overlap, 16)) & (var_a > floor) & (var_t > floor)
    out = np.where(ok, cov / np.sqrt(np.where(ok, var_a * var_t, 1.0)), -1.0)
    return np.clip(out, -1.0, 1.0), n
