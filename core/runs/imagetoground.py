"""pushbroom:imagetoground as a use case: the ground points (lon, lat, ellipsoidal h) the lines of
sight of image points (col, row) of one camera meet on the terrain."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..dem import ConstantHeight, no_height_words, surface_name
from ..errors import Cancelled, InputError
from ..geodesy import ecef_to_geodetic
from ..log import LogLine
from ..products.footprint import rays_without_height
from .base import DEM, FilesInUse, RunResult, Terrain, camera_of, nonfinite_text, scene_from, surface_from

POINTS = "points"  # the input the image points come from, as errors name it


@dataclass(frozen=True)
class ImageToGroundRequest:
    """Image points ``col``, ``row`` (n,) GDAL px of camera ``camera`` (a name or index, '' the first)
    of the scene file ``scene`` (NaN: a missing or non-numeric value), ``ids`` (n,) the features they
    come from and ``fields`` the names of their col and row fields, for the refusals; heights from
    ``terrain``. ``files``: the files around the run (the outputs are checked first)."""
    scene: str
    col: np.ndarray
    row: np.ndarray
    ids: np.ndarray
    fields: tuple[str, str] = ("col", "row")
    terrain: Terrain = Terrain()
    camera: str = ""
    files: FilesInUse = field(default_factory=FilesInUse)


def run(request: ImageToGroundRequest, progress: Callable[[float, str | None], None] | None = None,
        is_cancelled: Callable[[], bool] | None = None) -> RunResult:
    """Figures {'kept': mask (n,) of the points with a ground point, 'lon', 'lat' (deg), 'h' (m,
    ellipsoidal) (k,) of those}; no files (the caller writes the points). Points whose lines of sight
    meet the DEM only on its nodata holes are left out with a warning line; lines of sight that leave
    the DEM or miss the Earth are refused, naming the features."""
    report = progress or (lambda fraction, message=None: None)
    request.files.check({})
    scene, lines = scene_from(request.scene)
    camera = camera_of(scene, request.camera)
    col, row = np.asarray(request.col, dtype=float), np.asarray(request.row, dtype=float)
    bad = ~(np.isfinite(col) & np.isfinite(row))
    if bad.any():
        raise InputError(nonfinite_text(f"{request.fields[0]}/{request.fields[1]} values", request.ids, bad),
                         parameter=POINTS)
    surface, more = surface_from(request.terrain, scene)
    lines += more
    if is_cancelled is not None and is_cancelled():
        raise Cancelled("cancelled by the user")
    cam = scene.cameras[camera]
    outside = ~cam.in_image(col, row)
    if outside.any():
        lines.append(LogLine(f"{int(outside.sum())} points lie outside the image of camera {cam.name} "
                             f"({cam.cols} x {cam.rows} px); their lines of sight are extrapolated", True))
    report(0.0, f"intersecting {col.size} lines of sight with the terrain")
    if isinstance(surface, ConstantHeight):
        xyz = scene.image_to_ground(col, row, surface.value, camera)
    else:
        xyz = scene.image_to_ground_dem(col, row, surface, camera)
    missed = ~np.all(np.isfinite(xyz), axis=1)
    if missed.any():
        lines.append(_missed(scene, camera, col, row, surface, np.asarray(request.ids), missed, request.terrain))
    lon, lat, h = ecef_to_geodetic(xyz[~missed])
    report(1.0)
    return RunResult({}, {"kept": ~missed, "lon": lon, "lat": lat, "h": h}, lines)


def _missed(scene, camera: int, col, row, surface, ids, missed, terrain: Terrain) -> LogLine:
    """Points whose lines of sight met no height: a warning that counts them when they meet the DEM
    only on its nodata holes; else refused, naming the DEM and why."""
    lost = [str(i) for i in ids[missed]]
    named = ", ".join(lost[:5]) + (", ..." if len(lost) > 5 else "")
    if isinstance(surface, ConstantHeight):
        raise InputError(f"the lines of sight of {int(missed.sum())} points miss the Earth; feature ids {named}",
                         parameter=DEM)
    off, hole = rays_without_height(scene, camera, col[missed], row[missed], surface)
    words = no_height_words(int(missed.sum() - hole.sum()), int(hole.sum()), missed.size, "points")
    if not hole.all() or missed.all():
        raise InputError(f"{terrain.dem_name}: {surface_name(surface)} {words}: their lines of sight leave it (it "
                         f"does not cover them); feature ids {named}", parameter=DEM)
    return LogLine(f"{surface_name(surface)} {words}: their lines of sight meet it only there; those points are left "
                   f"out (feature ids {named})", True, DEM)
