"""Resampling a raw image through a :class:`core.products.mapping.Mapper` into a tiled,
compressed GeoTIFF with overviews: tiles on a thread per core (or on any runner of tiles, e.g. a
Dask scheduler, :mod:`core.products.orthojobs`), each resampled (nearest, bilinear or cubic) at
its image positions with its part of every overview level, written completely or not at all
(:class:`core.files.OutputSet`).
"""
from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from typing import Callable

import numpy as np
from osgeo import gdal

from ..errors import Cancelled, InputError
from ..files import OutputSet, closing_errors, write_failure
from .mapping import Mapper, MappingFigures, Nodes
from .rawimage import RawImage, resample

gdal.UseExceptions()

RESAMPLING = {"nearest": 0, "bilinear": 1, "cubic": 3}  # spline orders of scipy.ndimage
OVERVIEW_FACTORS = (2, 4, 8, 16, 32, 64)


def overview_levels(cols: int, rows: int) -> list[int]:
    """Overview decimation factors of an output: halvings down to about 256 px on the long side."""
    return [f for f in OVERVIEW_FACTORS if max(cols, rows) / f >= 256]


def check_resampling(resampling: str, tile: int, step: int) -> None:
    """InputError for an unknown resampling; ValueError for a tile that is not a multiple of the
    node step and of the largest overview factor."""
    if resampling not in RESAMPLING:
        raise InputError(f"resampling must be one of {', '.join(RESAMPLING)} (got {resampling!r})")
    if tile % step or tile % OVERVIEW_FACTORS[-1]:
        raise ValueError(f"tile ({tile}) must be a multiple of step ({step}) and of {OVERVIEW_FACTORS[-1]}")


def tile_blocks(mapper: Mapper, raw: RawImage, window: tuple[int, int, int, int], step: int, max_error: float,
                planned: "Nodes | None", order: int, fill, levels: list[int], nodata):
    """One tile: the bands (resampled), their parts of each overview level and what mapping its
    pixels measured (:class:`core.products.mapping.MappingFigures`). The same computation for the
    threads of one process and for a distributed job."""
    r0, r1, c0, c1 = window
    col, row, figures = mapper.tile(r0, r1, c0, c1, step, max_error, planned)
    blocks = resample(raw, col, row, order, fill, mapper.rows)
    return blocks, [_overview_blocks(b, levels, nodata, order == 0) for b in blocks], figures


