"""pushbroom:orthorectify as a use case: a raw image resampled onto a map grid with the scene model
and the terrain, into a GeoTIFF; or every camera (and every scene of a strip) in one run, into a
folder; or a block's products (SCENES) on one common grid with their VRT mosaic and the
co-registration of every overlap. The outputs are planned and checked, the inputs read and checked,
before any pixel."""
from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np
from osgeo import ogr
from pyproj import CRS, Transformer

from ..dem import ConstantHeight
from ..errors import InputError
from ..files import atomic_outputs
from ..log import LogLine
from ..measure.mosaiccheck import MISREGISTERED_PX, check_mosaic, misregistered
from ..products.footprint import footprints
from ..products.mosaic import (OFF_NADIR, block_grids, check_mosaic_bands, check_mosaic_order, mosaic_order,
                               off_nadir_deg, write_vrt)
from ..products.ortho import (check_images, default_grid, gap_sentence, orthorectify, orthorectify_each,
                              orthorectify_products, scene_utm_crs, strip_products)
from .base import IMAGES, FilesInUse, RunResult, Terrain, camera_images, camera_of, concerning, scene_from, surface_from
from .matchtiepoints import block_views
from .scenes import SCENES

# The outputs (files of the result) and the inputs errors and log lines name, beside core.runs.base's.
OUTPUT, ORTHO_FOLDER, ORTHOIMAGES, MOSAIC = "OUTPUT", "ORTHO_FOLDER", "ORTHOIMAGES", "MOSAIC"
IMAGE, EXTENT, DEM, MOSAIC_ORDER = "image", "extent", "dem", "mosaic_order"
MOSAIC_NAME = "mosaic.vrt"  # the block's mosaic in its folder, beside ortho_<scene>.tif


@dataclass(frozen=True)
class OrthoRequest:
    """One orthorectification. ``scene``: the scene file; ``output``: the GeoTIFF (.tif) of camera
    ``camera`` (a name or index, '' the first) from raw image ``image``, or with ``images`` (one raw
    image per camera of the scene, in its camera order) the folder of every camera's orthoimage
    (created when its parent exists). ``crs``: a projected CRS (None: the UTM zone of the scene's
    centre); ``resolution`` in its units (None: the ground sample distance at the image centre);
    ``extent``: (xmin, ymin, xmax, ymax) of the part to produce in a given CRS (the caller converts
    its extent, None: the whole footprint). ``resampling``, ``nodata``, ``scheduler``: those of
    :func:`core.products.ortho.orthorectify`. ``files``: the files around the run, which the
    orthoimages may not replace. ``scenes``: a block's scene files instead of ``scene`` (with
    ``images`` one raw image per scene, ``output`` the folder): every product on one common grid,
    the mosaic of them in ``mosaic_order`` (core.products.mosaic.MOSAIC_ORDERS) and the
    co-registration of every overlapping pair (:func:`run_block`)."""
    scene: str
    output: str
    terrain: Terrain = Terrain()
    image: str = ""
    camera: str = ""
    images: tuple[str, ...] | None = None
    crs: CRS | None = None
    resolution: float | None = None
    extent: Callable[[CRS], tuple] | None = None
    resampling: str = "bilinear"
    nodata: float = 0.0
    scheduler: str | None = None
    files: FilesInUse = field(default_factory=FilesInUse)
    scenes: tuple[str, ...] = ()
    mosaic_order: str = OFF_NADIR


