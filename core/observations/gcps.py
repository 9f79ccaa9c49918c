"""Ground control points: the GCP table, its readers, heights, a-priori residuals against a
scene, and the GeoPackage layer the bundle adjustment reads.

Conventions (as everywhere in the core):
- image coordinates (col, row) are GDAL's: (0, 0) is the upper-left corner of the upper-left
  pixel, pixel centres sit at half-integers; rows grow downwards;
- ground coordinates are WGS84 longitude/latitude in degrees and ellipsoidal heights in
  metres (EPSG:4979 sense); geoid (EGM96) heights are converted on the way in;
- roles: 'control' points enter the adjustment, 'check' points never do (they are only
  evaluated); sigma_px is the image measurement sigma (px), sigma_xy / sigma_z the ground
  sigmas (m) of a weighted control point.

Inputs:
- CSV with a header row and a column mapping (:class:`CsvMapping`), any delimiter among
  ``, ; TAB |`` (detected from the header; decimal commas accepted when the delimiter is not a
  comma), ground coordinates in any CRS pyproj understands (EPSG code, WKT, PROJ string);
- the QGIS Georeferencer ``.points`` file (:func:`read_points_file`);
- arrays from elsewhere (a QGIS layer) through :func:`build_table`.

Output: a GeoPackage point layer (:func:`write_gpkg` / :func:`read_gpkg`) in EPSG:4979 with Z,
written and read with OGR only, so the core reads it without QGIS.
"""
from __future__ import annotations

import csv
import logging
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from osgeo import gdal, ogr, osr
from pyproj import CRS, Transformer
from pyproj.exceptions import CRSError

from ..dem import Dem, to_ellipsoidal
from ..errors import InputError
from ..files import OutputSet
from ..geodesy import geodetic_to_ecef
from ..validation import (MAX_IMAGE_COORDINATE, PLAUSIBLE_HEIGHTS, implausible_heights,
                         implausible_image_coordinates)
from ..vector_io import open_layer, write_layer

gdal.UseExceptions()
ogr.UseExceptions()
log = logging.getLogger(__name__)

ROLES = ("control", "check")
_ROLE_WORDS = {"": "control", "control": "control", "gcp": "control", "check": "check", "cp": "check",
               "checkpoint": "check", "check point": "check", "chk": "check"}
HEIGHT_SOURCES = ("z", "dem", "constant")
DEFAULT_SIGMA_PX = 0.5
DEFAULT_SIGMA_XY = 1.0
DEFAULT_SIGMA_Z = 1.0
# Largest a-priori sigmas accepted: beyond them a point carries no information (and a typo is likelier).
# Ground sigmas may be 0 (ground fixed); the image sigma may not.
MAX_SIGMA = {"sigma_px": 1e4, "sigma_xy": 1e5, "sigma_z": 1e5}
GPKG_LAYER = "gcps"
SCENE_METADATA_KEY = "PUSHBROOM_SCENE"
_MAX_LISTED = 10


# --- the table ------------------------------------------------------------------------------
@dataclass
class Residuals:
    """A-priori residuals of GCPs against a scene model, one value per point.

    col, row: predicted minus measured image position (px), predicted = the scene's
    ground_to_image of the GCP in its camera; NaN where the scene has no image of the point.
    px: their length (px). m: ground distance (m) between the GCP and the point the scene sees
    at the measured (col, row) on the GCP's ellipsoidal height; NaN where that ray misses.
    inside: True where both the measured and the predicted position lie in the image.
    """
    col: np.ndarray
    row: np.ndarray
    px: np.ndarray
    m: np.ndarray
    inside: np.ndarray

    def select(self, mask) -> "Residuals":
        return Residuals(*(getattr(self, f)[mask] for f in ("col", "row", "px", "m", "inside")))


