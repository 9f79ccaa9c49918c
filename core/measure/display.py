"""Display copy of a raw image: the image in its own pixel frame, for digitising image lines.

A raw image carrying RPC or GCP metadata is warped by QGIS on display (to the RPC's or GCPs'
ground frame), and one without any is drawn in an unnamed frame; neither shows pixel
coordinates. The display copy is a VRT that references the raw image's bands (nothing is
copied or resampled) without its RPC and GCP metadata, with the pixel geotransform
(0, 1, 0, 0, 0, -1) — x = col, y = -row, GDAL convention: (0, 0) is the upper-left corner of
the upper-left pixel — and the engineering CRS of :func:`core.observations.lines.pixel_frame`, the frame of
the ``image_lines`` layers. The VRT's PUSHBROOM metadata domain names the scene file and the
camera, so that the digitising dock finds them again.

Each band of the copy carries the image's statistics (:func:`core.rasters.copy_statistics`): a
viewer that finds none computes them, and GDAL's VRT hands that work to the raw image's band,
which stores the result in a side file beside the raw image (``<image>.aux.xml``): a file written
beside an input. The docks keep their copies in a cache folder of their own
(:func:`cached_display_copy`), never beside the image.
"""
from __future__ import annotations

import hashlib
import logging
import os
import re
from dataclasses import dataclass
from pathlib import Path

from osgeo import gdal

from ..errors import InputError
from ..files import OutputSet, atomic_output
from ..observations.lines import ImageLines, pixel_frame, write_gpkg
from ..rasters import check_input_raster, copy_statistics, open_input_raster

gdal.UseExceptions()
log = logging.getLogger(__name__)

PIXEL_GEOTRANSFORM = (0.0, 1.0, 0.0, 0.0, 0.0, -1.0)  # x = col, y = -row
METADATA_DOMAIN = "PUSHBROOM"
DROPPED_DOMAINS = ("RPC", "GEOLOCATION")


@dataclass(frozen=True)
class DisplaySource:
    """What a display copy shows: the raw image (path, cols, rows), the scene file and the
    camera's name (from the VRT's PUSHBROOM metadata; '' when absent)."""
    image: str
    cols: int
    rows: int
    scene: str
    camera: str


def check_image_size(path, cols: int, rows: int, camera: str) -> None:
    """InputError unless the raster at ``path`` has the camera's (cols, rows): another image's
    pixels would put every digitised vertex at the wrong place."""
    got = check_input_raster(path)
    if got != (cols, rows):
        raise InputError(f"{path}: the image is {got[0]} x {got[1]} pixels but camera {camera} of the scene "
                         f"delivers {cols} x {rows}; give the raw image of that camera (not an orthoimage or "
                         "another scene's image)")


def write_display_vrt(image, output, scene: str = "", camera: str = "", files: OutputSet | None = None) -> None:
    """Write the display copy of raster ``image`` to ``output`` (.vrt), completely or not at all.

    The VRT references ``image`` by absolute path (it stays valid when moved) and keeps its bands,
    nodata and overviews; RPC, GEOLOCATION and GCPs are dropped. It carries the image's statistics
    (core.rasters.copy_statistics), so that QGIS, which computes those of a raster it loads, never
    computes them on the image and writes them beside it. ``scene`` and ``camera`` go to
    the PUSHBROOM metadata domain. The input is only read."""
    output = Path(output)
    if output.suffix.lower() != ".vrt":
        raise InputError(f"{output}: the display copy is a virtual raster; use a .vrt file name")
    source = os.path.abspath(str(image))
    check_input_raster(source)
    src = open_input_raster(source)
    with atomic_output(output, files) as tmp:
        ds = gdal.Translate(str(tmp), src, format="VRT")
        copy_statistics(src, ds)  # a viewer loading the copy finds them: none computed on the image, none beside it
        ds.SetGCPs([], "")
        for domain in DROPPED_DOMAINS:
            ds.SetMetadata({}, domain)
        ds.SetGeoTransform(PIXEL_GEOTRANSFORM)
        ds.SetSpatialRef(pixel_frame())
        ds.SetMetadata({"SCENE": os.path.abspath(scene) if scene else "", "CAMERA": camera,
                        "IMAGE": source}, METADATA_DOMAIN)
        ds.FlushCache()
        ds = None
        log.info("display copy of %s written to %s", source, output)


def cached_display_copy(image, scene: str, camera: str, cache) -> Path:
    """The display copy of raw ``image`` for ``scene``'s ``camera`` in folder ``cache`` (created),
    written when missing. Its name is the image's stem, the camera and a hash of the image's
    absolute path, size and modification time, the scene file and the camera: one image shown
    for several scenes or cameras gets a copy each, and a replaced image a new one."""
    source = Path(os.path.abspath(str(image)))
    check_input_raster(source)
    stat = source.stat()
    key = "|".join([str(source), str(stat.st_size), str(stat.st_mtime_ns), os.path.abspath(scene) if scene else "",
                    camera])
    digest = hashlib.sha256(key.encode()).hexdigest()[:12]
    path = Path(cache) / f"{source.stem}_{re.sub(r'[^A-Za-z0-9_.-]', '_', camera) or 'image'}_{digest}.vrt"
    if not path.is_file():
        path.parent.mkdir(parents=True, exist_ok=True)
        write_display_vrt(source, path, scene, camera)
    return path


def read_display_source(path) -> DisplaySource:
    """The raw image, scene and camera a display copy (or any raster) shows; for a raster
    that is not a display copy, the raster itself with no scene."""
    cols, rows = check_input_raster(path)
    ds = open_input_raster(path)
    meta = ds.GetMetadata(METADATA_DOMAIN) or {}
    return DisplaySource(meta.get("IMAGE", str(path)), cols, rows, meta.get("SCENE", ""), meta.get("CAMERA", ""))


def empty_image_lines() -> ImageLines:
    """No image lines: what an empty ``image_lines`` layer holds."""
    return ImageLines([], [], [0], [], [], 1.0)


def write_empty_lines(output, files: OutputSet | None = None) -> None:
    """A GeoPackage with an empty ``image_lines`` layer (:mod:`core.observations.lines`' format) to digitise in."""
    write_gpkg(output, image=empty_image_lines(), files=files)
