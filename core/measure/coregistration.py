"""How well two orthoimages of the same grid co-register: phase correlation on a grid of windows.

Both images are cut into square windows (``window`` px, every ``spacing`` px). For each window the
normalised cross-power spectrum of the two (mean removed, Hann-tapered so the window's edges do
not correlate) is inverted: its peak is the shift of the second image against the first. The
integer peak is refined by an upsampled DFT of the spectrum around it (Guizar-Sicairos et al.
2008; UPSAMPLING steps per pixel, then a parabola through the finest samples). The taper
pulls the estimate towards zero in proportion to the shift (1.5 % of it: 0.08 px of a 5 px
shift), so the second image's window is then moved back by the estimate (an integer offset and
a Fourier shift) and correlated again, REFINEMENTS times, adding what remains: measured on
Fourier-shifted images, the shift is read to 0.0005 px (a periodic texture) or 0.004 px (a
Pleiades crop, whose own shift rings at its borders). A window whose moved-back patch leaves the
image or meets nodata keeps its first estimate.

A window is left out, with its reason counted, when either image holds nodata (or NaN) in it,
when either image has too little texture there (standard deviation < ``min_texture`` DN: water,
saturated or flat ground, which gives no shift), or when the correlation peak is weak (height <
``min_peak``: the images do not show the same thing there, e.g. changed land cover, clouds,
relief the surface of the orthoimages misses, or noise; a peak of pure noise in a 64 px window
is about 0.07, a clean pair's is near 1). A window whose shift lies FAR_PX or more (or
FAR_SIGMAS robust sigmas, if that is more) from the median shift of all windows is left out
too, its shift kept: what moves one window alone is not the images' registration but the
ground (relief the orthoimages' surface misses: a building, a pyramid; a moving object), and
it is counted, not averaged in.

Shifts (dx, dy) are in output pixels, x along columns (east on a north-up grid), y along rows
(south): the second image shows at (x + dx, y + dy) what the first shows at (x, y).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.fft
from osgeo import gdal

from ..errors import InputError
from ..rasters import open_input_raster

gdal.UseExceptions()

NODATA = "nodata"
LOW_TEXTURE = "low texture"
WEAK_PEAK = "weak peak"
FAR = "far from the others"
REASONS = (NODATA, LOW_TEXTURE, WEAK_PEAK, FAR)
FAR_PX = 1.0      # px: a window this far (at least) from the median shift of all windows is left out ...
FAR_SIGMAS = 5.0  # ... or this many robust sigmas (1.4826 MAD) of the distances, if that is more
MARGIN = 16  # px of patch around a window moved back by a Fourier shift (its wrap-around is cut off)
REFINEMENTS = 2  # passes on the resampled second image (each shrinks the taper's bias)
UPSAMPLING = 100  # steps per pixel of the sub-pixel search: 0.01 px, refined further by a parabola
BATCH = 64  # windows per FFT batch (memory: the upsampled DFT takes batch x window x upsampled points)


@dataclass(frozen=True)
class CoregSettings:
    """window (px, even, 16-512), spacing (px between window origins, >= 8), min_texture (DN,
    standard deviation of each window), min_peak (phase correlation peak height, 0-1)."""
    window: int = 64
    spacing: int = 64
    min_texture: float = 2.0
    min_peak: float = 0.15

    def validate(self) -> None:
        checks = {"window": 16 <= self.window <= 512 and self.window % 2 == 0, "spacing": self.spacing >= 8,
                  "min_texture": self.min_texture >= 0, "min_peak": 0 <= self.min_peak < 1}
        bad = [k for k, ok in checks.items() if not ok]
        if bad:
            raise InputError(f"co-registration settings out of range: "
                             f"{', '.join(f'{k}={getattr(self, k)}' for k in bad)} (window even 16-512 px, "
                             "spacing >= 8 px, min_peak in [0, 1))")


@dataclass
class Coregistration:
    """Per window (n,): centre (x, y) in array positions of the grid (pixel centres at integers),
    shift (dx, dy) px (NaN where none was read: nodata, low texture, weak peak), phase
    correlation peak height (NaN where not correlated) and reason index into REASONS (-1: used)."""
    x: np.ndarray
    y: np.ndarray
    dx: np.ndarray
    dy: np.ndarray
    peak: np.ndarray
    reason: np.ndarray

    @property
    def used(self) -> np.ndarray:
        return self.reason < 0

    @property
    def n_used(self) -> int:
        return int(self.used.sum())

    def left_out(self) -> dict:
        """{reason: number of windows left out for it}, every reason of REASONS."""
        return {r: int((self.reason == k).sum()) for k, r in enumerate(REASONS)}

    def _length(self) -> np.ndarray:
        return np.hypot(self.dx[self.used], self.dy[self.used])

    @property
    def rms(self) -> float:
        """RMS length of the used windows' shifts (px); NaN without one."""
        d = self._length()
        return float(np.sqrt(np.mean(d * d))) if d.size else float("nan")

    @property
    def max(self) -> float:
        """Largest shift length of a used window (px); NaN without one."""
        d = self._length()
        return float(d.max()) if d.size else float("nan")

    @property
    def median(self) -> float:
        """Median shift length of the used windows (px): the typical window, blind to a few outliers."""
        d = self._length()
        return float(np.median(d)) if d.size else float("nan")

    @property
    def mean(self) -> tuple[float, float]:
        """Mean shift (dx, dy) of the used windows (px): the common part, e.g. a relative bias."""
        if not self.n_used:
            return float("nan"), float("nan")
        return float(self.dx[self.used].mean()), float(self.dy[self.used].mean())

    def summary(self) -> dict:
        return {"windows": int(self.reason.size), "used": self.n_used, "left_out": self.left_out(),
                "rms_px": self.rms, "max_px": self.max, "median_px": self.median, "mean_px": self.mean}