@dataclass
class GcpTable:
    """Ground control and check points, as parallel arrays of shape (n,).

    id (str), role ('control' | 'check'), camera (camera name; '' = not yet assigned, see
    :func:`resolve_cameras`), col, row (GDAL px), lon, lat (WGS84 deg), h (ellipsoidal m),
    sigma_px (px), sigma_xy, sigma_z (m). One ground point measured in several cameras is
    several rows with the same id. ``residuals`` and ``scene`` (the scene file they were
    computed against) are set by :func:`apriori_residuals`.
    """
    id: np.ndarray
    role: np.ndarray
    camera: np.ndarray
    col: np.ndarray
    row: np.ndarray
    lon: np.ndarray
    lat: np.ndarray
    h: np.ndarray
    sigma_px: np.ndarray
    sigma_xy: np.ndarray
    sigma_z: np.ndarray
    residuals: Residuals | None = None
    scene: str = ""
    ARRAYS = ("id", "role", "camera", "col", "row", "lon", "lat", "h", "sigma_px", "sigma_xy", "sigma_z")

    def __post_init__(self):
        n = np.size(self.id)
        for name in self.ARRAYS:
            kind = str if name in ("id", "role", "camera") else float
            value = np.broadcast_to(np.asarray(getattr(self, name), dtype=kind), (n,)).copy()
            setattr(self, name, value)
        bad = sorted(set(self.role) - set(ROLES))
        if bad:
            raise InputError(f"GCP roles must be 'control' or 'check' (got {', '.join(map(repr, bad))})")

    def __len__(self) -> int:
        return int(self.id.size)

    def select(self, mask) -> "GcpTable":
        """The points where ``mask`` (boolean or index array) selects."""
        arrays = {name: getattr(self, name)[mask] for name in self.ARRAYS}
        res = None if self.residuals is None else self.residuals.select(mask)
        return GcpTable(**arrays, residuals=res, scene=self.scene)

    def ecef(self) -> np.ndarray:
        """Ground points as ECEF metres (n, 3)."""
        return geodetic_to_ecef(self.lon, self.lat, self.h)


@dataclass
class Heights:
    """Where the GCP heights come from.

    source: 'z' (the input's Z values / Z field), 'dem' (sampled from ``dem``) or 'constant'
    (``value`` for every point). datum: 'ellipsoid' or 'geoid' (EGM96) for the Z values, the
    DEM and the constant alike. dem: a raster path, or an already loaded :class:`core.dem.Dem`.
    """
    source: str = "z"
    datum: str = "ellipsoid"
    dem: object = None
    value: float = 0.0


@dataclass
class CsvMapping:
    """Which CSV columns hold what. id None: ids are the data line numbers (1-based).
    x, y: ground coordinates in the CRS given to :func:`read_csv` (lon/lat order for degrees).
    z, role, camera: optional columns. sigma_px (px), sigma_xy, sigma_z (m): optional columns
    of per-point sigmas (empty cells take the sigma given to :func:`read_csv`)."""
    col: str = "col"
    row: str = "row"
    x: str = "lon"
    y: str = "lat"
    id: str | None = "id"
    z: str | None = None
    role: str | None = None
    camera: str | None = None
    sigma_px: str | None = None
    sigma_xy: str | None = None
    sigma_z: str | None = None


# --- building a table -----------------------------------------------------------------------
def build_table(ids, col, row, x, y, *, crs, heights: Heights, z=None, role=None, camera=None,
                sigma_px: float = DEFAULT_SIGMA_PX, sigma_xy: float = DEFAULT_SIGMA_XY,
                sigma_z: float = DEFAULT_SIGMA_Z, source: str = "GCP input") -> GcpTable:
    """A GCP table from raw columns (arrays of shape (n,)).

    col, row: GDAL image coordinates (px). x, y: ground coordinates in ``crs`` (any EPSG code,
    WKT or PROJ string; x is easting/longitude). z: heights for ``heights.source == 'z'``.
    role: per-point role words (control/gcp/check/cp/checkpoint, case-insensitive; empty =
    control), default all control. camera: per-point camera names, default '' (unassigned).
    source names the input in error messages. Raises InputError for NaN coordinates (naming
    the ids), an unknown CRS (naming it), ground points the CRS cannot convert, heights the
    DEM does not cover, unknown roles and repeated (id, camera) pairs.
    """
    ids = np.char.strip(np.asarray(ids, dtype=str))
    n = ids.size
    if (ids == "").any():
        lines = (np.nonzero(ids == "")[0] + 1).astype(str)
        raise InputError(f"{source}: empty point id in data line(s) {_listed(lines)}")
    camera = np.full(n, "") if camera is None else np.char.strip(np.asarray(camera, dtype=str))
    col, row, x, y = (np.asarray(v, dtype=float) for v in (col, row, x, y))
    _require_finite(ids, source, col=col, row=row, x=x, y=y)
    _require_unique(ids, camera, source)
    lon, lat = _to_lonlat(x, y, crs, ids, source)
    h = _heights(lon, lat, heights, z, ids, source)
    table = GcpTable(ids, _roles(role, ids, source), camera, col, row, lon, lat, h, sigma_px, sigma_xy, sigma_z)
    _require_plausible(table, source)
    return table


