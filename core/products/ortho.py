"""Orthorectification of a raw pushbroom image with its rigorous scene model.

For every output pixel (a north-up grid in a projected CRS,
:class:`core.products.mapping.OrthoGrid`) the terrain height comes from the DEM (bilinear) and
the image position from the scene's ground -> image, evaluated on a node grid and densified
(:class:`core.products.mapping.Mapper`: checked per tile, CCD seams mapped pixel by pixel). The
raw image is then resampled (nearest, bilinear or cubic) at the image positions
(:mod:`core.products.resampling`).

Tiles are processed on a thread per core, or as jobs on a Dask scheduler
(:mod:`core.products.orthojobs`), and written to a tiled, compressed GeoTIFF with overviews,
completely or not at all (:class:`core.files.OutputSet`).
Coordinates: image positions in the GDAL convention (pixel centres at +0.5); output pixel
centres at the geotransform's +0.5.
"""
from __future__ import annotations

import json
import logging
import math
import time
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Callable

import numpy as np
from osgeo import gdal_array
from pyproj import CRS, Transformer

from ..dem import no_height_words, surface_name
from ..errors import InputError
from ..files import OutputSet, atomic_outputs, check_destination
from ..formats.scene_json import scene_to_dict
from ..geodesy import ecef_to_geodetic
from ..model.sensor import SceneModel
from ..validation import check_nodata
from .mapping import Mapper, OrthoGrid, utm_crs
from .orthojobs import OrthoJob, connect_scheduler, surface_description, tiles_on_scheduler
from .rawimage import RawImage, check_image_belongs, image_on_surface, open_raw
from .resampling import check_resampling, write_resampled

log = logging.getLogger(__name__)

PRODUCT_MARK = "PUSHBROOM_PRODUCT"  # metadata item naming the product an image is (not a DEM: core.measure.sources)
MAX_OUTPUT_PIXELS = 2e9  # per band: ~2 GB at 8 bits, more than any scene needs at its own GSD


def scene_utm_crs(scene: SceneModel, camera: int, surface) -> CRS:
    """The WGS84 UTM zone CRS of the image centre on the surface (the default output CRS)."""
    lon, lat, _ = ecef_to_geodetic(image_on_surface(scene, camera, surface, footprint=False))
    return utm_crs(float(lon[-1]), float(lat[-1]))


def default_grid(scene: SceneModel, camera: int, surface, crs: CRS | None = None,
                 resolution: float | None = None, extent: tuple | None = None,
                 rows: tuple[int, int] | None = None) -> OrthoGrid:
    """The grid covering the image's footprint on the surface (or ``extent`` = (xmin, ymin,
    xmax, ymax) in ``crs``), in ``crs`` (default: the UTM zone of the scene centre), at
    ``resolution`` m (default: the ground sample distance at the image centre). ``rows``:
    (first, end) image rows of one scene of a strip (default: the whole image)."""
    ground = image_on_surface(scene, camera, surface, footprint=extent is None, rows=rows)
    lon, lat, _ = ecef_to_geodetic(ground)
    crs = crs or utm_crs(float(lon[-1]), float(lat[-1]))
    x, y = Transformer.from_crs(CRS.from_epsg(4326), crs, always_xy=True).transform(lon, lat)
    if resolution is None:
        resolution = float(np.hypot(x[-1] - x[-2], y[-1] - y[-2]))
    if not resolution > 0:
        raise InputError(f"the output resolution must be positive (got {resolution})", parameter="resolution")
    xmin, ymin, xmax, ymax = extent or (np.min(x[:-2]), np.min(y[:-2]), np.max(x[:-2]), np.max(y[:-2]))
    if not (xmax > xmin and ymax > ymin):
        raise InputError(f"the extent {extent} is empty: it needs xmin < xmax and ymin < ymax")
    check_resolution(resolution, float(xmax - xmin), float(ymax - ymin))
    x0 = math.floor(xmin / resolution) * resolution
    y0 = math.ceil(ymax / resolution) * resolution
    cols, rows = int(math.ceil((xmax - x0) / resolution)), int(math.ceil((y0 - ymin) / resolution))
    return OrthoGrid(crs, x0, y0, resolution, cols, rows)


def check_resolution(resolution: float, width: float, height: float) -> None:
    """InputError (parameter 'resolution') for a pixel size (m) that gives a grid over ``width`` x
    ``height`` m (the footprint or extent) of more than MAX_OUTPUT_PIXELS, or under 2 pixels
    across its shorter side; the message gives the size the grid would have and the range."""
    finest = math.sqrt(width * height / MAX_OUTPUT_PIXELS)
    coarsest = min(width, height) / 2
    cols, rows = width / resolution, height / resolution
    if not finest <= resolution <= coarsest:  # also inf: never round sizes that no file can hold
        raise InputError(f"{resolution:g} m: the orthoimage would have {cols:.4g} x {rows:.4g} pixels over the "
                         f"{width / 1000:.4g} x {height / 1000:.4g} km it covers; give a pixel size from {finest:.3g} "
                         f"m ({MAX_OUTPUT_PIXELS:.0e} pixels) to {coarsest:.4g} m (2 pixels across), or another "
                         "extent", parameter="resolution")


