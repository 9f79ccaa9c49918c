"""pushbroom:groundtoimage as a use case: the image coordinates (col, row) of ground points in one
camera of a scene, their heights from their Z values, the DEM or a constant height."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from pyproj import CRS

from ..errors import Cancelled, InputError
from ..geodesy import geodetic_to_ecef
from ..log import LogLine
from ..observations.tables import point_heights
from .base import (FilesInUse, RunResult, Terrain, camera_of, concerning, lonlat_from, nonfinite_text, scene_from,
                   surface_from, z_datum_of)

# The inputs errors name, beside core.runs.base's; the points' layer and the Z options are named in the
# sentences by the provider's parameters (INPUT, USE_Z, Z_DATUM), which they tell the user to change.
POINTS, Z_DATUM = "points", "z_datum"


@dataclass(frozen=True)
class GroundToImageRequest:
    """Ground points ``x``, ``y``, ``z`` (n,) in ``crs`` (called ``crs_name`` in messages; NaN: no value)
    of the features ``ids`` (n,), projected into camera ``camera`` (a name or index, '' the first) of the
    scene file ``scene``. Heights: a point's Z in ``z_datum`` ('geoid', 'ellipsoid'; None: what ``crs``
    says) when ``use_z`` and it has one, else the terrain's. ``files``: the files around the run."""
    scene: str
    x: np.ndarray
    y: np.ndarray
    z: np.ndarray
    ids: np.ndarray
    crs: CRS
    crs_name: str = ""
    use_z: bool = True
    z_datum: str | None = None
    terrain: Terrain = Terrain()
    camera: str = ""
    files: FilesInUse = field(default_factory=FilesInUse)


def run(request: GroundToImageRequest, progress: Callable[[float, str | None], None] | None = None,
        is_cancelled: Callable[[], bool] | None = None) -> RunResult:
    """Figures {'col', 'row' (n,) GDAL px (NaN where a point does not project), 'inside' (n,) bool: in
    the camera's image}; no files (the caller writes the points); a warning line for points outside."""
    report = progress or (lambda fraction, message=None: None)
    request.files.check({})
    scene, lines = scene_from(request.scene)
    camera = camera_of(scene, request.camera)
    lon, lat, h = _ground(request, scene, lines)
    if is_cancelled is not None and is_cancelled():
        raise Cancelled("cancelled by the user")
    cam = scene.cameras[camera]
    report(0.0, f"projecting {lon.size} points into camera {cam.name}")
    col, row = scene.ground_to_image(geodetic_to_ecef(lon, lat, h), camera)
    inside = cam.in_image(col, row)
    if (~inside).any():
        lines.append(LogLine(f"{int((~inside).sum())} of {lon.size} points fall outside the image of camera "
                             f"{cam.name} ({cam.cols} x {cam.rows} px); they are kept with in_image = 0", True))
    report(1.0)
    return RunResult({}, {"col": col, "row": row, "inside": inside}, lines)


def _ground(request: GroundToImageRequest, scene, lines: list) -> tuple:
    """(lon, lat, ellipsoidal height) of the request's points, checked for NaN, conversion and
    coverage; the terrain is read only when a point takes its height from it (its lines to ``lines``)."""
    ids = np.asarray(request.ids)
    x, y, z = (np.asarray(v, dtype=float) for v in (request.x, request.y, request.z))
    bad = ~(np.isfinite(x) & np.isfinite(y))
    if bad.any():
        raise InputError(nonfinite_text("point coordinates", ids, bad), parameter=POINTS)
    with concerning(POINTS):
        lon, lat = lonlat_from(request.crs, x, y, request.crs_name)
    use_z = request.use_z & np.isfinite(z)
    datum = None
    if use_z.any():
        datum = request.z_datum or z_datum_of(request.crs)
        if datum is None:
            raise InputError(f"{int(use_z.sum())} points have Z values and the layer's CRS ({request.crs_name}) does "
                             "not say what they are measured from: give Z_DATUM=geoid or Z_DATUM=ellipsoid (or "
                             "USE_Z=false to take heights from the DEM or HEIGHT)", parameter=Z_DATUM)

    def terrain():
        surface, more = surface_from(request.terrain, scene)
        lines.extend(more)
        return surface
    h = point_heights(lon, lat, np.where(use_z, z, np.nan), datum, terrain, ids, "INPUT",
                      "uncheck USE_Z to take heights from the DEM or HEIGHT")
    return lon, lat, h