def _listed(ids) -> str:
    ids = list(ids)
    more = f" and {len(ids) - _MAX_LISTED} more" if len(ids) > _MAX_LISTED else ""
    return ", ".join(ids[:_MAX_LISTED]) + more


def _require_finite(ids, source: str, **columns) -> None:
    for name, values in columns.items():
        bad = ~np.isfinite(values)
        if bad.any():
            raise InputError(f"{source}: {name} is missing or not a number for point(s) {_listed(ids[bad])}")


def _require_unique(ids, camera, source: str) -> None:
    keys = np.char.add(np.char.add(ids, "\x1f"), camera)  # numpy strings drop NUL characters
    uniq, counts = np.unique(keys, return_counts=True)
    if (counts > 1).any():
        dup = list(dict.fromkeys(k.split("\x1f")[0] for k in uniq[counts > 1]))
        raise InputError(f"{source}: point id(s) {_listed(dup)} occur more than once for the same camera")


def _require_plausible(table: GcpTable, source: str) -> None:
    """Image coordinates no image reaches, heights no terrain has, and sigmas that are not
    positive numbers are refused, naming the points (finite-ness is checked before)."""
    checks = (("col/row", f"beyond any image (|value| > {MAX_IMAGE_COORDINATE:g} px)",
               implausible_image_coordinates(table.col, table.row)),
              ("h", f"not a terrain height ({PLAUSIBLE_HEIGHTS[0]:g} to {PLAUSIBLE_HEIGHTS[1]:g} m ellipsoidal)",
               implausible_heights(table.h)))
    for name, what, bad in checks:
        if bad.any():
            raise InputError(f"{source}: {name} of point(s) {_listed(table.id[bad])} is {what}")
    for name, low in (("sigma_px", "> 0"), ("sigma_xy", ">= 0"), ("sigma_z", ">= 0")):
        values = getattr(table, name)
        with np.errstate(invalid="ignore"):
            bad = ~(((values > 0) | ((values == 0) & (low == ">= 0"))) & (values < MAX_SIGMA[name]))
        if bad.any():
            raise InputError(f"{source}: {name} of point(s) {_listed(table.id[bad])} must be {low} and below "
                             f"{MAX_SIGMA[name]:g} (got {values[bad][0]:g})")


def parse_crs(crs, source: str = "GCP input") -> CRS:
    """A pyproj CRS from any user string (EPSG:xxxx, WKT, PROJ); InputError naming it if unknown."""
    if crs is None or not str(crs).strip():
        raise InputError(f"{source}: no ground CRS given; state the CRS of the ground coordinates (e.g. EPSG:4326)")
    try:
        parsed = CRS.from_user_input(str(crs).strip())
    except CRSError:
        text = str(crs).strip()
        raise InputError(f"{source}: unknown ground CRS {text[:200]!r} (expected an EPSG code, WKT or PROJ string)") \
            from None
    if parsed.is_compound:
        parsed = parsed.sub_crs_list[0]
    if not (parsed.is_geographic or parsed.is_projected):
        raise InputError(f"{source}: ground CRS {parsed.name!r} is not a horizontal (geographic or projected) CRS")
    return parsed


def _to_lonlat(x, y, crs, ids, source: str) -> tuple[np.ndarray, np.ndarray]:
    """(lon, lat) WGS84 degrees of (x, y) in crs (axis order: easting/longitude first)."""
    tr = Transformer.from_crs(parse_crs(crs, source), CRS.from_epsg(4326), always_xy=True)
    lon, lat = (np.asarray(v, dtype=float) for v in tr.transform(x, y))
    bad = ~(np.isfinite(lon) & np.isfinite(lat) & (np.abs(lat) <= 90.0) & (np.abs(lon) <= 360.0))
    if bad.any():
        raise InputError(f"{source}: ground coordinates of point(s) {_listed(ids[bad])} cannot be converted "
                         f"from {tr.source_crs.name!r} to WGS84 (outside the CRS's area or wrong axis order?)")
    return lon, lat


