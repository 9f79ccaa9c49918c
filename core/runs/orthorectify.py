"""pushbroom:orthorectify as a use case: a raw image resampled onto a map grid with the scene model
and the terrain, into a GeoTIFF; or every camera (and every scene of a strip) in one run, into a
folder. The outputs are planned and checked, the inputs read and checked, before any pixel."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np
from osgeo import ogr
from pyproj import CRS, Transformer

from ..dem import ConstantHeight
from ..errors import InputError
from ..log import LogLine
from ..products.footprint import footprints
from ..products.ortho import (check_images, default_grid, gap_sentence, orthorectify, orthorectify_products,
                              scene_utm_crs, strip_products)
from .base import IMAGES, FilesInUse, RunResult, Terrain, camera_images, camera_of, concerning, scene_from, surface_from

# The outputs (files of the result) and the inputs errors and log lines name, beside core.runs.base's.
OUTPUT, ORTHO_FOLDER, ORTHOIMAGES = "OUTPUT", "ORTHO_FOLDER", "ORTHOIMAGES"
IMAGE, EXTENT, DEM = "image", "extent", "dem"


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
    orthoimages may not replace."""
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


def run(request: OrthoRequest, progress: Callable[[float, str | None], None] | None = None,
        is_cancelled: Callable[[], bool] | None = None) -> RunResult:
    """Orthorectify as ``request`` says; files {OUTPUT} (one camera) or {ORTHO_FOLDER, ORTHOIMAGES}
    (every camera), figures those of :func:`core.products.ortho.orthorectify` (a list of them, one per
    orthoimage, for every camera)."""
    report = progress or (lambda fraction, message=None: None)
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
