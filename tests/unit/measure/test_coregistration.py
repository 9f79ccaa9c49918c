"""Co-registration of two images of one grid (core.measure.coregistration) against known truth:
images shifted by a known sub-pixel offset (Fourier shift: exact for a band-limited image), and
windows that must be left out (noise, nodata, flat ground) counted by reason."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.fft
from osgeo import gdal, osr
from scipy.ndimage import gaussian_filter

from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.measure.coregistration import (
    FAR, LOW_TEXTURE, NODATA, REASONS, WEAK_PEAK, CoregSettings, coregister, coregister_files, window_origins)

gdal.UseExceptions()

SIZE = 400  # px: 6 x 6 windows of 64 px, 8 px from the edges


def texture(seed: int = 1, size: int = SIZE) -> np.ndarray:
    """A ground-like texture: smoothed white noise, about 200-800 DN."""
    rng = np.random.default_rng(seed)
    t = gaussian_filter(rng.normal(size=(size, size)), 1.5, mode="wrap")
    return 500 + 100 * t / t.std()


def fourier_shift(image: np.ndarray, dx: float, dy: float) -> np.ndarray:
    """``image`` moved by (dx, dy) px (x along columns): out(x + dx, y + dy) = image(x, y)."""
    ky = scipy.fft.fftfreq(image.shape[0])[:, None]
    kx = scipy.fft.fftfreq(image.shape[1])[None, :]
    return scipy.fft.ifft2(scipy.fft.fft2(image) * np.exp(-2j * np.pi * (kx * dx + ky * dy))).real


@pytest.mark.parametrize("shift", [(0.3, -0.7), (-0.05, 0.45), (5.25, -3.6)])
def test_a_known_subpixel_shift_is_recovered_in_every_window(shift):
    first = texture()
    result = coregister(first, fourier_shift(first, *shift))
    assert result.reason.size == 36 and result.n_used == 36
    assert result.left_out() == {r: 0 for r in REASONS}
    np.testing.assert_array_less(np.abs(result.dx - shift[0]), 0.005)  # measured 0.0003 px at most
    np.testing.assert_array_less(np.abs(result.dy - shift[1]), 0.005)  # measured 0.0005 px
    length = np.hypot(*shift)
    assert abs(result.rms - length) < 0.005 and abs(result.max - length) < 0.005
    assert np.all(result.peak > 0.5)


def test_no_shift_reads_zero():
    first = texture(3)
    result = coregister(first, first.copy())
    assert result.n_used == 36 and result.max < 0.005


def test_a_window_of_noise_is_left_out_and_counted():
    """One window of the second image replaced by unrelated noise: its peak is weak (about 0.07),
    it is left out as such, and the others still read the shift."""
    first = texture()
    second = fourier_shift(first, 0.3, -0.7)
    rows, cols = window_origins(first.shape, 64, 64)
    k = 14
    r, c = rows[k], cols[k]
    second[r:r + 64, c:c + 64] = texture(seed=99, size=64)
    result = coregister(first, second)
    assert result.left_out() == {NODATA: 0, LOW_TEXTURE: 0, WEAK_PEAK: 1, FAR: 0}
    assert result.reason[k] == REASONS.index(WEAK_PEAK) and np.isnan(result.dx[k])
    assert result.peak[k] < CoregSettings().min_peak
    assert result.n_used == 35
    assert abs(result.mean[0] - 0.3) < 0.02 and abs(result.mean[1] + 0.7) < 0.02
    assert abs(result.rms - np.hypot(0.3, 0.7)) < 0.02


def test_a_window_moved_alone_is_left_out_with_its_shift():
    """Ground moved in one window only (relief the orthoimages' surface misses, a moving object):
    its shift is read but kept out of the figures, which are the others'."""
    first = texture()
    second = fourier_shift(first, 0.3, -0.7)
    rows, cols = window_origins(first.shape, 64, 64)
    k = 21
    r, c = rows[k], cols[k]
    second[r:r + 64, c:c + 64] = fourier_shift(first, 2.8, 1.3)[r:r + 64, c:c + 64]
    result = coregister(first, second)
    assert result.left_out() == {NODATA: 0, LOW_TEXTURE: 0, WEAK_PEAK: 0, FAR: 1}
    assert result.reason[k] == REASONS.index(FAR)
    assert abs(result.dx[k] - 2.8) < 0.1 and abs(result.dy[k] - 1.3) < 0.1  # the window's own shift, kept
    others = result.used
    assert others.sum() == 35
    np.testing.assert_array_less(np.abs(result.dx[others] - 0.3), 0.02)
    np.testing.assert_array_less(np.abs(result.dy[others] + 0.7), 0.02)
    assert abs(result.max - np.hypot(0.3, 0.7)) < 0.02


def test_nodata_and_flat_windows_are_left_out_with_their_reason():
    first = texture()
    second = fourier_shift(first, -0.4, 0.2)
    first[:80, :] = 0.0                          # the first image's upper edge: no data (rows 0-79)
    second[200:264, 200:264] = 321.0             # a flat patch (water, saturation) in the second, one window
    result = coregister(first, second, nodata=0.0)
    rows, cols = window_origins(first.shape, 64, 64)
    expected_nodata = int((rows < 80).sum())     # windows reaching into rows 0-79: two rows of windows
    assert expected_nodata == 12
    assert result.left_out() == {NODATA: expected_nodata, LOW_TEXTURE: 1, WEAK_PEAK: 0, FAR: 0}
    assert result.n_used == 36 - 13
    np.testing.assert_array_less(np.abs(result.dx[result.used] + 0.4), 0.02)
    summary = result.summary()
    assert summary["windows"] == 36 and summary["used"] == 23


def _write(path, array, geotransform, epsg=32636) -> None:
    ds = gdal.GetDriverByName("GTiff").Create(str(path), array.shape[1], array.shape[0], 1, gdal.GDT_Float32)
    ds.SetGeoTransform(geotransform)
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(epsg)
    ds.SetProjection(srs.ExportToWkt())
    ds.GetRasterBand(1).SetNoDataValue(0)
    ds.GetRasterBand(1).WriteArray(array)
    ds = None


def test_files_of_one_grid_are_compared_and_others_refused(tmp_path):
    first = texture()
    second = fourier_shift(first, 0.3, -0.7)
    second[:, :64] = 0                           # the file's nodata: the first column of windows
    gt = (320000.0, 0.5, 0.0, 3318000.0, 0.0, -0.5)
    _write(tmp_path / "a.tif", first, gt)
    _write(tmp_path / "b.tif", second, gt)
    result = coregister_files(tmp_path / "a.tif", tmp_path / "b.tif")
    assert result.left_out()[NODATA] == 6 and result.n_used == 30
    np.testing.assert_array_less(np.abs(result.dy[result.used] + 0.7), 0.02)
    _write(tmp_path / "c.tif", second, (320000.5, 0.5, 0.0, 3318000.0, 0.0, -0.5))
    with pytest.raises(InputError, match="not on one grid"):
        coregister_files(tmp_path / "a.tif", tmp_path / "c.tif")
    _write(tmp_path / "d.tif", second, gt, epsg=32637)
    with pytest.raises(InputError, match="not in one CRS"):
        coregister_files(tmp_path / "a.tif", tmp_path / "d.tif")


def test_settings_and_shapes_are_checked():
    with pytest.raises(InputError, match="window=63"):
        coregister(texture(), texture(), CoregSettings(window=63))
    with pytest.raises(InputError, match="one grid"):
        coregister(texture(), texture(size=128))