def _overview_blocks(block: np.ndarray, levels: list[int], nodata, nearest: bool) -> list[np.ndarray]:
    """A tile's part of each overview level (factor f: ceil(shape / f) px): the mean of the valid
    (not nodata) pixels of each f x f cell, or with ``nearest`` the pixel nearest its centre.
    Cells without valid pixels are nodata."""
    if nearest:
        def pick(n, f):
            return np.minimum(np.arange(-(-n // f)) * f + f // 2, n - 1)
        return [block[np.ix_(pick(block.shape[0], f), pick(block.shape[1], f))] for f in levels]
    valid = np.ones(block.shape, bool) if nodata is None else block != nodata
    if not valid.any():
        return [np.full((-(-block.shape[0] // f), -(-block.shape[1] // f)), nodata, block.dtype) for f in levels]
    total = block.astype(np.float32)  # float32 sums: 1e-7 relative, far below one grey level
    total[~valid] = 0.0
    count = valid.astype(np.float32)
    out, reached = [], 1
    for f in levels:
        while reached < f:  # halve the sums and counts: level 2f from level f
            total, count = _sum_pairs(total), _sum_pairs(count)
            reached *= 2
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = total / count
        if np.issubdtype(block.dtype, np.integer):
            mean = np.rint(mean)
        out.append(np.where(count > 0, mean, nodata if nodata is not None else 0).astype(block.dtype))
    return out


def _sum_pairs(a: np.ndarray) -> np.ndarray:
    """Sums of 2 x 2 cells (a ragged last row / column summed alone)."""
    h, w = a.shape
    if h % 2 or w % 2:
        padded = np.zeros((h + h % 2, w + w % 2), a.dtype)
        padded[:h, :w] = a
        a = padded
    return a[0::2, 0::2] + a[1::2, 0::2] + a[0::2, 1::2] + a[1::2, 1::2]


def write_tile(out_bands, levels: list[int], window: tuple, blocks, overviews) -> None:
    """A tile's bands and overview parts into the output's bands (in tile order: the file's
    layout depends on the order blocks are written)."""
    r0, _, c0, _ = window
    for band, b, ovr in zip(out_bands, blocks, overviews):
        band.WriteArray(b, c0, r0)
        for k, (f, o) in enumerate(zip(levels, ovr)):
            band.GetOverview(k).WriteArray(o, c0 // f, r0 // f)


def create_geotiff(path, cols: int, rows: int, count: int, data_type: int, levels: list[int], nodata,
                   options: list[str]):
    """A new GeoTIFF with empty overviews at ``levels`` (each tile writes its part of them)."""
    out = gdal.GetDriverByName("GTiff").Create(str(path), cols, rows, count, data_type, options)
    for k in range(count):
        if nodata is not None:
            out.GetRasterBand(k + 1).SetNoDataValue(nodata)
    if levels:
        out.BuildOverviews("NONE", levels)
    return out


def write_resampled(raw: RawImage, mapper: Mapper, planned: Nodes, shape: tuple[int, int], output_path,
                    resampling: str,
                    nodata: float | None, tile: int, max_error: float,
                    georeference: Callable[[gdal.Dataset], None] | None = None,
                    progress: Callable[[float], None] | None = None,
                    is_cancelled: Callable[[], bool] | None = None, files: OutputSet | None = None,
                    run_tiles: Callable | None = None) -> MappingFigures:
    """Resample ``raw`` through ``mapper`` (output pixel -> raw image position; any subclass of
    :class:`Mapper` with its own ``exact``) onto an output of ``shape`` (rows, cols), whose node
    grid ``planned`` (:meth:`Mapper.nodes` over the whole output) it slices, and write it as a
    tiled, compressed GeoTIFF with overviews to ``output_path``; ``georeference(dataset)`` sets
    its georeferencing. Tiles on a thread per core, or by ``run_tiles(windows, out_bands, levels,
    progress, is_cancelled)`` (e.g. :func:`core.products.orthojobs.tiles_on_scheduler`), which
    writes every window (r0, r1, c0, c1) into the output's bands with :func:`write_tile` in the
    order given and returns the tiles' mapping figures merged; ``progress`` gets the share of tiles
    done. Written completely or not at all: with ``files`` as part of that set (its owner commits
    it). Returns what mapping the pixels measured (:class:`core.products.mapping.MappingFigures`)."""
    rows, cols = shape
    fill = nodata if nodata is not None else 0.0
    cancelled = is_cancelled or (lambda: False)
    report = progress or (lambda fraction: None)
    levels = overview_levels(cols, rows)
    own = files is None
    files = files or OutputSet()
    failed = ""
    figures = MappingFigures()
    try:
        out = create_geotiff(files.path(output_path), cols, rows, raw.count, raw.data_type, levels, nodata,
                             ["TILED=YES", f"BLOCKXSIZE={tile}", f"BLOCKYSIZE={tile}", "COMPRESS=DEFLATE",
                              "PREDICTOR=2", "BIGTIFF=IF_SAFER", "NUM_THREADS=ALL_CPUS"])
        if georeference is not None:
            georeference(out)
        out_bands = [out.GetRasterBand(k + 1) for k in range(raw.count)]
        windows = [(r0, min(r0 + tile, rows), c0, min(c0 + tile, cols))
                   for r0 in range(0, rows, tile) for c0 in range(0, cols, tile)]
        if run_tiles is not None:
            figures = run_tiles(windows, out_bands, levels, report, cancelled)
        else:
            order = RESAMPLING[resampling]

            def work(window):
                if cancelled():
                    raise Cancelled("resampling cancelled by the user")
                return tile_blocks(mapper, raw, window, planned.step, max_error, planned, order, fill, levels,
                                   nodata)

            with ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as pool:
                for n, (window, (blocks, overviews, tiled)) in enumerate(zip(windows, pool.map(work, windows))):
                    write_tile(out_bands, levels, window, blocks, overviews)
                    figures = figures.merge(tiled)
                    report((n + 1) / len(windows))
        out_bands = None
        out.FlushCache()
        with closing_errors() as closing:
            out = None  # closes the file: writing its last directories can still fail (a full disk)
        failed = closing.message
        if own and not failed:
            files.commit()
    except RuntimeError as exc:  # GDAL: disk full, file system errors; raised below, as this error's
        failed = str(exc)        # traceback holds the file open
    finally:
        with closing_errors() as closing:
            out_bands = out = None  # closes the file, flushing what is left
        failed = failed or closing.message
        if failed:  # in words while the partial file still fills the disk: a full disk is named as such
            failed = write_failure(output_path, failed)
        if own:
            files.discard()
    if failed:
        raise InputError(f"cannot write {output_path}: {failed}")
    return figures
