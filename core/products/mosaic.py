"""The orthomosaic of a block: every product's orthoimage on one pixel lattice and a GDAL VRT of them.

One common grid: every product's orthoimage is in one CRS at one pixel size, its origin a multiple
of the pixel size (:func:`core.products.ortho.default_grid` snaps it so), so the pixels of any two
orthoimages coincide exactly where they overlap and each covers only its own footprint
(:func:`block_grids`). The mosaic is a VRT (``gdal.BuildVRT``) listing the orthoimages, each
source's nodata left transparent; in a VRT the last source listed is drawn on top, so the order
is bottom to top (:func:`mosaic_order`: by default the least off-nadir product on top, the one that
hides least ground behind relief). The off-nadir angle of a product (:func:`off_nadir_deg`) is its
line of sight's angle from the local vertical (ellipsoid normal) at the image centre's ground point,
from the product's own model (rigorous or RPC) between two heights: what the ground sees, a little
more than the angle at the satellite (Earth's curvature: 18.0 degrees at the satellite of a 500 km
orbit is 19.1 at the ground).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from osgeo import gdal

from ..errors import InputError
from ..files import OutputError
from ..geodesy import ecef_to_geodetic, up_vector
from ..rasters import open_input_raster
from .mapping import OrthoGrid
from .ortho import default_grid, scene_utm_crs

gdal.UseExceptions()

# MOSAIC_ORDER's values: the least off-nadir product on top, or the order products are given in
# (the first on top)
OFF_NADIR, GIVEN = "off_nadir", "given"
MOSAIC_ORDERS = (OFF_NADIR, GIVEN)
RAY_SPAN_M = 1000.0  # height span (m) over which a product's line of sight is traced


def off_nadir_deg(scene, camera: int, surface) -> float:
    """The off-nadir angle (degrees) of camera ``camera`` of ``scene`` at its image centre: the
    angle between its line of sight (the ground points of the centre pixel at the surface's mean
    height and RAY_SPAN_M above) and the ellipsoid normal there."""
    cam = scene.cameras[camera]
    h = float(np.mean(surface.height_range))
    ground = scene.image_to_ground(np.full(2, cam.cols / 2), np.full(2, cam.rows / 2), np.array([h, h + RAY_SPAN_M]),
                                   camera)
    ray = ground[1] - ground[0]
    lon, lat, _ = ecef_to_geodetic(ground[:1])
    cosine = float(np.dot(ray, up_vector(lon[0], lat[0])) / np.linalg.norm(ray))
    if not np.isfinite(cosine):
        raise InputError(f"camera {cam.name}: its image centre's line of sight misses the ground")
    return math.degrees(math.acos(min(1.0, abs(cosine))))


def mosaic_order(names: list[str], off_nadir: list[float], order: str = OFF_NADIR) -> list[int]:
    """Indices into ``names`` from the bottom of the mosaic to its top (the VRT's source order):
    OFF_NADIR puts the least off-nadir on top (ties: the earlier name above), GIVEN the first
    name on top."""
    check_mosaic_order(order)
    if order == GIVEN:
        return list(range(len(names)))[::-1]
    return sorted(range(len(names)), key=lambda k: (-off_nadir[k], -k))


def check_mosaic_order(order: str) -> None:
    """InputError (mosaic_order) for an order not in MOSAIC_ORDERS."""
    if order not in MOSAIC_ORDERS:
        raise InputError(f"unknown mosaic order {order!r}: one of {', '.join(MOSAIC_ORDERS)}", parameter="mosaic_order")


def block_grids(products: list[tuple], surface, crs=None, resolution: float | None = None) -> list[OrthoGrid]:
    """One grid per product (``products``: (scene, camera) pairs), each covering that product's
    footprint on ``surface``, all in one CRS (default: the UTM zone of the first product's centre)
    at one pixel size (default: the coarsest of the products' ground sample distances at their
    centres, so that no product is magnified) with origins on one lattice (multiples of the pixel
    size): pixels of any two of them coincide."""
    crs = crs or scene_utm_crs(products[0][0], products[0][1], surface)
    size = resolution or max(default_grid(scene, camera, surface, crs).resolution for scene, camera in products)
    return [default_grid(scene, camera, surface, crs, size) for scene, camera in products]


def write_vrt(path, sources: list, nodata: float | None) -> None:
    """The VRT ``path`` of the raster files ``sources`` (one grid lattice, same bands), drawn from
    the first (bottom) to the last (top), each source's ``nodata`` transparent. Sources in the
    VRT's folder are referenced relative to it (the folder can be moved whole)."""
    options = gdal.BuildVRTOptions(srcNodata=nodata, VRTNodata=nodata, resolution="highest")
    vrt = gdal.BuildVRT(str(path), [str(s) for s in sources], options=options)
    if vrt is None:
        raise OutputError(f"cannot build the mosaic {path}: {gdal.GetLastErrorMsg()}")
    vrt.FlushCache()
    vrt = None
    if not Path(path).is_file():
        raise OutputError(f"cannot write the mosaic {path}")


def check_mosaic_bands(images: dict) -> None:
    """InputError (images) when the raw images ``images`` ({name: file}) differ in band count or
    data type: a VRT takes its bands from the first source and would drop or convert the others."""
    kinds = {}
    for name, path in images.items():
        ds = open_input_raster(path)
        kinds[name] = (ds.RasterCount, gdal.GetDataTypeName(ds.GetRasterBand(1).DataType))
    if len(set(kinds.values())) > 1:
        listed = ", ".join(f"{name} {count} x {kind}" for name, (count, kind) in kinds.items())
        raise InputError(f"the images differ in bands or data type ({listed}), and one mosaic needs one band count "
                         "and data type: mosaic them in groups of one kind, or convert them first "
                         "(gdal_translate -ot, -b)", parameter="images")