def _heights(lon, lat, heights: Heights, z, ids, source: str) -> np.ndarray:
    """Ellipsoidal heights (m) of the points, from the source ``heights`` names."""
    if heights.source == "z":
        if z is None:
            raise InputError(f"{source}: heights from Z were requested but the input has no Z values; "
                             "name a Z field, or take heights from a DEM or a constant")
        z = np.asarray(z, dtype=float)
        _require_finite(ids, source, z=z)
        return to_ellipsoidal(lon, lat, z, heights.datum)
    if heights.source == "constant":
        if not np.isfinite(heights.value):
            raise InputError(f"{source}: the constant height must be a number (got {heights.value})")
        return to_ellipsoidal(lon, lat, np.full(lon.shape, float(heights.value)), heights.datum)
    if heights.source == "dem":
        if heights.dem is None:
            raise InputError(f"{source}: heights from a DEM were requested but no DEM was given")
        dem = Dem(heights.dem, heights.datum) if isinstance(heights.dem, (str, Path)) else heights.dem
        h = dem.height(lon, lat)
        bad = ~np.isfinite(h)
        if bad.any():
            raise InputError(f"{source}: the DEM {getattr(dem, 'path', '')} does not cover point(s) "
                             f"{_listed(ids[bad])} (outside it or on nodata)")
        return h
    raise InputError(f"height source must be one of {', '.join(HEIGHT_SOURCES)} (got {heights.source!r})")


def _roles(role, ids, source: str) -> np.ndarray:
    if role is None:
        return np.full(ids.size, "control")
    words = np.char.lower(np.char.strip(np.asarray(role, dtype=str)))
    known = np.isin(words, list(_ROLE_WORDS))
    if not known.all():
        raise InputError(f"{source}: unknown role(s) {sorted(set(words[~known]))} for point(s) "
                         f"{_listed(ids[~known])}; use 'control' or 'check'")
    keys = np.array(sorted(_ROLE_WORDS))
    return np.array([_ROLE_WORDS[k] for k in keys])[np.searchsorted(keys, words)]


# --- readers --------------------------------------------------------------------------------
def read_csv(path, mapping: CsvMapping, crs, heights: Heights, **sigmas) -> GcpTable:
    """GCPs from a delimited text file with a header row (see :class:`CsvMapping`).

    crs: CRS of the x/y columns. heights: where heights come from (Z column = mapping.z).
    sigmas: sigma_px, sigma_xy, sigma_z keywords for :func:`build_table`.
    """
    path = Path(path)
    header, cells = _read_delimited(path)
    source = str(path)

    def text(name: str | None):
        return None if name is None else csv_column(header, cells, name, source)

    ids = text(mapping.id) if mapping.id else np.arange(1, len(cells) + 1).astype(str)

    def number(name: str | None):
        return None if name is None else _numbers(text(name), name, ids, source)

    for key in ("sigma_px", "sigma_xy", "sigma_z"):
        column = getattr(mapping, key)
        if column is not None:
            sigmas[key] = per_point_sigmas(text(column), sigmas.get(key, _DEFAULT_SIGMAS[key]), column, ids, source,
                                           key)
    return build_table(ids, number(mapping.col), number(mapping.row), number(mapping.x), number(mapping.y),
                       crs=crs, heights=heights, z=number(mapping.z), role=text(mapping.role),
                       camera=text(mapping.camera), source=source, **sigmas)


_DEFAULT_SIGMAS = {"sigma_px": DEFAULT_SIGMA_PX, "sigma_xy": DEFAULT_SIGMA_XY, "sigma_z": DEFAULT_SIGMA_Z}


def per_point_sigmas(values, default: float, name: str, ids, source: str, key: str) -> np.ndarray:
    """(n,) sigmas ``key`` (sigma_px, sigma_xy or sigma_z) from a column of per-point values (text, numbers,
    or None); empty cells and None take ``default``. Every given value must be a number in
    (0, MAX_SIGMA[key]): InputError naming the
    column ``name`` and the points otherwise (an exact point is not a sigma of 0 but GROUND =
    fixed in the adjustment)."""
    ids = np.asarray(ids, dtype=str)
    raw = np.char.strip(np.array(["" if v is None else str(v) for v in values], dtype=str))
    given = raw != ""
    numeric = np.array([_is_number(t) for t in np.char.replace(raw, ",", ".")], dtype=bool)
    out = np.full(raw.size, float(default))
    ok = given & numeric
    out[ok] = np.char.replace(raw[ok], ",", ".").astype(float)
    bad = given & ~(numeric & (out > 0) & (out < MAX_SIGMA[key]))
    if bad.any():
        shown = ", ".join(f"{i}: {t!r}" for i, t in zip(ids[bad][:_MAX_LISTED], raw[bad][:_MAX_LISTED]))
        more = f" and {int(bad.sum()) - _MAX_LISTED} more" if bad.sum() > _MAX_LISTED else ""
        raise InputError(f"{source}: per-point sigma field {name!r} must hold numbers > 0 and below "
                         f"{MAX_SIGMA[key]:g} (or stay empty for the default {default:g}); point(s) {shown}{more}. "
                         "A sigma of 0 is not possible in a weighted adjustment: give exact points a small sigma, "
                         "or fix all ground coordinates (GROUND)")
    return out


