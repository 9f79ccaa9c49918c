"""Distributed orthorectification: one picklable job per tile of an orthoimage, run by the
workers of a Dask scheduler (other processes or machines, with this package importable and the
files reachable at the same paths), each writing its tile to a file that is then assembled into
the output in tile order: the same bytes as the threaded run.
"""
from __future__ import annotations

import json
import shutil
import tempfile
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Callable

from osgeo import gdal
from pyproj import CRS

from ..dem import ConstantHeight, Dem
from ..errors import Cancelled, InputError
from ..files import check_closed, closing_errors
from ..formats.scene_json import scene_from_dict
from ..rasters import open_input_raster
from .mapping import Mapper, MappingFigures, Nodes, OrthoGrid
from .rawimage import RawImage
from .resampling import RESAMPLING, create_geotiff, tile_blocks, write_tile

gdal.UseExceptions()

SCHEDULER_TIMEOUT = 10  # s to reach a Dask scheduler


def surface_description(surface) -> dict:
    """The terrain as plain data a job carries: {"height": m} or {"dem": path, "datum": ...}."""
    if isinstance(surface, ConstantHeight):
        return {"height": float(surface.value)}
    return {"dem": str(surface.path), "datum": surface.datum}


@dataclass(frozen=True)
class OrthoJob:
    """One tile of one orthoimage, as plain picklable data: a worker of a distributed engine
    (another process or machine, with this package importable and the files reachable at the
    same paths) runs it with :func:`run_job` and writes the tile to ``output`` (a GeoTIFF of
    the window's size, holding the tile's part of each overview level as its own overviews).

    scene: the scene model as scene JSON text; camera: its index; image: the raw image's path;
    grid: (CRS WKT, x0, y0, resolution m, cols, rows) of the whole output; window: (r0, r1, c0,
    c1) output rows and columns of the tile; surface: :func:`surface_description`; rows: (first,
    end) image rows of one scene of a strip or None; nodes: the planned exact image positions of
    the window (a ``Nodes``), so the tile is the threaded run's to the bit."""
    scene: str
    camera: int
    image: str
    grid: tuple
    window: tuple[int, int, int, int]
    surface: dict
    resampling: str
    nodata: float | None
    output: str
    rows: tuple[int, int] | None = None
    step: int = 32
    max_error: float = 0.01
    levels: tuple[int, ...] = ()
    nodes: Nodes | None = None


@lru_cache(maxsize=4)
def _job_mapper(scene_text: str, camera: int, grid: tuple, surface: str, rows: tuple | None) -> Mapper:
    """The mapper a worker builds once per orthoimage (scene JSON parsed, DEM opened)."""
    description = json.loads(surface)
    terrain = (ConstantHeight(description["height"]) if "height" in description
               else Dem(description["dem"], datum=description["datum"]))
    wkt, x0, y0, resolution, cols, n_rows = grid
    return Mapper(scene_from_dict(json.loads(scene_text)), camera, terrain,
                  OrthoGrid(CRS.from_wkt(wkt), x0, y0, resolution, cols, n_rows), rows)


def run_job(job: OrthoJob) -> MappingFigures:
    """Compute one tile (:class:`OrthoJob`) and write it to ``job.output``; returns what mapping
    its pixels measured."""
    mapper = _job_mapper(job.scene, job.camera, job.grid, json.dumps(job.surface, sort_keys=True), job.rows)
    src = open_input_raster(job.image)
    raw = RawImage(job.image, src, budget=0)  # read by window: a worker holds only its tiles' pixels
    levels = list(job.levels)
    fill = job.nodata if job.nodata is not None else 0.0
    blocks, overviews, figures = tile_blocks(mapper, raw, job.window, job.step, job.max_error, job.nodes,
                                         RESAMPLING[job.resampling], fill, levels, job.nodata)
    r0, r1, c0, c1 = job.window
    out = create_geotiff(job.output, c1 - c0, r1 - r0, raw.count, raw.data_type, levels, job.nodata, [])
    try:
        wkt, x0, y0, resolution, _, _ = job.grid
        out.SetGeoTransform((x0 + c0 * resolution, resolution, 0.0, y0 - r0 * resolution, 0.0, -resolution))
        out.SetProjection(wkt)
        write_tile([out.GetRasterBand(k + 1) for k in range(raw.count)], levels, (0, 0, 0, 0), blocks, overviews)
    finally:
        with closing_errors() as closing:
            out = None  # closes the tile, also after an error (a full disk): GDAL's error is kept, not printed
        raw.close()
    check_closed(job.output, closing)
    return figures