def common_grid(grids: list[OrthoGrid]) -> OrthoGrid:
    """The part of ``grids`` (one CRS and resolution, e.g. :func:`default_grid` s of the images of
    a block, whose origins are multiples of the resolution) that all of them cover, on their pixel
    lattice: orthoimages of several images on it compare pixel by pixel. InputError when the
    grids differ in CRS or resolution or do not overlap."""
    first = grids[0]
    res = first.resolution
    if any(not g.crs.equals(first.crs) or g.resolution != res for g in grids):
        raise InputError("grids of different CRS or resolution have no common grid: give every image the same "
                         f"CRS and resolution (got {sorted({(g.crs.to_string(), g.resolution) for g in grids})})")
    x0, y0 = max(g.x0 for g in grids), min(g.y0 for g in grids)
    x1, y1 = min(g.x0 + g.cols * res for g in grids), max(g.y0 - g.rows * res for g in grids)
    cols, rows = math.floor((x1 - x0) / res + 1e-9), math.floor((y0 - y1) / res + 1e-9)
    if cols < 1 or rows < 1:
        raise InputError("the images' footprints do not overlap: no common grid")
    return OrthoGrid(first.crs, x0, y0, res, cols, rows)


def orthorectify(scene: SceneModel, image_path, surface, output_path, camera: int = 0, grid: OrthoGrid | None = None,
                 resampling: str = "bilinear", nodata: float | None = 0.0, tile: int = 512, step: int = 32,
                 max_error: float = 0.01, memory_budget: float = 2 ** 30,
                 progress: Callable[[float], None] | None = None,
                 is_cancelled: Callable[[], bool] | None = None, rows: tuple[int, int] | None = None,
                 scheduler: str | None = None, files: OutputSet | None = None) -> dict:
    """Orthorectify ``image_path`` (any GDAL raster, any bands and type, of the scene camera's
    size) onto ``grid`` (default :func:`default_grid`) and write a tiled, compressed GeoTIFF
    with overviews to ``output_path``. The raw image is held in memory when it takes at most
    ``memory_budget`` bytes, else read by window for each tile. ``rows``: (first, end) image
    rows of one scene of a strip (the rest is nodata). Tiles run on a thread per core, or with
    ``scheduler`` (a Dask distributed address, e.g. tcp://host:8786) as :class:`core.products.orthojobs.OrthoJob` s on
    its workers, which write tile files in a temporary folder beside the output that are then
    assembled here: the same bytes. With ``files`` the output joins that set (its owner commits
    it). Returns figures: grid, densification error (px; :class:`core.products.mapping.MappingFigures`:
    the largest error at the checks), the shares (%) of output pixels corrected for relief, refined and
    mapped exactly, the share (0..1) of the image's footprint in the output with no height and its
    pixels (those on the DEM's nodata holes), time."""
    t_start = time.perf_counter()
    check_resampling(resampling, tile, step)
    cam = scene.cameras[camera]
    src = open_raw(image_path, cam)
    if nodata is not None:
        check_nodata(nodata, gdal_array.GDALTypeCodeToNumericTypeCode(src.GetRasterBand(1).DataType))
    grid = grid or default_grid(scene, camera, surface, rows=rows)
    output_path = Path(output_path)
    check_destination(output_path)
    client = connect_scheduler(scheduler) if scheduler else None  # an unreachable scheduler stops before any work
    if client is not None:
        client.close()
    raw = RawImage(image_path, src, 0 if scheduler else memory_budget)  # workers read their own windows
    cancelled = is_cancelled or (lambda: False)
    report = progress or (lambda fraction: None)
    try:
        mapper = Mapper(scene, camera, surface, grid, rows)
        planned = mapper.nodes(0, grid.rows, 0, grid.cols, step, is_cancelled=cancelled)
        report(0.05)

        def georeference(out) -> None:
            out.SetGeoTransform(grid.geotransform())
            out.SetProjection(grid.crs.to_wkt())
            out.SetMetadataItem(PRODUCT_MARK, "orthoimage")

        run_tiles = None
        if scheduler:
            text = json.dumps(scene_to_dict(scene))
            plain_grid = (grid.crs.to_wkt(), grid.x0, grid.y0, grid.resolution, grid.cols, grid.rows)

            def job(window: tuple[int, int, int, int], output: str, levels: list[int]) -> OrthoJob:
                return OrthoJob(text, camera, str(image_path), plain_grid, window, surface_description(surface),
                                resampling, nodata, output, rows, step, max_error, tuple(levels),
                                planned.window(*window))

            run_tiles = partial(tiles_on_scheduler, scheduler, job, output_path)
        mapped = write_resampled(raw, mapper, planned, (grid.rows, grid.cols), output_path, resampling, nodata, tile,
                                max_error,
                                georeference=georeference, progress=lambda f: report(0.05 + 0.93 * f),
                                is_cancelled=cancelled, files=files, run_tiles=run_tiles)
    finally:
        raw.close()
    report(1.0)
    figures = {"cols": grid.cols, "rows": grid.rows, "resolution_m": grid.resolution, "crs": grid.crs.to_string(),
               "densification_error_px": mapped.error_px, "max_error_px": max_error,
               "relief_corrected_percent": mapped.share(mapped.relief), "refined_percent": mapped.share(mapped.refined),
               "exact_percent": mapped.share(mapped.exact), "mapping": mapped.sentence(max_error),
               "dem_gap_share": mapped.gap_share, "dem_gap_pixels": mapped.no_height, "dem_hole_pixels": mapped.holes,
               "footprint_pixels": mapped.footprint, "seconds": time.perf_counter() - t_start}
    log.info("orthoimage %d x %d at %.3f m in %.1f s; %s", grid.cols, grid.rows, grid.resolution, figures["seconds"],
             figures["mapping"])
    if mapped.no_height:
        log.warning(gap_sentence(surface, figures))
    return figures