def _read_delimited(path: Path) -> tuple[list[str], np.ndarray]:
    """(header names, string array (n_rows, n_cols)) of a delimited text file."""
    try:
        lines = [ln for ln in path.read_text(encoding="utf-8-sig").splitlines() if ln.strip()]
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot be read as a text file ({exc})") from None
    if len(lines) < 2:
        raise InputError(f"{path}: needs a header line and at least one point")
    delimiter = max(",;\t|", key=lines[0].count)
    table = list(csv.reader(lines, delimiter=delimiter))
    header = [h.strip() for h in table[0]]
    width = len(header)
    body = [r + [""] * (width - len(r)) if len(r) < width else r[:width] for r in table[1:]]
    values = np.array(body, dtype=str)
    if delimiter != ",":
        values = np.char.replace(values, ",", ".")
    return header, values


def csv_column(header: list[str], cells: np.ndarray, name: str, source: str) -> np.ndarray:
    """The stripped text (n,) of column ``name`` of :func:`_read_delimited`'s cells; InputError
    naming the file and listing its columns when there is none of that name."""
    if name not in header:
        raise InputError(f"{source}: no column {name!r} (columns: {', '.join(header)})")
    return np.char.strip(cells[:, header.index(name)])


def _numbers(values, name: str, ids, source: str) -> np.ndarray:
    """Floats of a string column; empty cells become NaN (reported later with the ids)."""
    text = np.char.strip(np.asarray(values, dtype=str))
    text = np.where(text == "", "nan", text)
    try:
        return text.astype(float)
    except ValueError:
        ok = np.array([_is_number(t) for t in text])
        raise InputError(f"{source}: column {name!r} is not a number for point(s) {_listed(np.asarray(ids)[~ok])}") \
            from None


def _is_number(text: str) -> bool:
    try:
        float(text)
        return True
    except ValueError:
        return False


def read_points_file(path, heights: Heights, crs=None, **sigmas) -> GcpTable:
    """GCPs from a QGIS Georeferencer ``.points`` file.

    Format (QGIS 3.x): optional first line ``#CRS: <WKT or authid>`` (the CRS of mapX/mapY),
    a header ``mapX,mapY,pixelX,pixelY,enable,dX,dY,residual`` (QGIS <= 3.24; ``sourceX,
    sourceY`` from 3.26), one point per line, comma separated (tab in files from before
    QGIS 2). ``enable`` is optional (1 when absent).

    Pixel coordinates: QGIS shows a raw image (no geotransform) with the layer coordinates
    x = GDAL col, y = -GDAL row (corner convention, y negative downwards), and writes these.
    So when any source/pixel y is negative the file is taken in that convention, row = -y;
    when all are >= 0 they are line numbers already (QGIS 3.22 writes column/line for a
    source image that has a geotransform) and row = y (logged).

    CRS: the file's ``#CRS`` line wins; ``crs`` is used only when the file has none (QGIS
    then meant the project CRS, which the file does not record).

    Disabled points (enable = 0) become check points, with a warning listing them: they
    stay visible and evaluated but never enter the adjustment. Ids are the QGIS GCP table
    ids (0-based, in file order). No heights are in the file: heights.source must be 'dem'
    or 'constant'.
    """
    path = Path(path)
    source = str(path)
    if heights.source == "z":
        raise InputError(f"{path}: .points files carry no heights; take heights from a DEM or a constant")
    try:
        lines = path.read_text(encoding="utf-8-sig").splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot be read as a text file ({exc})") from None
    file_crs = next((ln.split(":", 1)[1].strip() for ln in lines[:1] if ln.startswith("#CRS:")), "")
    data = [ln for ln in lines if ln.strip() and not ln.startswith("#") and not ln.lower().startswith("mapx")]
    if not data:
        raise InputError(f"{path}: no points in this .points file")
    cells = [ln.split("," if "," in ln else "\t") for ln in data]
    short = [i for i, c in enumerate(cells) if len(c) < 4]
    if short:
        raise InputError(f"{path}: line(s) of point(s) {_listed(map(str, short))} have fewer than 4 values "
                         "(mapX, mapY, sourceX, sourceY)")
    width = max(len(c) for c in cells)
    values = np.array([c + ["1"] * (width - len(c)) for c in cells], dtype=str)
    ids = np.arange(len(values)).astype(str)
    map_x, map_y, px, py = (_numbers(values[:, k], name, ids, source)
                            for k, name in enumerate(("mapX", "mapY", "sourceX", "sourceY")))
    enabled = _numbers(values[:, 4], "enable", ids, source) != 0 if width > 4 else np.ones(ids.size, bool)
    finite_py = py[np.isfinite(py)]
    if finite_py.size and (finite_py >= 0).all():
        log.info("%s: all pixel y values are >= 0: taken as image line numbers (no sign change)", source)
        row = py
    else:
        row = -py
    if (~enabled).any():
        log.warning("%s: %d disabled point(s) imported as check points: %s", source, (~enabled).sum(),
                    _listed(ids[~enabled]))
    role = np.where(enabled, "control", "check")
    return build_table(ids, px, row, map_x, map_y, crs=file_crs or crs, heights=heights, role=role,
                       source=source, **sigmas)