def run(request: OrthoRequest, progress: Callable[[float, str | None], None] | None = None,
        is_cancelled: Callable[[], bool] | None = None) -> RunResult:
    """Orthorectify as ``request`` says; files {OUTPUT} (one camera) or {ORTHO_FOLDER, ORTHOIMAGES}
    (every camera), figures those of :func:`core.products.ortho.orthorectify` (a list of them, one per
    orthoimage, for every camera)."""
    report = progress or (lambda fraction, message=None: None)
    if request.scenes:
        return run_block(request, report, is_cancelled)
    if request.images is not None:
        return _every_camera(request, report, is_cancelled)
    if Path(request.output).suffix.lower() not in (".tif", ".tiff"):
        raise InputError(f"the orthoimage is written as GeoTIFF; use a .tif file (got {request.output})",
                         parameter=OUTPUT)
    request.files.check({OUTPUT: [request.output]})
    if not request.image:
        raise InputError("no raw image given (or set ALL_CAMERAS with INPUTS for every camera)", parameter=IMAGE)
    scene, lines = scene_from(request.scene)
    camera = camera_of(scene, request.camera)
    with concerning(IMAGE):
        check_images(scene, {camera: request.image})
    surface, more = surface_from(request.terrain, scene)
    lines += more
    crs, extent = _extent(request, scene, camera, surface, lines)
    report(0.0, "planning the output grid")
    grid = default_grid(scene, camera, surface, crs, request.resolution, extent)
    lines.append(LogLine(f"orthoimage {grid.cols} x {grid.rows} px at {grid.resolution:.3f} m in "
                         f"{grid.crs.to_string()}"))
    figures = orthorectify(scene, request.image, surface, request.output, camera, grid, progress=report,
                           is_cancelled=is_cancelled, **_options(request))
    return RunResult({OUTPUT: request.output}, figures, lines + written_lines(figures, surface))


def _every_camera(request: OrthoRequest, report, is_cancelled) -> RunResult:
    """Every camera (and scene of a strip) of the scene from ``request.images`` into the folder
    ``request.output``, created when its parent exists (and removed again, empty, on failure)."""
    folder = Path(request.output)
    if folder.is_file():
        raise InputError(f"{folder} is a file, not a folder; give a folder for the orthoimages (created when its "
                         "parent exists)", parameter=ORTHO_FOLDER)
    scene, lines = scene_from(request.scene)
    images = camera_images(scene, request.images)
    products = strip_products(scene, list(images))
    made = not folder.exists() and folder.parent.is_dir()
    if made:
        folder.mkdir()
    try:
        return _write_products(request, scene, images, products, folder, lines, report, is_cancelled)
    except BaseException:
        if made and not any(folder.iterdir()):
            folder.rmdir()
        raise


def _write_products(request: OrthoRequest, scene, images: dict, products: list, folder: Path, lines: list,
                    report, is_cancelled) -> RunResult:
    outputs = [folder / p.name for p in products]
    request.files.check({ORTHO_FOLDER: outputs})
    with concerning(IMAGES):
        check_images(scene, images)
    lines += [LogLine(f"camera {scene.cameras[k].name}: {image}") for k, image in images.items()]
    surface, _ = surface_from(request.terrain)
    report(0.0, "planning the output grids")
    crs, extent = _extent(request, scene, products[0].camera, surface, lines)
    grids = []
    for product in products:
        grids.append(default_grid(scene, product.camera, surface, crs, request.resolution, extent, product.rows))
        g = grids[-1]
        lines.append(LogLine(f"{product.name}: {g.cols} x {g.rows} px at {g.resolution:.3f} m in "
                             f"{g.crs.to_string()}"))
    figures = orthorectify_products(scene, images, surface, folder, products, grids, progress=report,
                                    is_cancelled=is_cancelled, **_options(request))
    for product, fig in zip(products, figures):
        lines += written_lines(fig, surface, f"{product.name}: ")
    return RunResult({ORTHO_FOLDER: str(folder), ORTHOIMAGES: [str(p) for p in outputs]}, figures, lines)


