"""Ground control points: the GCP table, its readers, a-priori residuals against a scene, and
the GeoPackage layer the bundle adjustment reads (the helpers it shares with the other
observations, heights among them, are in :mod:`core.observations.tables`).

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

import logging
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from osgeo import gdal, ogr

from ..errors import InputError
from ..files import OutputSet
from ..geodesy import geodetic_to_ecef
from ..validation import (MAX_IMAGE_COORDINATE, PLAUSIBLE_HEIGHTS, implausible_heights,
                         implausible_image_coordinates, per_point)
from ..vector_io import layer_to_wgs84_3d, open_layer, wgs84_3d, write_layer
from .tables import (MAX_SIGMA, SCENE_METADATA_KEY, Heights, csv_column, ellipsoidal_heights, listed, present,
                     nullable_floats, parse_numbers, per_point_sigmas, read_delimited, require_finite,
                     require_unique, resolve_cameras, scene_of_rows, to_lonlat)

gdal.UseExceptions()
ogr.UseExceptions()
log = logging.getLogger(__name__)

ROLES = ("control", "check")
_ROLE_WORDS = {"": "control", "control": "control", "gcp": "control", "check": "check", "cp": "check",
               "checkpoint": "check", "check point": "check", "chk": "check"}
DEFAULT_SIGMA_PX = 0.5
DEFAULT_SIGMA_XY = 1.0
DEFAULT_SIGMA_Z = 1.0
_DEFAULT_SIGMAS = {"sigma_px": DEFAULT_SIGMA_PX, "sigma_xy": DEFAULT_SIGMA_XY, "sigma_z": DEFAULT_SIGMA_Z}
GPKG_LAYER = "gcps"


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
    :func:`core.observations.tables.resolve_cameras`), col, row (GDAL px), lon, lat (WGS84
    deg), h (ellipsoidal m), sigma_px (px), sigma_xy, sigma_z (m). One ground point measured in several cameras is
    several rows with the same id. ``residuals`` and ``scene_path`` (the scene file they were
    computed against) are set by :func:`apriori_residuals`. ``scene`` (n,) str: in a block
    of scenes (:mod:`core.adjust.block`) the name of the scene each row was measured in ('' when
    not stated; None: all '').
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
    scene_path: str = ""
    scene: np.ndarray | None = None
    ARRAYS = ("id", "role", "camera", "col", "row", "lon", "lat", "h", "sigma_px", "sigma_xy", "sigma_z")

    def __post_init__(self):
        n = np.size(self.id)
        for name in self.ARRAYS:
            kind = str if name in ("id", "role", "camera") else float
            value = np.broadcast_to(np.asarray(getattr(self, name), dtype=kind), (n,)).copy()
            setattr(self, name, value)
        self.scene = np.broadcast_to(np.asarray("" if self.scene is None else self.scene,
                                                      dtype=str), (n,)).copy()
        bad = sorted(set(self.role) - set(ROLES))
        if bad:
            raise InputError(f"GCP roles must be 'control' or 'check' (got {', '.join(map(repr, bad))})")

    def __len__(self) -> int:
        return int(self.id.size)

    def select(self, mask) -> "GcpTable":
        """The points where ``mask`` (boolean or index array) selects."""
        arrays = {name: getattr(self, name)[mask] for name in self.ARRAYS}
        res = None if self.residuals is None else self.residuals.select(mask)
        return GcpTable(**arrays, residuals=res, scene_path=self.scene_path, scene=self.scene[mask])

    def ecef(self) -> np.ndarray:
        """Ground points as ECEF metres (n, 3)."""
        return geodetic_to_ecef(self.lon, self.lat, self.h)


@dataclass
class CsvMapping:
    """Which CSV columns hold what. id None: the column ``id`` when the file has one, else the data
    line numbers (1-based); '' always the line numbers.
    x, y: ground coordinates in the CRS given to :func:`read_csv` (lon/lat order for degrees).
    z, role, camera: optional columns (role, camera None: the columns ``role``, ``camera`` when the
    file has them, else all control points of the scene's only camera). scene: the column naming the
    product of a block each row was measured in (None: the column ``scene`` when the file has one,
    else none; '': none). sigma_px (px), sigma_xy,
    sigma_z (m): optional columns of per-point sigmas (empty cells take the sigma given to :func:`read_csv`)."""
    col: str = "col"
    row: str = "row"
    x: str = "lon"
    y: str = "lat"
    id: str | None = "id"
    z: str | None = None
    role: str | None = None
    camera: str | None = None
    scene: str | None = None
    sigma_px: str | None = None
    sigma_xy: str | None = None
    sigma_z: str | None = None


# --- building a table -----------------------------------------------------------------------
def build_table(ids, col, row, x, y, *, crs, heights: Heights, z=None, role=None, camera=None, scene=None,
                block=None, sigma_px: float = DEFAULT_SIGMA_PX, sigma_xy: float = DEFAULT_SIGMA_XY,
                sigma_z: float = DEFAULT_SIGMA_Z, source: str = "GCP input") -> GcpTable:
    """A GCP table from raw columns (arrays of shape (n,)).

    col, row: GDAL image coordinates (px). x, y: ground coordinates in ``crs`` (any EPSG code,
    WKT or PROJ string; x is easting/longitude). z: heights for ``heights.source == 'z'``.
    role: per-point role words (control/gcp/check/cp/checkpoint, case-insensitive; empty =
    control), default all control. camera: per-point camera names, default '' (unassigned).
    scene: per-point names of the block's product each row was measured in (``scene``),
    default none. block: the scene names of the block the rows belong to (a sequence), when they are
    read for one: every row's scene is checked to be one of them first
    (:func:`core.observations.tables.scene_of_rows`, parameter 'gcps.scene'), before the pairs are.
    source names the input in error messages. Raises InputError for NaN coordinates
    (naming the ids), an unknown CRS (naming it), ground points the CRS cannot convert, heights the
    DEM does not cover, unknown roles and repeated (id, camera) pairs ((id, scene, camera) with
    ``scene``: one point measured by the cameras of one name of two products is two rows).
    Every per-point argument is one value per point or a single value for all; InputError naming
    them when their lengths differ (core.validation.per_point).
    """
    optional = {k: v for k, v in dict(z=z, role=role, camera=camera, scene=scene).items() if v is not None}
    ids, col, row, x, y, sigma_px, sigma_xy, sigma_z, *given = per_point(
        ids=ids, col=col, row=row, x=x, y=y, sigma_px=sigma_px, sigma_xy=sigma_xy, sigma_z=sigma_z, **optional)
    z, role, camera, scene = (dict(zip(optional, given)).get(k) for k in ("z", "role", "camera", "scene"))
    ids = np.char.strip(np.asarray(ids, dtype=str))
    n = ids.size
    if (ids == "").any():
        lines = (np.nonzero(ids == "")[0] + 1).astype(str)
        raise InputError(f"{source}: empty point id in data line(s) {listed(lines)}")
    camera = np.full(n, "") if camera is None else np.char.strip(np.asarray(camera, dtype=str))
    col, row, x, y = (np.asarray(v, dtype=float) for v in (col, row, x, y))
    require_finite(ids, source, col=col, row=row, x=x, y=y)
    scene = None if scene is None else np.char.strip(np.asarray(scene, dtype=str))
    if block is not None:
        scene = scene_of_rows(np.full(n, "") if scene is None else scene, ids, block, source, parameter="gcps.scene")
    require_unique(ids, camera, source, scene)
    lon, lat = to_lonlat(x, y, crs, ids, source)
    h = ellipsoidal_heights(lon, lat, heights, z, ids, source)
    table = GcpTable(ids, _roles(role, ids, source), camera, col, row, lon, lat, h, sigma_px, sigma_xy, sigma_z,
                     scene=scene)
    _require_plausible(table, source)
    return table


def _require_plausible(table: GcpTable, source: str) -> None:
    """Image coordinates no image reaches, heights no terrain has, and sigmas that are not
    positive numbers are refused, naming the points (finite-ness is checked before)."""
    checks = (("col/row", f"beyond any image (|value| > {MAX_IMAGE_COORDINATE:g} px)",
               implausible_image_coordinates(table.col, table.row)),
              ("h", f"not a terrain height ({PLAUSIBLE_HEIGHTS[0]:g} to {PLAUSIBLE_HEIGHTS[1]:g} m ellipsoidal)",
               implausible_heights(table.h)))
    for name, what, bad in checks:
        if bad.any():
            raise InputError(f"{source}: {name} of point(s) {listed(table.id[bad])} is {what}")
    for name, low in (("sigma_px", "> 0"), ("sigma_xy", ">= 0"), ("sigma_z", ">= 0")):
        values = getattr(table, name)
        with np.errstate(invalid="ignore"):
            bad = ~(((values > 0) | ((values == 0) & (low == ">= 0"))) & (values < MAX_SIGMA[name]))
        if bad.any():
            raise InputError(f"{source}: {name} of point(s) {listed(table.id[bad])} must be {low} and below "
                             f"{MAX_SIGMA[name]:g} (got {values[bad][0]:g})")


def _roles(role, ids, source: str) -> np.ndarray:
    if role is None:
        return np.full(ids.size, "control")
    words = np.char.lower(np.char.strip(np.asarray(role, dtype=str)))
    known = np.isin(words, list(_ROLE_WORDS))
    if not known.all():
        raise InputError(f"{source}: unknown role(s) {sorted(set(words[~known]))} for point(s) "
                         f"{listed(ids[~known])}; use 'control' or 'check'")
    keys = np.array(sorted(_ROLE_WORDS))
    return np.array([_ROLE_WORDS[k] for k in keys])[np.searchsorted(keys, words)]


# --- readers --------------------------------------------------------------------------------
def read_csv(path, mapping: CsvMapping, crs, heights: Heights, block=None, **sigmas) -> GcpTable:
    """GCPs from a delimited text file with a header row (see :class:`CsvMapping`).

    crs: CRS of the x/y columns. heights: where heights come from (Z column = mapping.z).
    block: the scene names of a block the rows are read for (see :func:`build_table`).
    sigmas: sigma_px, sigma_xy, sigma_z keywords for :func:`build_table`.
    """
    path = Path(path)
    header, cells = read_delimited(path)
    source = str(path)

    def text(name: str | None):
        return None if name is None else csv_column(header, cells, name, source)

    id_column = mapping.id if mapping.id is not None else present(header, "id")
    ids = text(id_column) if id_column else np.arange(1, len(cells) + 1).astype(str)

    def number(name: str | None):
        return None if name is None else parse_numbers(text(name), name, ids, source)

    for key in ("sigma_px", "sigma_xy", "sigma_z"):
        column = getattr(mapping, key)
        if column is not None:
            sigmas[key] = per_point_sigmas(text(column), sigmas.get(key, _DEFAULT_SIGMAS[key]), column, ids, source,
                                           key)
    return build_table(ids, number(mapping.col), number(mapping.row), number(mapping.x), number(mapping.y),
                       crs=crs, heights=heights, z=number(mapping.z),
                       role=text(mapping.role if mapping.role is not None else present(header, "role")),
                       camera=text(mapping.camera if mapping.camera is not None else present(header, "camera")),
                       scene=text((mapping.scene if mapping.scene is not None else present(header, "scene")) or None),
                       block=block, source=source, **sigmas)


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
        raise InputError(f"{path}: line(s) of point(s) {listed(map(str, short))} have fewer than 4 values "
                         "(mapX, mapY, sourceX, sourceY)")
    width = max(len(c) for c in cells)
    values = np.array([c + ["1"] * (width - len(c)) for c in cells], dtype=str)
    ids = np.arange(len(values)).astype(str)
    map_x, map_y, px, py = (parse_numbers(values[:, k], name, ids, source)
                            for k, name in enumerate(("mapX", "mapY", "sourceX", "sourceY")))
    enabled = parse_numbers(values[:, 4], "enable", ids, source) != 0 if width > 4 else np.ones(ids.size, bool)
    finite_py = py[np.isfinite(py)]
    if finite_py.size and (finite_py >= 0).all():
        log.info("%s: all pixel y values are >= 0: taken as image line numbers (no sign change)", source)
        row = py
    else:
        row = -py
    if (~enabled).any():
        log.warning("%s: %d disabled point(s) imported as check points: %s", source, (~enabled).sum(),
                    listed(ids[~enabled]))
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


# --- a-priori residuals ---------------------------------------------------------------------
def check_against_scene(table: GcpTable, scene, scene_path: str = "", camera: str | None = None,
                        check_fraction: float = 0.0) -> GcpTable:
    """The import pipeline after reading: cameras
    (:func:`core.observations.tables.resolve_cameras`), check points (:func:`assign_check_points`),
    then a-priori residuals (:func:`apriori_residuals`)."""
    table = assign_check_points(resolve_cameras(table, scene, camera), check_fraction)
    return apriori_residuals(table, scene, scene_path)


def apriori_residuals(table: GcpTable, scene, scene_path: str = "") -> GcpTable:
    """The table with :class:`Residuals` of every point against ``scene`` (a SceneModel).

    Cameras must be resolved (:func:`core.observations.tables.resolve_cameras`). Predicted
    positions come from the scene's ground_to_image of the ECEF GCP in its camera; the ground
    size of the residual from image_to_ground of the measured position at the GCP's height. Points whose measured or
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
        inside[sel] = cam.in_image(table.col[sel], table.row[sel]) & cam.in_image(*pred[:, sel])
    res_col, res_row = pred[0] - table.col, pred[1] - table.row
    res = Residuals(res_col, res_row, np.hypot(res_col, res_row), np.linalg.norm(ground - xyz, axis=1), inside)
    if (~inside).any():
        log.warning("%d point(s) outside the image (measured or predicted), kept with inside = 0: %s",
                    (~inside).sum(), listed(table.id[~inside]))
    return replace(table, residuals=res, scene_path=str(scene_path))


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
_READ_FIELDS = tuple(n for n, _ in _GPKG_FIELDS) + ("scene",)


def write_gpkg(table: GcpTable, path, layer: str = GPKG_LAYER, extra: dict | None = None,
               files: OutputSet | None = None) -> None:
    """Write the table as a GeoPackage point layer (replacing the file, completely or not at all;
    with ``files``, as part of that set).

    Geometry: Point Z (lon, lat, ellipsoidal h) in EPSG:4979. Fields: id, role, camera, col, row,
    h, sigma_px, sigma_xy, sigma_z, res_col, res_row, res_px, res_m, inside (0/1; NULL = not
    checked), scene (the block scene each row was measured in; only when a row names one), then
    the ``extra`` columns {name: (n,) array}. Missing values are NULL. The scene file the
    residuals were computed against is the layer metadata item PUSHBROOM_SCENE.
    """
    named = {"scene": table.scene} if (table.scene != "").any() else {}
    columns = {**_gpkg_columns(table), **named, **(extra or {})}
    points = (f"POINT Z ({lo!r} {la!r} {h!r})" for lo, la, h in zip(table.lon.tolist(), table.lat.tolist(),
                                                                       table.h.tolist()))
    write_layer(path, layer, wgs84_3d(), ogr.wkbPoint25D, columns, points,
                {SCENE_METADATA_KEY: table.scene_path} if table.scene_path else None, files)


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
    restored when every point has them; an optional text field ``scene`` gives each row's
    ``scene`` (the product of a block it was measured in; NULL: '').
    """
    path = Path(path)
    ds, lyr = open_layer(path, layer)
    names = [lyr.GetLayerDefn().GetFieldDefn(i).GetName() for i in range(lyr.GetLayerDefn().GetFieldCount())]
    missing = [f for f in ("id", "role", "col", "row") if f not in names]
    if missing:
        raise InputError(f"{path}: layer {lyr.GetName()!r} lacks GCP field(s) {', '.join(missing)}")
    to_wgs = layer_to_wgs84_3d(lyr)
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
                        for n in _READ_FIELDS])
    if not records:
        raise InputError(f"{path}: layer {lyr.GetName()!r} holds no points")
    cols = {n: [r[k] for r in records] for k, n in enumerate(_READ_FIELDS)}
    lon, lat, z = np.array(coords, dtype=float).T
    num = {n: nullable_floats(cols[n]) for n in ("h", "col", "row", "inside", "res_col", "res_row", "res_px", "res_m")}
    h = np.where(np.isfinite(z), z, num["h"])
    ids = np.array([str(v) for v in cols["id"]])
    require_finite(ids, str(path), col=num["col"], row=num["row"], h=h)
    table = GcpTable(ids, np.array([v or "control" for v in cols["role"]]),
                     np.array([v or "" for v in cols["camera"]]), num["col"], num["row"], lon, lat, h,
                     *(nullable_floats(cols[k], _DEFAULT_SIGMAS[k]) for k in ("sigma_px", "sigma_xy", "sigma_z")),
                     scene_path=lyr.GetMetadataItem(SCENE_METADATA_KEY) or "",
                     scene=np.array([str(v).strip() if v is not None else "" for v in cols["scene"]]))
    _require_plausible(table, str(path))
    if np.isfinite(num["inside"]).all():
        table.residuals = Residuals(num["res_col"], num["res_row"], num["res_px"], num["res_m"], num["inside"] != 0)
    return table