# --- roles and cameras ----------------------------------------------------------------------
def assign_check_points(table: GcpTable, fraction: float) -> GcpTable:
    """Make a share ``fraction`` (0..1) of all points check points, deterministically.

    Points already marked check count toward the share; more are taken from the control
    points, evenly spread over the image in (row, col) order, so the same input always gives
    the same split and the check points cover the scene along track.
    """
    if not 0.0 <= fraction <= 1.0:
        raise InputError(f"check fraction must be between 0 and 1 (got {fraction})")
    wanted = int(round(fraction * len(table))) - int(np.sum(table.role == "check"))
    control = np.nonzero(table.role == "control")[0]
    if wanted <= 0 or control.size == 0:
        return table
    wanted = min(wanted, control.size)
    ordered = control[np.lexsort((table.col[control], table.row[control]))]
    picks = ordered[((np.arange(wanted) + 0.5) * control.size / wanted).astype(int)]
    role = table.role.copy()
    role[picks] = "check"
    return replace(table, role=role)


def resolve_cameras(table: GcpTable, scene, camera: str | None = None) -> GcpTable:
    """Give every point a camera name of ``scene``.

    camera: a name (or index) for all points, overriding the table's. Otherwise points with
    an empty camera get the scene's only camera; a camera given as an index (e.g. '1') that is
    no camera name is taken as an index. InputError for unknown cameras or points without one
    in a multi-camera scene.
    """
    names = [c.name for c in scene.cameras]
    if camera not in (None, ""):
        key = int(camera) if isinstance(camera, int) or (str(camera).isdigit() and camera not in names) else camera
        return replace(table, camera=np.full(len(table), names[scene.camera_index(key)]))
    cams = table.camera
    missing = cams == ""
    if missing.any():
        if len(names) > 1:
            raise InputError(f"point(s) {_listed(table.id[missing])} have no camera and the scene has several "
                             f"({', '.join(names)}); give a camera field or choose a camera")
        cams = np.where(missing, names[0], cams)
    for value in set(np.unique(cams)) - set(names):
        try:
            cams = np.where(cams == value, names[scene.camera_index(int(value))], cams)
        except ValueError:
            raise InputError(f"camera {value!r} of point(s) {_listed(table.id[cams == value])} is not in the scene "
                             f"(cameras: {', '.join(names)})") from None
    return replace(table, camera=cams)


# --- a-priori residuals ---------------------------------------------------------------------
def check_against_scene(table: GcpTable, scene, scene_path: str = "", camera: str | None = None,
                        check_fraction: float = 0.0) -> GcpTable:
    """The import pipeline after reading: cameras (:func:`resolve_cameras`), check points
    (:func:`assign_check_points`), then a-priori residuals (:func:`apriori_residuals`)."""
    table = assign_check_points(resolve_cameras(table, scene, camera), check_fraction)
    return apriori_residuals(table, scene, scene_path)