def run_block(request: OrthoRequest, report, is_cancelled) -> RunResult:
    """A block's products (``request.scenes``, one raw image each in ``request.images``) orthorectified
    into the folder ``request.output`` (created when its parent exists) on one common grid
    (:func:`core.products.mosaic.block_grids`), the VRT mosaic of them and the co-registration of every
    overlapping pair (:func:`core.measure.mosaiccheck.check_mosaic`): all written, or none. Files
    {ORTHO_FOLDER, ORTHOIMAGES (in the order of the scenes), MOSAIC}; figures {orthoimages: each one's
    figures of :func:`core.products.ortho.orthorectify`, off_nadir_deg: {scene: angle}, mosaic_order:
    the scenes from the mosaic's bottom to its top, coregistration: each pair's
    :class:`core.measure.mosaiccheck.PairCoregistration` as a dict}."""
    check_mosaic_order(request.mosaic_order)
    if request.extent is not None:
        raise InputError("EXTENT is for one scene; a block's orthoimages each cover their own footprint",
                         parameter=EXTENT)
    views, lines, _ = block_views(request.scenes, request.images or ())
    check_mosaic_bands({v.scene_name: v.image for v in views})
    folder = Path(request.output)
    if folder.is_file():
        raise InputError(f"{folder} is a file, not a folder; give a folder for the orthoimages and the mosaic "
                         "(created when its parent exists)", parameter=ORTHO_FOLDER)
    made = not folder.exists() and folder.parent.is_dir()
    if made:
        folder.mkdir()
    try:
        return _block_in(request, views, folder, lines, report, is_cancelled)
    except BaseException:
        if made and not any(folder.iterdir()):
            folder.rmdir()
        raise


def _block_in(request: OrthoRequest, views: list, folder: Path, lines: list, report, is_cancelled) -> RunResult:
    """:func:`run_block` once its folder exists."""
    outputs = {v.scene_name: folder / f"ortho_{v.scene_name}.tif" for v in views}
    request.files.check({ORTHO_FOLDER: [*outputs.values(), folder / MOSAIC_NAME]})
    surface, more = surface_from(request.terrain, views[0].scene)
    lines += more
    report(0.0, "planning the common grid")
    grids = block_grids([(v.scene, v.camera) for v in views], surface, request.crs, request.resolution)
    g = grids[0]
    lines.append(LogLine(f"common grid: {g.resolution:.3f} m pixels in {g.crs.to_string()}, origins on multiples of "
                         "the pixel size"))
    angles = {v.scene_name: off_nadir_deg(v.scene, v.camera, surface) for v in views}
    order = [views[k].scene_name for k in mosaic_order(list(angles), list(angles.values()), request.mosaic_order)]
    figures, checks = _write_block(request, views, grids, outputs, order, surface, report, is_cancelled)
    for v, grid, fig in zip(views, grids, figures):
        lines.append(LogLine(f"{v.scene_name}: {grid.cols} x {grid.rows} px, off-nadir {angles[v.scene_name]:.1f} deg"))
        lines += written_lines(fig, surface, f"{v.scene_name}: ")
    lines.append(LogLine(f"mosaic {folder / MOSAIC_NAME}, from bottom to top: {', '.join(order)}"))
    lines += coregistration_lines(checks)
    return RunResult({ORTHO_FOLDER: str(folder), ORTHOIMAGES: [str(p) for p in outputs.values()],
                      MOSAIC: str(folder / MOSAIC_NAME)},
                     {"orthoimages": figures, "off_nadir_deg": angles, "mosaic_order": order,
                      "coregistration": [asdict(c) for c in checks]}, lines)


def _write_block(request: OrthoRequest, views: list, grids: list, outputs: dict, order: list, surface, report,
                 is_cancelled) -> tuple[list, list]:
    """(each orthoimage's figures, each overlapping pair's co-registration): the orthoimages and the
    mosaic written together, or nothing."""
    items = [(v.scene, str(v.image), outputs[v.scene_name], v.camera, None) for v in views]
    with atomic_outputs() as files:
        figures = orthorectify_each(items, surface, grids, lambda f: report(0.9 * f), files,
                                    is_cancelled=is_cancelled, **_options(request))
        written = {name: files.path(path) for name, path in outputs.items()}
        write_vrt(files.path(Path(request.output) / MOSAIC_NAME), [written[name] for name in order], request.nodata)
        report(0.9, "co-registration of the overlaps")
        checks = check_mosaic(written)
    return figures, checks