def connect_scheduler(scheduler: str):
    """A Dask distributed client of the scheduler at ``scheduler``; InputError naming SCHEDULER
    when Dask is missing or the scheduler does not answer."""
    try:
        from distributed import Client
    except ImportError:
        raise InputError(f"SCHEDULER: {scheduler} needs Dask distributed, which is not installed (Debian: "
                         "python3-distributed); leave SCHEDULER empty to use this machine's cores") from None
    try:
        return Client(scheduler, timeout=SCHEDULER_TIMEOUT, set_as_default=False)
    except (OSError, TimeoutError, ValueError, TypeError) as exc:
        raise InputError(f"SCHEDULER: cannot reach the Dask scheduler at {scheduler!r} within "
                         f"{SCHEDULER_TIMEOUT} s ({exc}); give its address, e.g. tcp://host:8786") from None


def map_on_scheduler(scheduler: str, function: Callable, jobs: list, report: Callable[[float], None],
                     cancelled: Callable[[], bool], what: str) -> list:
    """``function(job)`` of each of ``jobs`` on the Dask scheduler at ``scheduler``, the results in
    the jobs' order (``report`` gets the share done); Cancelled ('``what`` cancelled by the user')
    when ``cancelled()``."""
    from distributed import as_completed
    client = connect_scheduler(scheduler)
    try:
        futures = client.map(function, jobs, pure=False)
        for n, _ in enumerate(as_completed(futures, loop=client.loop)):
            if cancelled():
                client.cancel(futures)
                raise Cancelled(f"{what} cancelled by the user")
            report((n + 1) / len(jobs))
        return [future.result() for future in futures]
    finally:
        client.close()


def _run_jobs(scheduler: str, jobs: list[OrthoJob], report, cancelled) -> MappingFigures:
    """Run ``jobs`` on the Dask scheduler (``report`` gets the share done); returns their
    mapping figures merged."""
    figures = MappingFigures()
    for tile in map_on_scheduler(scheduler, run_job, jobs, report, cancelled, "orthorectification"):
        figures = figures.merge(tile)
    return figures


def _assemble(jobs: list[OrthoJob], out_bands, levels: list[int], folder: Path, report, cancelled) -> None:
    """Write the tiles of ``jobs`` into the output in tile order: bands through a VRT mosaic of
    the tile files (GDAL), overview parts from each tile's overviews."""
    mosaic = gdal.BuildVRT(str(folder / "tiles.vrt"), [job.output for job in jobs])  # the tiles cover the grid
    for n, job in enumerate(jobs):
        if cancelled():
            raise Cancelled("orthorectification cancelled by the user")
        r0, r1, c0, c1 = job.window
        tile = gdal.Open(job.output)
        blocks = [mosaic.GetRasterBand(k + 1).ReadAsArray(c0, r0, c1 - c0, r1 - r0)
                  for k in range(tile.RasterCount)]
        overviews = [[tile.GetRasterBand(k + 1).GetOverview(v).ReadAsArray() for v in range(len(levels))]
                     for k in range(tile.RasterCount)]
        tile = None
        write_tile(out_bands, levels, job.window, blocks, overviews)
        report((n + 1) / len(jobs))
    mosaic = None


def tiles_on_scheduler(scheduler: str, job: Callable[[tuple, str, list[int]], OrthoJob], output_path: Path,
                       windows: list[tuple[int, int, int, int]], out_bands, levels: list[int], report,
                       cancelled) -> MappingFigures:
    """The ``run_tiles`` of :func:`core.products.resampling.write_resampled` on a Dask scheduler:
    ``job(window, tile file, levels)`` for each window, run by the workers into a temporary folder
    beside ``output_path`` (removed afterwards), then assembled into ``out_bands`` in window
    order. Returns the tiles' mapping figures merged."""
    folder = Path(tempfile.mkdtemp(prefix=f".{output_path.name}.", suffix=".tiles", dir=output_path.parent))
    try:
        jobs = [job(w, str(folder / f"tile_{w[0]}_{w[2]}.tif"), levels) for w in windows]
        figures = _run_jobs(scheduler, jobs, lambda f: report(0.86 * f), cancelled)
        _assemble(jobs, out_bands, levels, folder, lambda f: report(0.86 + 0.14 * f), cancelled)
        return figures
    finally:
        shutil.rmtree(folder, ignore_errors=True)
