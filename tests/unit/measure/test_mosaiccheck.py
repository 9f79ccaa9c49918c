"""core.measure.mosaiccheck: two orthoimages of one pixel lattice whose grids only partly overlap,
the second showing the ground moved by a known sub-pixel shift, measured on their overlap alone;
grids off the lattice are refused, grids or data that do not meet are no pair."""
import numpy as np
import pytest
import scipy.fft
from osgeo import gdal, osr

from pushbroom_adjust.core.errors import InputError
from pushbroom_adjust.core.measure.mosaiccheck import (Raster, check_mosaic, check_pair, misregistered,
                                                       overlap_window)

SIZE = 5.0


def ground(shape=(400, 500), shift=(0.0, 0.0)) -> np.ndarray:
    """A smooth random texture (DN 20-220), moved by ``shift`` (dx, dy) px by a Fourier shift."""
    rng = np.random.default_rng(7)
    spectrum = scipy.fft.fft2(rng.normal(size=shape))
    fy, fx = scipy.fft.fftfreq(shape[0])[:, None], scipy.fft.fftfreq(shape[1])[None, :]
    spectrum *= np.exp(-(fx ** 2 + fy ** 2) / (2 * 0.08 ** 2))          # features of a few pixels
    spectrum *= np.exp(-2j * np.pi * (fx * shift[0] + fy * shift[1]))
    image = scipy.fft.ifft2(spectrum).real
    return 20 + 200 * (image - image.min()) / np.ptp(image)


def write(path, data: np.ndarray, col: int, row: int, x0: float = 500000.0) -> str:
    """``data`` as a GeoTIFF whose upper-left pixel is (col, row) of a lattice of SIZE m at x0."""
    ds = gdal.GetDriverByName("GTiff").Create(str(path), data.shape[1], data.shape[0], 1, gdal.GDT_Float32)
    ds.SetGeoTransform((x0 + col * SIZE, SIZE, 0.0, 4000000.0 - row * SIZE, 0.0, -SIZE))
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(32650)
    ds.SetProjection(srs.ExportToWkt())
    ds.GetRasterBand(1).SetNoDataValue(0.0)
    ds.GetRasterBand(1).WriteArray(data)
    ds = None
    return str(path)


def test_a_known_shift_is_read_on_the_overlap_alone(tmp_path):
    """The second image moved by (0.3, -0.2) px: read to 0.01 px on every window of the overlap
    (cols 200-349 of the first, 150 px wide); the nodata corner of the second is left out."""
    first = ground()
    moved = ground(shift=(0.3, -0.2))
    second = moved[:, 200:].copy()
    second[:64, :64] = 0.0                                                  # a nodata corner
    a = write(tmp_path / "a.tif", first[:, :350], 0, 0)
    b = write(tmp_path / "b.tif", second, 200, 0)
    (pair,) = check_mosaic({"a": a, "b": b})
    assert overlap_window(Raster.open("a", a), Raster.open("b", b)) == (200, 0, 0, 0, 150, 400)
    assert pair.first == "a" and pair.second == "b" and pair.common_pixels == 150 * 400 - 64 * 64
    assert pair.windows == 12 and pair.left_out["nodata"] == 1 and pair.used == 11
    assert pair.mean_px == pytest.approx((0.3, -0.2), abs=0.01)
    assert pair.rms_px == pytest.approx(np.hypot(0.3, 0.2), abs=0.01)
    assert misregistered([pair]) == [] and misregistered([pair], 0.2) == [pair]
    assert pair.sentence.startswith("a - b: 0.3") and pair.sentence.endswith("on 11 of 12 windows of 64 px; left out: 1 nodata")



def test_a_narrow_overlap_is_measured_on_smaller_windows(tmp_path):
    """An overlap of 70 x 400 px holds 6 windows of 64 px: measured again on 32 px windows every
    16 px (3 x 24), the known shift read to 0.02 px; a wide one keeps its 64 px windows."""
    first, moved = ground(), ground(shift=(0.3, -0.2))
    a = write(tmp_path / "a.tif", first[:, :270], 0, 0)
    b = write(tmp_path / "b.tif", moved[:, 200:], 200, 0)
    (pair,) = check_mosaic({"a": a, "b": b})
    assert pair.window_px == 32 and pair.windows == 72 and pair.used >= 60
    assert pair.mean_px == pytest.approx((0.3, -0.2), abs=0.02)
    assert "windows of 32 px" in pair.sentence
    wide = write(tmp_path / "wide.tif", moved[:, 100:], 100, 0)
    assert check_mosaic({"a": a, "wide": wide})[0].window_px == 64


def test_grids_off_the_lattice_are_refused_and_apart_are_no_pair(tmp_path):
    data = ground((100, 100))
    a = Raster.open("a", write(tmp_path / "a.tif", data, 0, 0))
    off = Raster.open("off", write(tmp_path / "off.tif", data, 50, 0, x0=500000.0 + 0.4 * SIZE))
    with pytest.raises(InputError, match="not on one pixel lattice: off's origin is 50.400000"):
        overlap_window(a, off)
    far = Raster.open("far", write(tmp_path / "far.tif", data, 100, 0))       # touching, not overlapping
    assert overlap_window(a, far) is None and check_pair(a, far) is None
    empty = Raster.open("empty", write(tmp_path / "empty.tif", np.zeros((100, 100)), 50, 50))
    assert overlap_window(a, empty) == (50, 50, 0, 0, 50, 50) and check_pair(a, empty) is None