def gap_sentence(surface, figures: dict) -> str:
    """The words for the output pixels of the image's footprint with no height (``figures`` of
    :func:`orthorectify`)."""
    holes = figures["dem_hole_pixels"]
    words = no_height_words(figures["dem_gap_pixels"] - holes, holes, figures["footprint_pixels"],
                            "output pixels of the image's footprint")
    return f"{surface_name(surface)} {words}, {100 * figures['dem_gap_share']:.1f} %: those pixels are nodata"


# --- every camera of a scene, every scene of a strip ------------------------------------------------
@dataclass(frozen=True)
class OrthoProduct:
    """One orthoimage of a multi-camera run: camera index, image rows (first, end) of its scene
    of the strip (None: the whole image) and the output file's name."""
    camera: int
    rows: tuple[int, int] | None
    name: str


def strip_products(scene: SceneModel, cameras: list[int]) -> list[OrthoProduct]:
    """The orthoimages of ``cameras``: one per camera (``ortho_<CAMERA>.tif``), or for a strip
    of n scenes (``info.n_scenes``, the scenes of one pass in one image per camera, equal row
    counts) one per camera and scene (``ortho_<CAMERA>_s<k>.tif``, k = 1..n along the pass)."""
    n = int(scene.info.get("n_scenes", 1) or 1)
    products = []
    for c in cameras:
        cam = scene.cameras[c]
        if n <= 1:
            products.append(OrthoProduct(c, None, f"ortho_{cam.name}.tif"))
            continue
        products += [OrthoProduct(c, (cam.rows * k // n, cam.rows * (k + 1) // n), f"ortho_{cam.name}_s{k + 1}.tif")
                     for k in range(n)]
    return products


def check_images(scene: SceneModel, images: dict[int, str]) -> None:
    """Refuse, before any work, a raw image that cannot be read, whose size is not its camera's, or whose own
    RPC puts it on ground the scene does not see there (:func:`core.products.rawimage.check_image_belongs`)
    (``images``: {camera index: path})."""
    for camera, path in images.items():
        open_raw(path, scene.cameras[camera])
        check_image_belongs(scene, camera, path)


def orthorectify_products(scene: SceneModel, images: dict[int, str], surface, folder, products: list[OrthoProduct],
                          grids: list[OrthoGrid], progress: Callable[[float], None] | None = None,
                          **options) -> list[dict]:
    """Orthorectify every product (:func:`strip_products`) onto its grid into ``folder``,
    completely or not at all: every orthoimage, or none when one fails or the user cancels.
    ``images``: {camera index: raw image path}; ``options``: those of :func:`orthorectify`.
    Progress runs over the whole run (weighted by each grid's pixels)."""
    items = [(scene, images[p.camera], Path(folder) / p.name, p.camera, p.rows) for p in products]
    with atomic_outputs() as files:
        return orthorectify_each(items, surface, grids, progress, files, **options)


def orthorectify_each(items: list[tuple], surface, grids: list[OrthoGrid], progress: Callable[[float], None] | None,
                      files: OutputSet, **options) -> list[dict]:
    """:func:`orthorectify` of every item (scene, raw image path, output path, camera index, rows
    (first, end) or None) on ``surface`` onto its grid, the outputs joining ``files`` (its owner commits them);
    progress over the whole (weighted by each grid's pixels)."""
    report = progress or (lambda fraction: None)
    weights = np.array([g.cols * g.rows for g in grids], dtype=float)
    starts = np.concatenate([[0.0], np.cumsum(weights)]) / weights.sum()
    return [orthorectify(scene, image, surface, output, camera, grid, rows=rows, files=files, **options,
                         progress=lambda f, a=starts[k], b=starts[k + 1]: report(a + (b - a) * f))
            for k, ((scene, image, output, camera, rows), grid) in enumerate(zip(items, grids))]