def apriori_residuals(table: GcpTable, scene, scene_path: str = "") -> GcpTable:
    """The table with :class:`Residuals` of every point against ``scene`` (a SceneModel).

    Cameras must be resolved (:func:`resolve_cameras`). Predicted positions come from the
    scene's ground_to_image of the ECEF GCP in its camera; the ground size of the residual from
    image_to_ground of the measured position at the GCP's height. Points whose measured or
    predicted position lies outside the image get inside=False; nothing is dropped.
    """
    n = len(table)
    pred = np.full((2, n), np.nan)
    ground = np.full((n, 3), np.nan)
    inside = np.zeros(n, dtype=bool)
    xyz = table.ecef()
    for name in np.unique(table.camera):
        sel = np.nonzero(table.camera == name)[0]
        cam = scene.cameras[scene.camera_index(str(name))]
        pred[:, sel] = scene.ground_to_image(xyz[sel], str(name))
        ground[sel] = scene.image_to_ground(table.col[sel], table.row[sel], table.h[sel], str(name))
        inside[sel] = _in_image(table.col[sel], table.row[sel], cam) & _in_image(*pred[:, sel], cam)
    res_col, res_row = pred[0] - table.col, pred[1] - table.row
    res = Residuals(res_col, res_row, np.hypot(res_col, res_row), np.linalg.norm(ground - xyz, axis=1), inside)
    if (~inside).any():
        log.warning("%d point(s) outside the image (measured or predicted), kept with inside = 0: %s",
                    (~inside).sum(), _listed(table.id[~inside]))
    return replace(table, residuals=res, scene=str(scene_path))


def _in_image(col, row, cam) -> np.ndarray:
    with np.errstate(invalid="ignore"):
        return (col >= 0) & (col <= cam.cols) & (row >= 0) & (row <= cam.rows)


def summary(table: GcpTable) -> dict:
    """Counts and a-priori residual statistics (over points inside the image) for reports.

    Keys: points, control, check, outside, median_px, max_px, median_m, max_m (NaN when there
    are no residuals or no point inside)."""
    out = {"points": len(table), "control": int(np.sum(table.role == "control")),
           "check": int(np.sum(table.role == "check")), "outside": 0}
    stats = dict.fromkeys(("median_px", "max_px", "median_m", "max_m"), float("nan"))
    res = table.residuals
    if res is not None:
        out["outside"] = int(np.sum(~res.inside))
        for key, values in (("px", res.px), ("m", res.m)):
            v = values[res.inside & np.isfinite(values)]
            if v.size:
                stats[f"median_{key}"], stats[f"max_{key}"] = float(np.median(v)), float(np.max(v))
    return {**out, **stats}


# --- GeoPackage -----------------------------------------------------------------------------
_GPKG_FIELDS = (("id", ogr.OFTString), ("role", ogr.OFTString), ("camera", ogr.OFTString),
                ("col", ogr.OFTReal), ("row", ogr.OFTReal), ("h", ogr.OFTReal), ("sigma_px", ogr.OFTReal),
                ("sigma_xy", ogr.OFTReal), ("sigma_z", ogr.OFTReal), ("res_col", ogr.OFTReal),
                ("res_row", ogr.OFTReal), ("res_px", ogr.OFTReal), ("res_m", ogr.OFTReal),
                ("inside", ogr.OFTInteger))


def _wgs84_3d() -> osr.SpatialReference:
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(4979)
    srs.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    return srs


def write_gpkg(table: GcpTable, path, layer: str = GPKG_LAYER, extra: dict | None = None,
               files: OutputSet | None = None) -> None:
    """Write the table as a GeoPackage point layer (replacing the file, completely or not at all;
    with ``files``, as part of that set).

    Geometry: Point Z (lon, lat, ellipsoidal h) in EPSG:4979. Fields: id, role, camera, col, row,
    h, sigma_px, sigma_xy, sigma_z, res_col, res_row, res_px, res_m, inside (0/1; NULL = not
    checked), then the ``extra`` columns {name: (n,) array}. Missing values are NULL. The
    scene file the residuals were computed against is the layer metadata item PUSHBROOM_SCENE.
    """
    columns = {**_gpkg_columns(table), **(extra or {})}
    points = (f"POINT Z ({lo!r} {la!r} {h!r})" for lo, la, h in zip(table.lon.tolist(), table.lat.tolist(),
                                                                       table.h.tolist()))
    write_layer(path, layer, _wgs84_3d(), ogr.wkbPoint25D, columns, points,
                {SCENE_METADATA_KEY: table.scene} if table.scene else None, files)


