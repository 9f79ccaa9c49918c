"""What the import and matching use cases share: the heights of imported points (HEIGHT_SOURCE), and
the one place their GeoPackage layers are written: the destination checked before any work, the
GCP or tie-point layer written completely or not at all, and the sentences that say what it holds."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pyproj import CRS
from pyproj.exceptions import CRSError

from ..errors import Cancelled, InputError
from ..log import LogLine
from ..observations import gcps, tiepoints
from ..observations.tables import Heights
from ..validation import check_terrain_height
from .base import FilesInUse, Terrain, concerning, surface_from, z_datum_of

# The output every import and matching use case writes (the provider's parameter name, which the
# refusals of core.files.check_outputs name).
OUTPUT = "OUTPUT"


@dataclass(frozen=True)
class PointHeights:
    """Where imported points take their heights: ``source`` 'z' (their Z values, in ``z_datum``:
    'geoid', 'ellipsoid', None for what the points' CRS says), 'dem' or 'constant' (the terrain's
    DEM, in its datum, or its constant height)."""
    source: str = "z"
    z_datum: str | None = None
    terrain: Terrain = Terrain()


def heights_of(spec: PointHeights, crs: str | None, crs_name: str = "") -> Heights:
    """:class:`core.observations.tables.Heights` of ``spec`` for points in CRS ``crs`` (a text pyproj
    reads, called ``crs_name`` in the refusal; None: unknown). The DEM is read, and a constant height
    checked, before any point; Z values need a datum the request or the CRS gives."""
    if spec.source == "constant":
        return Heights("constant", "ellipsoid", value=check_terrain_height(spec.terrain.height,
                                                                           spec.terrain.height_name))
    if spec.source == "dem":
        if not spec.terrain.dem:
            raise InputError("HEIGHT_SOURCE is dem but no DEM was given", parameter="")
        surface, _ = surface_from(spec.terrain)
        return Heights("dem", spec.terrain.datum, dem=surface)
    datum = spec.z_datum or _crs_datum(crs)
    if datum is None:
        raise InputError(f"Z_DATUM: HEIGHT_SOURCE is z and the points' CRS ({crs_name}) does not say what the Z "
                         "values are measured from: give Z_DATUM=geoid or Z_DATUM=ellipsoid (DEM_DATUM is the "
                         "DEM's datum only)", parameter="")
    return Heights("z", datum)


def _crs_datum(crs: str | None) -> str | None:
    """What Z values in CRS text ``crs`` are measured from, when it says (:func:`core.runs.base.z_datum_of`)."""
    if not crs:
        return None
    try:
        return z_datum_of(CRS.from_user_input(crs))
    except CRSError:
        return None


def check_cancelled(is_cancelled) -> None:
    """Stop between steps when ``is_cancelled`` (a callable, or None) says the user cancelled."""
    if is_cancelled is not None and is_cancelled():
        raise Cancelled("cancelled by the user")


def check_gpkg(path: str, what: str, files: FilesInUse) -> None:
    """Before any work: the GeoPackage ``path`` of OUTPUT (``what`` it holds, plural: 'GCP layers')
    is a .gpkg file that replaces no input or other output and can be written."""
    if Path(path).suffix.lower() != ".gpkg":
        raise InputError(f"{OUTPUT}: {what} are written as GeoPackage; choose a .gpkg file (got {path})",
                         parameter="")
    files.check({OUTPUT: [path]})


def write_gcps(table: gcps.GcpTable, path: str, extra: dict | None = None) -> None:
    """The GCP layer written to OUTPUT ``path`` (:func:`core.observations.gcps.write_gpkg`, ``extra``
    columns {name: (n,) array})."""
    with concerning(OUTPUT, OUTPUT):
        gcps.write_gpkg(table, path, extra=extra)


def gcp_lines(table: gcps.GcpTable) -> list[LogLine]:
    """The sentences saying what a GCP table holds: points by role and outside the image, a-priori
    residuals of the points inside."""
    s = gcps.summary(table)
    lines = [LogLine(f"{s['points']} points: {s['control']} control, {s['check']} check, {s['outside']} outside "
                     "the image")]
    if np.isfinite(s["median_px"]):
        lines.append(LogLine(f"a-priori residuals (points inside the image): median {s['median_px']:.2f} px "
                             f"({s['median_m']:.2f} m), max {s['max_px']:.2f} px ({s['max_m']:.2f} m)"))
    return lines


def write_ties(table: tiepoints.TieTable, path: str, by_scene: bool = False) -> list[LogLine]:
    """The tie-point layer written to OUTPUT ``path`` (:func:`core.observations.tiepoints.write_gpkg`);
    returns the sentences: points and observations per camera (``by_scene``: cameras named
    '<scene>/<camera>', a block of scenes), points seen in one camera, a-priori residuals."""
    with concerning(OUTPUT, OUTPUT):
        tiepoints.write_gpkg(table, path)
    s = tiepoints.summary(table, by_scene)
    seen = "image" if by_scene else "camera"
    histogram = ", ".join(f"{points} in {rays} {seen}{'s' if rays != 1 else ''}"
                          for rays, points in sorted(s["cameras_per_point"].items()))
    lines = [LogLine(f"{s['points']} tie points, {s['observations']} observations ("
                     + ", ".join(f"{k}: {v}" for k, v in s["cameras"].items()) + f"); points seen {histogram}")]
    if s["single"]:
        lines.append(LogLine(f"{s['single']} point(s) seen in one camera only: kept in the layer (rays = 1, empty "
                             "geometry) but left out of the adjustment", True))
    if s["rms_px"] == s["rms_px"]:  # not NaN: some point was intersected
        lines.append(LogLine(f"a-priori intersection residuals (onboard model, {s['points'] - s['single']} "
                             f"intersected points): RMS {s['rms_px']:.2f} px; {s['suspect']} point(s) likely "
                             "mismatched"))
    return lines