def phase_correlate(a: np.ndarray, b: np.ndarray,
                    upsampling: int = UPSAMPLING) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Shift (dx, dy) px of windows ``b`` against windows ``a`` (both (k, n, n), finite) and the
    phase correlation peak height (k,): the peak of the half-whitened cross-power spectrum's
    inverse, refined to 1 / ``upsampling`` px with an upsampled DFT and a parabola through its
    three finest samples per axis. Shifts beyond n / 2 wrap around (phase correlation sees shifts
    modulo the window)."""
    k, n, _ = a.shape
    taper = np.outer(np.hanning(n), np.hanning(n))
    fa = scipy.fft.fft2((a - a.mean(axis=(1, 2), keepdims=True)) * taper)
    fb = scipy.fft.fft2((b - b.mean(axis=(1, 2), keepdims=True)) * taper)
    cross = fb * np.conj(fa)
    magnitude = np.maximum(np.abs(cross), 1e-12)
    # the peak height of classic (whitened) phase correlation: 1 for identical content, about
    # 0.07 for unrelated 64 px windows
    peak = scipy.fft.ifft2(cross / magnitude).real.reshape(k, -1).max(axis=1)
    # the shift from the half-whitened spectrum: full whitening lets the frequencies without
    # signal (the taper's leakage, noise) weigh as much as the rest, doubling the error on smooth ground
    cross /= np.sqrt(magnitude)
    top = np.argmax(scipy.fft.ifft2(cross).real.reshape(k, -1), axis=1)
    i, j = np.divmod(top, n)
    i, j = np.where(i > n // 2, i - n, i), np.where(j > n // 2, j - n, j)
    # the spectrum's inverse DFT evaluated on a fine grid of +-0.75 px around the integer peak
    m = int(np.ceil(1.5 * upsampling)) | 1
    step = (np.arange(m) - m // 2) / upsampling
    freq = scipy.fft.fftfreq(n)
    ys, xs = i[:, None] + step[None], j[:, None] + step[None]           # (k, m)
    ey = np.exp(2j * np.pi * ys[:, :, None] * freq[None, None, :])      # (k, m, n)
    ex = np.exp(2j * np.pi * freq[None, :, None] * xs[:, None, :])      # (k, n, m)
    fine = np.einsum("kuf,kfg,kgv->kuv", ey, cross, ex, optimize=True).real.reshape(k, -1)
    u, v = np.divmod(np.argmax(fine, axis=1), m)
    fine = fine.reshape(k, m, m)
    return (xs[np.arange(k), v] + _vertex(fine, u, v, axis=2) / upsampling,
            ys[np.arange(k), u] + _vertex(fine, u, v, axis=1) / upsampling, peak)


def _vertex(fine: np.ndarray, u: np.ndarray, v: np.ndarray, axis: int) -> np.ndarray:
    """Vertex offset (in fine steps, within +-0.5) of the parabola through the fine surface's
    maximum (u, v) and its two neighbours along ``axis`` (0 on the border of the fine grid)."""
    k, m, _ = fine.shape
    pos = v if axis == 2 else u
    inner = (pos > 0) & (pos < m - 1)
    p = np.clip(pos, 1, m - 2)
    at = (lambda d: fine[np.arange(k), u, p + d]) if axis == 2 else (lambda d: fine[np.arange(k), p + d, v])
    left, mid, right = at(-1), at(0), at(1)
    curve = left - 2 * mid + right
    ok = inner & (curve < 0)
    return np.where(ok, np.clip(0.5 * (left - right) / np.where(ok, curve, -1.0), -0.5, 0.5), 0.0)


def _moved_back(padded: np.ndarray, r0: np.ndarray, c0: np.ndarray, dx: np.ndarray, dy: np.ndarray, w: int,
                nodata) -> tuple[np.ndarray, np.ndarray]:
    """The w x w windows (k, w, w) at (r0, c0) of an image moved by (dx, dy) px back onto the first
    image's: an integer offset and a Fourier shift of the rest (exact for a band-limited image,
    unlike an interpolation kernel, whose phase errors phase correlation would read) on a patch
    MARGIN px wider than the window, whose wrapped-around edge is then cut off. ``padded``: the
    image with MARGIN px of mirrored edge on each side. Also (k,) whether the moved window lies in
    the image and its patch holds data only."""
    iy, ix = np.rint(dy).astype(np.intp), np.rint(dx).astype(np.intp)
    top, left = r0 + iy, c0 + ix  # the patch's upper-left in the padded image
    size = w + 2 * MARGIN
    inside = ((top >= 0) & (left >= 0) & (top + w + 2 * MARGIN <= padded.shape[0])
              & (left + w + 2 * MARGIN <= padded.shape[1]))
    rows = np.where(inside, top, 0)[:, None, None] + np.arange(size)[None, :, None]
    cols = np.where(inside, left, 0)[:, None, None] + np.arange(size)[None, None, :]
    patch = padded[rows, cols].astype(np.float64)
    bad = ~np.isfinite(patch) if nodata is None else ~np.isfinite(patch) | (patch == nodata)
    inside &= ~bad.any(axis=(1, 2))
    patch[bad] = 0.0
    freq = scipy.fft.fftfreq(size)
    phase = np.exp(2j * np.pi * ((dx - ix)[:, None, None] * freq[None, None, :]
                                 + (dy - iy)[:, None, None] * freq[None, :, None]))
    moved = scipy.fft.ifft2(scipy.fft.fft2(patch) * phase).real
    return moved[:, MARGIN:MARGIN + w, MARGIN:MARGIN + w], inside


def window_origins(shape: tuple[int, int], window: int, spacing: int) -> tuple[np.ndarray, np.ndarray]:
    """Upper-left (row, col) of the windows of a grid over an image of ``shape`` (rows, cols),
    centred on the image: every ``spacing`` px, each window wholly inside."""
    def axis(size: int) -> np.ndarray:
        count = (size - window) // spacing + 1
        if count < 1:
            return np.zeros(0, np.intp)
        first = (size - window - (count - 1) * spacing) // 2
        return first + spacing * np.arange(count)

    r, c = np.meshgrid(axis(shape[0]), axis(shape[1]), indexing="ij")
    return r.ravel(), c.ravel()


def coregister(first: np.ndarray, second: np.ndarray, settings: CoregSettings = CoregSettings(),
               nodata: float | None = None) -> Coregistration:
    """The co-registration of two images of one grid (2-D arrays of one shape; ``nodata`` and
    NaN mark pixels without data), see the module docstring."""
    settings.validate()
    if first.ndim != 2 or first.shape != second.shape:
        raise InputError(f"co-registration needs two images of one grid (got {first.shape} and {second.shape})")
    w = settings.window
    r0, c0 = window_origins(first.shape, w, settings.spacing)
    padded = np.pad(second, MARGIN, mode="reflect")
    parts = [_measure(first, second, padded, r0[s:s + BATCH], c0[s:s + BATCH], settings, nodata)
             for s in range(0, r0.size, BATCH)]
    dx, dy, peak, reason = (np.concatenate([p[k] for p in parts]) if parts else np.zeros(0) for k in range(4))
    reason = reason.astype(np.intp)
    reason[far_from_the_others(dx, dy, reason < 0)] = REASONS.index(FAR)
    return Coregistration(c0 + (w - 1) / 2, r0 + (w - 1) / 2, dx, dy, peak, reason)


def far_from_the_others(dx: np.ndarray, dy: np.ndarray, used: np.ndarray) -> np.ndarray:
    """(n,) the ``used`` windows whose shift lies FAR_PX or more from the median shift of the
    used windows, or FAR_SIGMAS robust sigmas of their distances from it if that is more."""
    far = np.zeros(dx.size, bool)
    if not used.any():
        return far
    dist = np.hypot(dx[used] - np.median(dx[used]), dy[used] - np.median(dy[used]))
    far[used] = dist >= max(FAR_PX, FAR_SIGMAS * 1.4826 * float(np.median(dist)))
    return far


def _measure(first: np.ndarray, second: np.ndarray, padded: np.ndarray, r0: np.ndarray, c0: np.ndarray,
             settings: CoregSettings, nodata) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """dx, dy, peak and reason (see :class:`Coregistration`) of the windows at (r0, c0)."""
    w = settings.window
    rows = r0[:, None, None] + np.arange(w)[None, :, None]
    cols = c0[:, None, None] + np.arange(w)[None, None, :]
    a, b = first[rows, cols].astype(np.float64), second[rows, cols].astype(np.float64)
    missing = ~(np.isfinite(a) & np.isfinite(b))
    if nodata is not None:
        missing |= (a == nodata) | (b == nodata)
    empty = missing.any(axis=(1, 2))
    with np.errstate(invalid="ignore"):  # NaN in the windows with nodata, which are left out anyway
        flat = ~empty & ((a.std(axis=(1, 2)) < settings.min_texture) | (b.std(axis=(1, 2)) < settings.min_texture))
    good = ~empty & ~flat
    dx, dy, peak = (np.full(r0.size, np.nan) for _ in range(3))
    reason = np.where(empty, REASONS.index(NODATA), np.where(flat, REASONS.index(LOW_TEXTURE), -1))
    if not good.any():
        return dx, dy, peak, reason
    a = a[good]
    x, y, p = phase_correlate(a, b[good], UPSAMPLING)
    for _ in range(REFINEMENTS):
        # the second image moved back by the estimate leaves a small shift, which the taper does
        # not bias (it pulls a shift towards zero in proportion to it)
        moved, inside = _moved_back(padded, r0[good], c0[good], x, y, w, nodata)
        if not inside.any():
            break
        rx, ry, p[inside] = phase_correlate(a[inside], moved[inside], UPSAMPLING)
        x[inside] += rx
        y[inside] += ry
    weak = p < settings.min_peak
    peak[good] = p
    dx[good], dy[good] = np.where(weak, np.nan, x), np.where(weak, np.nan, y)
    reason[np.nonzero(good)[0][weak]] = REASONS.index(WEAK_PEAK)
    return dx, dy, peak, reason


def coregister_files(first, second, settings: CoregSettings = CoregSettings(), band: int = 1) -> Coregistration:
    """:func:`coregister` of band ``band`` of two raster files (e.g. orthoimages), which must share
    their grid: size, geotransform and CRS (InputError naming what differs). Each file's own
    nodata value marks its pixels without data."""
    arrays = []
    grids = []
    for path in (first, second):
        ds = open_input_raster(path)
        b = ds.GetRasterBand(band)
        data = b.ReadAsArray().astype(np.float64)
        if b.GetNoDataValue() is not None:
            data[data == b.GetNoDataValue()] = np.nan
        arrays.append(data)
        grids.append(((ds.RasterXSize, ds.RasterYSize), ds.GetGeoTransform(), ds.GetSpatialRef()))
    (size_a, gt_a, srs_a), (size_b, gt_b, srs_b) = grids
    if size_a != size_b or not np.allclose(gt_a, gt_b, rtol=0, atol=1e-9 * max(1.0, abs(gt_a[1]))):
        raise InputError(f"{first} and {second} are not on one grid (size {size_a} / {size_b}, geotransform "
                         f"{gt_a} / {gt_b}): orthorectify them onto the same grid")
    if (srs_a is None) != (srs_b is None) or (srs_a is not None and not srs_a.IsSame(srs_b)):
        raise InputError(f"{first} and {second} are not in one CRS: orthorectify them onto the same grid")
    return coregister(arrays[0], arrays[1], settings)