def _gpkg_columns(table: GcpTable) -> dict:
    res = table.residuals
    nan = np.full(len(table), np.nan)
    return {"id": table.id, "role": table.role, "camera": table.camera, "col": table.col, "row": table.row,
            "h": table.h, "sigma_px": table.sigma_px, "sigma_xy": table.sigma_xy, "sigma_z": table.sigma_z,
            "res_col": nan if res is None else res.col, "res_row": nan if res is None else res.row,
            "res_px": nan if res is None else res.px, "res_m": nan if res is None else res.m,
            "inside": nan if res is None else np.where(res.inside, 1.0, 0.0)}


def read_gpkg(path, layer: str | None = None) -> GcpTable:
    """Read a GCP layer written by :func:`write_gpkg` (or edited in QGIS).

    Ground positions come from the geometry (transformed to EPSG:4979 if the layer has another
    CRS); h from the geometry's Z (the 'h' field when the geometry has no Z). Residuals are
    restored when every point has them.
    """
    path = Path(path)
    ds, lyr = open_layer(path, layer)
    names = [lyr.GetLayerDefn().GetFieldDefn(i).GetName() for i in range(lyr.GetLayerDefn().GetFieldCount())]
    missing = [f for f in ("id", "role", "col", "row") if f not in names]
    if missing:
        raise InputError(f"{path}: layer {lyr.GetName()!r} lacks GCP field(s) {', '.join(missing)}")
    to_wgs = _layer_transform(lyr)
    records, coords = [], []
    for feat in lyr:  # OGR reads feature by feature
        geom = feat.GetGeometryRef()
        if geom is None:
            raise InputError(f"{path}: point {feat.GetField('id')!r} has no geometry")
        if ogr.GT_Flatten(geom.GetGeometryType()) != ogr.wkbPoint:
            raise InputError(f"{path}: GCP {feat.GetField('id')!r} is a {geom.GetGeometryName().lower()}, not a point "
                             f"(a GCP layer holds points)")
        if to_wgs is not None:
            geom = geom.Clone()
            geom.Transform(to_wgs)
        coords.append((geom.GetX(), geom.GetY(), geom.GetZ() if geom.Is3D() else np.nan))
        records.append([feat.GetField(n) if n in names and feat.IsFieldSetAndNotNull(n) else None
                        for n, _ in _GPKG_FIELDS])
    if not records:
        raise InputError(f"{path}: layer {lyr.GetName()!r} holds no points")
    cols = {n: [r[k] for r in records] for k, (n, _) in enumerate(_GPKG_FIELDS)}
    lon, lat, z = np.array(coords, dtype=float).T
    h = np.where(np.isfinite(z), z, _float(cols["h"]))
    ids = np.array([str(v) for v in cols["id"]])
    _require_finite(ids, str(path), col=_float(cols["col"]), row=_float(cols["row"]), h=h)
    table = GcpTable(ids, np.array([v or "control" for v in cols["role"]]),
                     np.array([v or "" for v in cols["camera"]]), _float(cols["col"]), _float(cols["row"]),
                     lon, lat, h, _float(cols["sigma_px"], DEFAULT_SIGMA_PX),
                     _float(cols["sigma_xy"], DEFAULT_SIGMA_XY), _float(cols["sigma_z"], DEFAULT_SIGMA_Z),
                     scene=lyr.GetMetadataItem(SCENE_METADATA_KEY) or "")
    _require_plausible(table, str(path))
    inside = _float(cols["inside"])
    if np.isfinite(inside).all():
        table.residuals = Residuals(_float(cols["res_col"]), _float(cols["res_row"]), _float(cols["res_px"]),
                                    _float(cols["res_m"]), inside != 0)
    return table


def _float(values, default: float = np.nan) -> np.ndarray:
    return np.array([default if v is None else v for v in values], dtype=float)


def _layer_transform(lyr) -> osr.CoordinateTransformation | None:
    srs = lyr.GetSpatialRef()
    target = _wgs84_3d()
    if srs is None or srs.IsSame(target):
        return None
    srs = srs.Clone()
    srs.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    return osr.CoordinateTransformation(srs, target)
