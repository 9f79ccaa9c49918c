"""What the measuring docks open: a scene (any file :func:`core.formats.load_scene` reads) and the
raw image of one of its cameras, found beside the scene file and shown through a display copy kept
in a cache folder (:func:`open_image_source`), and whether a raster can serve as a DEM.

A DEM guessed wrongly gives every point a wrong height without a word (an orthoimage's grey
values read as metres), so a raster is offered as a DEM only when it looks like elevation: one
band of floating point or 16-bit integers, and not an image this plugin made or reads (a raw
image, a display copy, a reference or orthoimage: their metadata name them; an image with RPC
metadata).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from osgeo import gdal

from ..errors import InputError, MetadataError
from ..formats import load_scene
from ..products.ortho import PRODUCT_MARK
from ..rasters import check_input_raster
from .display import METADATA_DOMAIN, cached_display_copy, check_image_size, read_display_source

gdal.UseExceptions()

RASTER_SUFFIXES = (".tif", ".tiff", ".jp2", ".ntf", ".til", ".img", ".vrt")
MAX_CANDIDATES_READ = 50  # rasters beside a scene file whose size is read: a folder of thousands is not scanned
ELEVATION_TYPES = (gdal.GDT_Float32, gdal.GDT_Float64, gdal.GDT_Int16, gdal.GDT_UInt16)
IMAGE_MARKS = ("PUSHBROOM_CAMERA", "PUSHBROOM_REFERENCE", PRODUCT_MARK)
"""Metadata items (default domain) of the plugin's images: the simulator's raw images and reference
orthoimage, orthorectify's products."""


@dataclass(frozen=True)
class ImageSource:
    """A raw image opened for measuring: its scene file ('' for an image without one), the scene
    model (None without), the camera's index and name, the raw image and the display copy that
    shows it."""
    scene_path: str
    scene: object = field(repr=False)
    camera: int
    camera_name: str
    image: Path
    display: Path


def open_image_source(path, cache, image=None, camera: str | int | None = None,
                      require_scene: bool = True) -> ImageSource:
    """Open what a user has: a scene file (scene JSON, DIMAP, Maxar XML, an RPC file or an image
    with RPC metadata) with the raw image ``image`` of its camera ``camera`` (name or index; the
    first when None; when ``image`` is None the one :func:`raw_image_candidates` proposes), or a
    display copy, which names all three. The display copy shown is always one of folder ``cache``
    (made when missing, :func:`core.measure.display.cached_display_copy`), never beside the image.
    A raster with no scene (neither a display copy naming one nor an RPC image) is opened alone
    unless ``require_scene``. InputError/MetadataError naming the file: a scene that cannot be
    read, a camera it lacks, an image of another size than the camera's."""
    path = Path(path)
    try:
        shown = read_display_source(path)
    except InputError:
        shown = None  # not a raster: a scene file
    scene_path, scene = str(path), None
    if shown is not None and (Path(shown.image) != path or shown.scene):  # a display copy
        scene_path, image, camera = shown.scene, shown.image, camera if camera is not None else shown.camera
    elif shown is not None:  # a raster: an image with RPC metadata is its own scene
        scene = scene_of_raster(path)
        if scene is None:
            scene_path, image = "", path
    if not scene_path:
        if require_scene:
            raise InputError(f"{path}: names no scene file (an image without RPC metadata, not a display copy); "
                             "give the scene (scene JSON, DIMAP, Maxar XML or RPC file) with this image as its raw "
                             "image")
        return ImageSource("", None, 0, "", Path(image), cached_display_copy(image, "", "", cache))
    scene = scene or load_scene(scene_path)
    try:
        index = scene.camera_index(camera if camera not in (None, "") else 0)
    except InputError as exc:
        raise InputError(f"{scene_path}: {exc}") from None
    cam = scene.cameras[index]
    if image is None:
        found = raw_image_candidates(scene_path, cam.cols, cam.rows, cam.name, scene.info.get("image"))
        if not found:
            raise InputError(f"{scene_path}: no raster of camera {cam.name}'s size ({cam.cols} x {cam.rows} px) "
                             "beside the scene file; give its raw image")
        image = found[0]
    check_image_size(image, cam.cols, cam.rows, cam.name)
    return ImageSource(str(scene_path), scene, index, cam.name, Path(image),
                       cached_display_copy(image, str(scene_path), cam.name, cache))


def scene_of_raster(path: Path):
    """The RPC scene of a raster with RPC metadata, None for one without."""
    try:
        return load_scene(path)
    except (InputError, MetadataError):
        return None


def raw_image_candidates(scene_path, cols: int, rows: int, camera: str, image_hint: str | None = None) -> list[Path]:
    """Raster files that can hold the raw image of a camera of ``cols`` x ``rows`` px whose scene
    is the file ``scene_path``, best first: ``image_hint`` (the image an RPC file names), the scene
    file itself (an image with RPC metadata), then rasters in its folder of that size, those
    whose name holds ``camera`` first. A display copy stands for the raw image it shows."""
    scene_path = Path(scene_path)
    beside = sorted(p for p in scene_path.parent.iterdir() if p.suffix.lower() in RASTER_SUFFIXES and p.is_file())
    beside.sort(key=lambda p: camera.lower() not in p.stem.lower())
    found = []
    hinted = [Path(image_hint)] if image_hint else []
    for path in hinted + [scene_path] + beside[:MAX_CANDIDATES_READ]:
        try:
            image = Path(read_display_source(path).image)
            fits = check_input_raster(image) == (cols, rows)
        except (InputError, OSError):
            continue
        if fits and image not in found:
            found.append(image)
    return found


def elevation_problem(path) -> str:
    """Why the raster at ``path`` cannot be a DEM ('' when it can): more than one band, a data
    type heights are not stored in (8-bit, 32-bit integers, complex), or one of this plugin's
    images (IMAGE_MARKS, a display copy) or any image with RPC metadata (a raw or sensor-corrected
    image)."""
    try:
        ds = gdal.Open(str(path))
    except RuntimeError as exc:
        return f"not a raster GDAL reads ({exc})"
    if ds.RasterCount != 1:
        return f"{ds.RasterCount} bands (a DEM has one)"
    data_type = ds.GetRasterBand(1).DataType
    if data_type not in ELEVATION_TYPES:
        return f"{gdal.GetDataTypeName(data_type)} values (a DEM holds floating point or 16-bit heights)"
    marks = [k for k in IMAGE_MARKS if ds.GetMetadataItem(k)]
    marks += ["display copy"] * bool(ds.GetMetadata(METADATA_DOMAIN)) + ["RPC metadata"] * bool(ds.GetMetadata("RPC"))
    if marks:
        return f"an image, not heights ({', '.join(marks)})"
    return ""
