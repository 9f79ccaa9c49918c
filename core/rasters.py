"""Input rasters, read and never written: opened read-only without GDAL's auxiliary files.

GDAL keeps what it learns about a raster — statistics, histograms, metadata a caller sets — in the
raster's PAM (persistent auxiliary metadata) and writes it, when the dataset is closed, to
``<file>.aux.xml`` beside the raster. An input must stay byte-identical with no file appearing beside
it (docs/files-and-outputs.md), so every raster the plugin reads is opened by
:func:`open_input_raster`: read-only, its PAM disabled. GDAL decides whether a dataset has PAM when it
first touches it (the GeoTIFF driver lazily, on the first metadata read), from the configuration
option GDAL_PAM_ENABLED; the dataset is touched once while the option is NO for the calling thread
only, so that outputs written meanwhile by other threads keep their PAM (an RPC or statistics beside
an output are wanted there). A VRT has no PAM: what is set on it goes into the VRT file itself, so
nothing is ever computed or set on an input dataset (statistics included).

A VRT written over an input (the display copy, an image with a fitted RPC) passes statistics asked
of it on to its source, whose PAM then lands beside the input: such a VRT carries the source's
statistics itself (:func:`copy_statistics`), so that a viewer loading it (QGIS computes statistics
of every raster layer it loads) finds them there.
"""
from __future__ import annotations

import math
from contextlib import contextmanager
from pathlib import Path

import numpy as np
from osgeo import gdal

from .errors import InputError

gdal.UseExceptions()

PAM_OPTION = "GDAL_PAM_ENABLED"
EXACT_STATISTICS_PIXELS = 1_000_000
"""Rasters of up to this many pixels get exact statistics (a full read costs little); larger ones get
GDAL's approximate statistics, which QGIS takes as they are for any raster over 500 000 pixels (twice
the sample of its QgsRasterLayer.SAMPLE_SIZE, 250 000)."""


@contextmanager
def pam_disabled():
    """A block during which GDAL datasets the calling thread touches first get no PAM (the thread's
    own GDAL_PAM_ENABLED=NO; other threads and the global setting are left alone)."""
    previous = gdal.GetThreadLocalConfigOption(PAM_OPTION, None)
    gdal.SetThreadLocalConfigOption(PAM_OPTION, "NO")
    try:
        yield
    finally:
        gdal.SetThreadLocalConfigOption(PAM_OPTION, previous)


def open_input_raster(path, open_options: list[str] | None = None) -> gdal.Dataset:
    """The raster at ``path`` (a file or any GDAL name: a VRT, /vsizip/...) opened read-only with its
    PAM disabled: nothing read from it, computed on it or set on it is ever written beside it.
    Fails as gdal.OpenEx fails (RuntimeError with GDAL's message; GDAL's exceptions are on)."""
    with pam_disabled():
        ds = gdal.OpenEx(str(path), gdal.OF_RASTER | gdal.OF_READONLY, open_options=open_options or [])
        if ds is not None:
            ds.GetMetadata()  # the GeoTIFF driver initialises PAM on its first metadata read: now, without it
    return ds


def check_input_raster(path) -> tuple[int, int]:
    """(cols, rows) of the raster at ``path``; InputError naming it and saying what it is when it is
    not a raster GDAL reads: missing, a folder, a vector file, another file (GDAL's reason), or a
    raster without a band."""
    text = str(path)
    if not text:
        raise InputError("no raster file given (a layer that is not a file: a memory or service layer; save it "
                         "as GeoTIFF first)")
    local = "://" not in text and not text.startswith("/vsi")
    if local and not Path(text).exists():
        raise InputError(f"{text} does not exist")
    if local and Path(text).is_dir():
        raise InputError(f"{text} is a folder, not a raster file")
    try:
        ds = open_input_raster(text)
    except RuntimeError as exc:
        raise InputError(not_a_raster(text, exc)) from None
    if ds is None or ds.RasterCount == 0:
        raise InputError(f"{text} holds no raster band")
    return ds.RasterXSize, ds.RasterYSize


def not_a_raster(text: str, reason: Exception) -> str:
    """What the file ``text``, which GDAL did not open as a raster (``reason``), is instead: a vector
    file (named by its driver) or a file GDAL cannot read."""
    try:
        vector = gdal.OpenEx(text, gdal.OF_VECTOR)
    except RuntimeError:
        vector = None
    if vector is not None:
        return f"{text} is a vector file ({vector.GetDriver().ShortName}: points, lines or polygons), not a raster"
    return f"{text} is not a raster GDAL can read ({str(reason).strip()})"


def copy_statistics(source: gdal.Dataset, target: gdal.Dataset) -> None:
    """Set on each band of ``target`` (a VRT showing ``source``, band for band) the statistics of the
    same band of ``source``, computed here from its pixels (nodata and non-finite values left out):
    exact for rasters of up to EXACT_STATISTICS_PIXELS pixels, from whole blocks spread evenly over
    the raster beyond (about that many pixels, flagged approximate as GDAL's own approximate
    statistics are). A viewer asking the VRT for statistics finds them instead of GDAL computing
    them on the source and writing them beside it. Nothing is set on ``source``."""
    for k in range(1, min(source.RasterCount, target.RasterCount) + 1):
        band = source.GetRasterBand(k)
        values, approximate = sample_band(band)
        valid = np.isfinite(values)
        if band.GetNoDataValue() is not None:
            valid &= values != band.GetNoDataValue()
        if not valid.any():  # no valid pixel: nothing to say; a viewer shows the band as it can
            continue
        values = values[valid]
        out = target.GetRasterBand(k)
        out.SetStatistics(float(values.min()), float(values.max()), float(values.mean()), float(values.std()))
        if approximate:
            out.SetMetadataItem("STATISTICS_APPROXIMATE", "YES")


def sample_band(band: gdal.Band) -> tuple[np.ndarray, bool]:
    """(pixel values (n,) float64, whether they are a sample): every pixel of a band of up to
    EXACT_STATISTICS_PIXELS pixels; beyond, the whole blocks of every k-th block row and column
    (k chosen for about that many pixels; every block when k is 1), so that a tiled or striped
    raster is read only where sampled."""
    cols, rows = band.XSize, band.YSize
    if cols * rows <= EXACT_STATISTICS_PIXELS:
        return band.ReadAsArray().astype(np.float64).ravel(), False
    width, height = band.GetBlockSize()
    across, down = math.ceil(cols / width), math.ceil(rows / height)
    step = max(1, math.floor(math.sqrt(across * down * width * height / EXACT_STATISTICS_PIXELS)))
    blocks = [band.ReadAsArray(i * width, j * height, min(width, cols - i * width), min(height, rows - j * height))
              for j in range(0, down, step) for i in range(0, across, step)]
    return np.concatenate([b.astype(np.float64).ravel() for b in blocks]), step > 1