def coregistration_lines(checks: list) -> list[LogLine]:
    """The log of the mosaic's co-registration check: one line per overlapping pair, a warning naming
    the pairs that do not co-register (or that no window measured)."""
    if not checks:
        return [LogLine("co-registration: no two orthoimages overlap", True, SCENES)]
    lines = [LogLine(f"co-registration of the {len(checks)} overlapping pairs (phase correlation on windows of each "
                     "overlap; shifts of the second against the first, px):")]
    lines += [LogLine(c.sentence) for c in checks]
    bad = misregistered(checks)
    if bad:
        lines.append(LogLine(f"{len(bad)} of {len(checks)} overlapping pairs do not co-register within "
                             f"{MISREGISTERED_PX} px RMS or could not be measured: "
                             f"{', '.join(f'{c.first} - {c.second}' for c in bad)}; adjust the block "
                             "(pushbroom:bundleadjust with SCENES) and orthorectify with the adjusted scenes",
                             True, SCENES))
    return lines


def _options(request: OrthoRequest) -> dict:
    """Resampling, nodata and scheduler for core.products.ortho.orthorectify."""
    return {"resampling": request.resampling, "nodata": request.nodata, "scheduler": request.scheduler}


def written_lines(figures: dict, surface, name: str = "") -> list[LogLine]:
    """The log of one orthoimage written (``name``: its name and ': ', '' for the only one): time and
    mapping, and the footprint's pixels without height."""
    lines = [LogLine(f"{name}written in {figures['seconds']:.1f} s; {figures['mapping']}")]
    if figures["dem_gap_pixels"]:
        lines.append(LogLine(f"{name}{gap_sentence(surface, figures)}", True, DEM))
    return lines


def _extent(request: OrthoRequest, scene, camera: int, surface, lines: list) -> tuple:
    """(output CRS or None, extent in it or None): the extent needs its CRS first (the request's, else
    the UTM zone of ``camera``'s centre); checked against the image's footprint."""
    if request.extent is None:
        return request.crs, None
    crs = request.crs or scene_utm_crs(scene, camera, surface)
    extent = tuple(float(v) for v in request.extent(crs))
    lines += extent_lines(scene, camera, surface, crs, extent)
    return crs, extent


def extent_lines(scene, camera: int, surface, crs: CRS, extent: tuple) -> list[LogLine]:
    """Refuse an ``extent`` (xmin, ymin, xmax, ymax in ``crs``) that misses the image's footprint
    (traced at the terrain's mean height); a warning line with the share of it outside."""
    xmin, ymin, xmax, ymax = min(extent[0], extent[2]), min(extent[1], extent[3]), \
        max(extent[0], extent[2]), max(extent[1], extent[3])
    box = _polygon([xmin, xmax, xmax, xmin], [ymin, ymin, ymax, ymax])
    if not box.Area() > 0:
        raise InputError(f"the extent {extent} is empty", parameter=EXTENT)
    flat = ConstantHeight(float(np.mean(surface.height_range)))
    (outline,) = footprints(scene, flat, cameras=[camera], samples_per_edge=32)
    x, y = Transformer.from_crs(CRS.from_epsg(4326), crs, always_xy=True).transform(outline.lon, outline.lat)
    footprint = _polygon(x, y)
    share = footprint.Intersection(box).Area() / box.Area()
    if share <= 0:
        west, east, south, north = footprint.GetEnvelope()
        raise InputError(f"the extent does not overlap the image's footprint ({west:.0f},{south:.0f} : "
                         f"{east:.0f},{north:.0f} in {crs.to_string()})", parameter=EXTENT)
    if share < 0.999:
        return [LogLine(f"{100 * (1 - share):.1f} % of the extent lies outside the image's footprint; those pixels "
                        "are nodata", True, EXTENT)]
    return []


def _polygon(x, y) -> ogr.Geometry:
    """An OGR polygon of the ring through points (x, y), closed."""
    ring = ogr.Geometry(ogr.wkbLinearRing)
    for a, b in zip(x, y):
        ring.AddPoint_2D(float(a), float(b))
    ring.CloseRings()
    polygon = ogr.Geometry(ogr.wkbPolygon)
    polygon.AddGeometry(ring)
    return polygon
