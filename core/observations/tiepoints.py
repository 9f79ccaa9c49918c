"""Tie points: image observations of ground points whose coordinates are unknown.

One tie point is one ground point measured in two or more cameras of a scene (three-line
cameras) or in overlapping scenes of a strip; the adjustment estimates its ground position
(eliminated per point, like a weighted GCP's) starting from a forward intersection of the
onboard rays (:mod:`core.model.intersection`).

Conventions as in :mod:`core.observations.gcps`: image coordinates are GDAL's (pixel centres at
half-integers), sigma_px is the image measurement sigma (px).

Inputs: CSV with a header row and a column mapping (:class:`CsvMapping`; the delimiters and
decimal commas of :func:`core.observations.gcps.read_csv`; other columns are ignored, so the simulator's
``tie_points.csv`` reads as it is), or arrays from elsewhere (a QGIS layer) through
:func:`build_table`. :func:`check_against_scene` checks them against the scene and adds the
onboard forward intersection (:class:`Apriori`). Output: a GeoPackage point layer
(:func:`write_gpkg` / :func:`read_gpkg`) in EPSG:4979 with Z, one feature per observation,
whose geometry is its point's onboard intersection (empty where it has one ray only).
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from osgeo import ogr

from ..errors import InputError
from ..files import OutputSet
from ..geodesy import ecef_to_geodetic
from ..model.intersection import MIN_CONVERGENCE, intersect
from ..validation import MAX_IMAGE_COORDINATE, implausible_image_coordinates, per_point, spread_problem
from ..vector_io import layer_to_wgs84_3d, open_layer, wgs84_3d, write_layer
from .tables import (SCENE_METADATA_KEY, csv_column, listed, nullable_floats, parse_numbers, per_point_sigmas, present,
                     read_delimited, require_finite, require_unique, resolve_cameras, stripped)

log = logging.getLogger(__name__)

DEFAULT_SIGMA_PX = 0.5
GPKG_LAYER = "tie_points"
# A point whose largest a-priori intersection residual exceeds both SUSPECT_FACTOR times the
# median of all points' largest residuals and SUSPECT_MIN_PX is likely mismatched: the onboard
# model's errors are mostly common to the cameras and alike over the scene (simulated TH-1, 4
# seeds x 200 points: median 4.5-7.0 px, the largest of a clean point at most 1.3 x the median),
# a mismatch adds its own size.
SUSPECT_FACTOR = 3.0
SUSPECT_MIN_PX = 5.0


@dataclass
class Apriori:
    """The onboard forward intersection of the tie points, per observation (n,): lon, lat (deg
    WGS84), h (m ellipsoidal) of its point, NaN where the point has fewer than two rays; rays:
    observations of its point; res_col, res_row, res_px: predicted minus measured (px) through
    the intersected point, NaN where it has none."""
    lon: np.ndarray
    lat: np.ndarray
    h: np.ndarray
    rays: np.ndarray
    res_col: np.ndarray
    res_row: np.ndarray
    res_px: np.ndarray
    FIELDS = ("lon", "lat", "h", "rays", "res_col", "res_row", "res_px")

    def select(self, mask) -> "Apriori":
        return Apriori(*(getattr(self, f)[mask] for f in self.FIELDS))


@dataclass
class TieTable:
    """Tie-point observations, parallel arrays of shape (n,): id (str; one id is one ground
    point), camera (camera name), col, row (GDAL px), sigma_px (px), scene (str: the scene of a
    strip the observation was measured in, '' when not stated; informational).
    ``apriori`` and ``scene_path`` (the scene file it was computed against) are set by
    :func:`check_against_scene`."""
    id: np.ndarray
    camera: np.ndarray
    col: np.ndarray
    row: np.ndarray
    sigma_px: np.ndarray
    scene: np.ndarray
    apriori: Apriori | None = None
    scene_path: str = ""
    ARRAYS = ("id", "camera", "col", "row", "sigma_px", "scene")

    def __post_init__(self):
        n = np.size(self.id)
        for name in self.ARRAYS:
            kind = str if name in ("id", "camera", "scene") else float
            setattr(self, name, np.broadcast_to(np.asarray(getattr(self, name), dtype=kind), (n,)).copy())
        if not (np.all(np.isfinite(self.col)) and np.all(np.isfinite(self.row))):
            raise InputError("tie-point image coordinates contain empty, NaN or infinite values")
        if not np.all(self.sigma_px > 0):
            raise InputError("tie-point image sigmas must be positive")

    def __len__(self) -> int:
        return int(self.id.size)

    def select(self, mask) -> "TieTable":
        apriori = None if self.apriori is None else self.apriori.select(mask)
        return TieTable(*(getattr(self, name)[mask] for name in self.ARRAYS), apriori=apriori,
                        scene_path=self.scene_path)

    def points(self) -> tuple[np.ndarray, np.ndarray]:
        """(ids (m,) sorted unique, index (n,) of each observation's point in ids)."""
        return np.unique(self.id, return_inverse=True)


@dataclass
class CsvMapping:
    """Which CSV columns hold what: id, camera, col, row; optional scene and sigma_px (px;
    empty cells take the sigma given to :func:`read_csv`). camera, scene None: the column
    ``camera`` (``scene``) when the file has one, else none (a single-camera scene; no scene
    named); scene '': none."""
    id: str = "id"
    camera: str | None = "camera"
    col: str = "col"
    row: str = "row"
    scene: str | None = None
    sigma_px: str | None = None


# --- reading ------------------------------------------------------------------------------
def build_table(ids, camera, col, row, *, scene=None, sigma_px=DEFAULT_SIGMA_PX,
                source: str = "tie-point input") -> TieTable:
    """A tie table from raw columns ((n,) arrays; camera and scene None: all ''). sigma_px: a
    number or (n,) px. ``source`` names the input in the messages. InputError for columns of
    different lengths (naming them: core.validation.per_point), empty ids, missing or non-finite
    image coordinates and coordinates beyond any image (naming the points)."""
    optional = {k: v for k, v in dict(camera=camera, scene=scene).items() if v is not None}
    ids, col, row, sigma_px, *given = per_point(ids=ids, col=col, row=row, sigma_px=sigma_px, **optional)
    camera, scene = (dict(zip(optional, given)).get(k) for k in ("camera", "scene"))
    ids = stripped(ids)
    if ids.size == 0:
        raise InputError(f"{source}: no tie points")
    if (ids == "").any():
        lines = (np.nonzero(ids == "")[0] + 1).astype(str)
        raise InputError(f"{source}: empty point id in data line(s) {listed(lines)}")
    col, row = np.asarray(col, dtype=float), np.asarray(row, dtype=float)
    require_finite(ids, source, col=col, row=row)
    bad = implausible_image_coordinates(col, row)
    if bad.any():
        raise InputError(f"{source}: col/row of point(s) {listed(ids[bad])} is beyond any image "
                         f"(|value| > {MAX_IMAGE_COORDINATE:g} px)")

    def texts(values):
        return np.full(ids.size, "") if values is None else stripped(values)

    return TieTable(ids, texts(camera), col, row, sigma_px, texts(scene))


def read_csv(path, mapping: CsvMapping | None = None, sigma_px: float = DEFAULT_SIGMA_PX) -> TieTable:
    """Tie points from a delimited text file with a header row (see :class:`CsvMapping`;
    columns it does not name are ignored)."""
    mapping = mapping or CsvMapping()
    path = Path(path)
    source = str(path)
    header, cells = read_delimited(path)

    def text(name: str | None):
        return None if name is None else csv_column(header, cells, name, source)

    ids = text(mapping.id)
    col, row = (parse_numbers(text(name), name, ids, source) for name in (mapping.col, mapping.row))
    sigmas = sigma_px if mapping.sigma_px is None else \
        per_point_sigmas(text(mapping.sigma_px), sigma_px, mapping.sigma_px, ids, source, "sigma_px")
    camera = mapping.camera if mapping.camera is not None else present(header, "camera")
    scene = mapping.scene if mapping.scene is not None else present(header, "scene")
    return build_table(ids, text(camera), col, row, scene=text(scene or None),
                       sigma_px=sigmas, source=source)


# --- checks against the scene -------------------------------------------------------------
def check_against_scene(table: TieTable, scene, scene_path: str = "", source: str = "tie points") -> TieTable:
    """The table checked against ``scene`` (a SceneModel), with its onboard forward
    intersection (:class:`Apriori`) and ``scene_path``.

    InputError: an empty table, a camera the scene lacks (listing the scene's cameras),
    duplicate observations (one id twice in one camera), observations outside their camera's
    image, all points in one image corner or on a line (the rule of
    :func:`core.validation.spread_problem`). Warnings (logged, the points kept): points seen
    in one camera only (not intersected; the adjustment leaves them out), points whose rays meet
    at less than MIN_CONVERGENCE (not intersected; the adjustment starts them from a height) and points with an
    implausible a-priori residual (:func:`suspect_points`, likely mismatched).
    """
    if len(table) == 0:
        raise InputError(f"{source}: no tie points")
    table = resolve_cameras(table, scene)
    require_unique(table.id, table.camera, source)
    names = [c.name for c in scene.cameras]
    camera = np.array([names.index(c) for c in table.camera.tolist()], dtype=np.int64)
    sizes = np.array([(c.cols, c.rows) for c in scene.cameras], dtype=float)[camera]
    x, y = table.col / sizes[:, 0], table.row / sizes[:, 1]
    outside = (x < 0) | (x > 1) | (y < 0) | (y > 1)
    if outside.any():
        cams = ", ".join(f"{c.name} {c.cols} x {c.rows}" for c in scene.cameras)
        raise InputError(f"{source}: observation(s) of point(s) {listed(_unique_ids(table.id[outside]))} lie "
                         f"outside their camera's image (cols x rows: {cams}); are they from another scene?")
    ids, point = table.points()
    if ids.size >= 3:
        problem = spread_problem(x, y, f"the {ids.size} tie points")
        if problem:
            raise InputError(f"{source}: {problem}")
    found = intersect(scene, camera, table.col, table.row, point, ids.size)
    lon, lat, h = ecef_to_geodetic(found.ground)
    res = found.residuals
    table = replace(table, apriori=Apriori(lon[point], lat[point], h[point], found.rays[point].astype(float),
                                           res[:, 0], res[:, 1], np.hypot(res[:, 0], res[:, 1])),
                    scene_path=str(scene_path))
    single = ids[found.rays < 2]
    if single.size:
        log.warning("%d tie point(s) seen in one camera only, kept in the layer but not intersected (the "
                    "adjustment leaves them out): %s", single.size, listed(single))
    weak = ids[found.weak]
    if weak.size:
        log.warning("%d tie point(s) whose rays meet at less than %g° (seen along one line), kept in the layer "
                    "but not intersected (the adjustment starts them from a height): %s", weak.size,
                    np.degrees(MIN_CONVERGENCE), listed(weak))
    if not found.converged:
        log.warning("the forward intersection did not converge in %d passes; the a-priori residuals are "
                    "approximate", found.iterations)
    suspect = suspect_points(table)
    if suspect.size:
        log.warning("%d tie point(s) with implausible a-priori intersection residuals (more than %.1f px, %g x "
                    "the median point's): likely mismatched points, check them: %s", suspect.size,
                    _suspect_threshold(table), SUSPECT_FACTOR, listed(suspect))
    return table


def _unique_ids(ids: np.ndarray) -> list[str]:
    return list(dict.fromkeys(ids.tolist()))


def _largest_residual_per_point(table: TieTable) -> tuple[np.ndarray, np.ndarray]:
    """(ids (m,), the largest a-priori residual (px) of each point's observations, NaN when not intersected)."""
    ids, point = table.points()
    res = np.where(np.isfinite(table.apriori.res_px), table.apriori.res_px, -1.0)
    largest = np.full(ids.size, -1.0)
    np.maximum.at(largest, point, res)
    return ids, np.where(largest >= 0, largest, np.nan)


def _suspect_threshold(table: TieTable) -> float:
    _, largest = _largest_residual_per_point(table)
    finite = largest[np.isfinite(largest)]
    return max(SUSPECT_MIN_PX, SUSPECT_FACTOR * float(np.median(finite))) if finite.size else np.inf


def suspect_points(table: TieTable) -> np.ndarray:
    """Ids of the points whose largest a-priori intersection residual exceeds
    max(SUSPECT_MIN_PX, SUSPECT_FACTOR x the median point's largest residual)."""
    ids, largest = _largest_residual_per_point(table)
    with np.errstate(invalid="ignore"):
        return ids[largest > _suspect_threshold(table)]


def summary(table: TieTable, by_scene: bool = False) -> dict:
    """Figures for the log: points, observations, cameras_per_point {rays: points}, single (points
    with one ray, left out), suspect (points likely mismatched), rms_px (a-priori residual RMS over
    the observations of intersected points, px; NaN without any), cameras {name: observations},
    pairs {"A-B": points seen by both cameras A and B} (cameras in the table's order of appearance).
    ``by_scene``: a camera is '<scene>/<camera>' (a block of scenes, whose cameras may share a
    name: every scene's 'NAD')."""
    ids, point = table.points()
    rays = np.bincount(point, minlength=ids.size)
    cameras = np.char.add(np.char.add(table.scene, "/"), table.camera) if by_scene else table.camera
    names, camera = np.unique(cameras, return_inverse=True)
    seen = np.zeros((ids.size, names.size), bool)
    seen[point, camera] = True
    shared = seen.T.astype(int) @ seen.astype(int)  # (cameras, cameras): points seen by both
    order = sorted(range(names.size), key=lambda k: int(np.argmax(camera == k)))
    out = {"points": int(ids.size), "observations": len(table),
           "cameras_per_point": {int(k): int(v) for k, v in zip(*np.unique(rays, return_counts=True))},
           "single": int(np.sum(rays < 2)), "cameras": dict(zip(*np.unique(cameras, return_counts=True))),
           "suspect": 0, "rms_px": float("nan"),
           "pairs": {f"{names[a]}-{names[b]}": int(shared[a, b]) for i, a in enumerate(order) for b in order[i + 1:]}}
    if table.apriori is not None:
        res = table.apriori.res_px[np.isfinite(table.apriori.res_px)]
        out["suspect"] = int(suspect_points(table).size)
        out["rms_px"] = float(np.sqrt(np.mean(res ** 2))) if res.size else float("nan")
    out["cameras"] = {str(k): int(v) for k, v in out["cameras"].items()}
    return out


# --- GeoPackage ---------------------------------------------------------------------------
_TEXT_FIELDS = ("id", "camera", "scene")
_NUMBER_FIELDS = ("col", "row", "sigma_px", "rays", "res_col", "res_row", "res_px")


def write_gpkg(table: TieTable, path, layer: str = GPKG_LAYER, files: OutputSet | None = None) -> None:
    """Write the table as a GeoPackage point layer, one feature per observation (replacing the
    file, completely or not at all; with ``files``, as part of that set).

    Geometry: Point Z (lon, lat, ellipsoidal h) in EPSG:4979 of the observation's point as the
    onboard model intersects it, empty where it has one ray (or no :class:`Apriori`). Fields: id,
    camera, col, row, sigma_px, scene, rays, res_col, res_row, res_px (NULL where not computed).
    The scene file of the intersection is the layer metadata item PUSHBROOM_SCENE."""
    a = table.apriori
    nan = np.full(len(table), np.nan)
    ground = (nan, nan, nan) if a is None else (a.lon, a.lat, a.h)
    columns = {"id": table.id, "camera": table.camera, "col": table.col, "row": table.row,
               "sigma_px": table.sigma_px, "scene": table.scene,
               "rays": nan if a is None else a.rays.astype(int),
               **{k: nan if a is None else getattr(a, k) for k in ("res_col", "res_row", "res_px")}}
    write_layer(path, layer, wgs84_3d(), ogr.wkbPoint25D, columns, point_wkt(*ground),
                {SCENE_METADATA_KEY: table.scene_path} if table.scene_path else None, files)


def point_wkt(lon, lat, h):
    """WKT Point Z per (n,) lon, lat (deg), h (m); POINT Z EMPTY where h is NaN (no ground position)."""
    # math.isfinite: numpy's costs a microsecond per Python float (600,000 points 2.5 -> 1.5 s)
    return (f"POINT Z ({lo!r} {la!r} {z!r})" if math.isfinite(z) else "POINT Z EMPTY"
            for lo, la, z in zip(*(np.asarray(v, float).tolist() for v in (lon, lat, h))))


def read_gpkg(path, layer: str | None = GPKG_LAYER) -> TieTable:
    """Read a tie-point layer written by :func:`write_gpkg` (or edited in QGIS): the observations,
    and their :class:`Apriori` when every feature has its rays (ground from the geometry, in
    EPSG:4979, NaN for an empty one)."""
    path = Path(path)
    ds, lyr = open_layer(path, layer)
    defn = lyr.GetLayerDefn()
    names = [defn.GetFieldDefn(i).GetName() for i in range(defn.GetFieldCount())]
    missing = [f for f in ("id", "camera", "col", "row") if f not in names]
    if missing:
        raise InputError(f"{path}: layer {lyr.GetName()!r} lacks tie-point field(s) {', '.join(missing)}")
    to_wgs = layer_to_wgs84_3d(lyr)
    wanted = [n for n in _TEXT_FIELDS + _NUMBER_FIELDS if n in names]
    records, coords = [], []
    for feat in lyr:  # OGR reads feature by feature
        records.append([feat.GetField(n) if feat.IsFieldSetAndNotNull(n) else None for n in wanted])
        coords.append(_point_lon_lat_h(feat.GetGeometryRef(), to_wgs, path, feat.GetField("id")))
    if not records:
        raise InputError(f"{path}: layer {lyr.GetName()!r} holds no tie points")
    cols = {n: [r[k] for r in records] for k, n in enumerate(wanted)}
    texts = {n: np.array(["" if v is None else str(v) for v in cols.get(n, [None] * len(records))])
             for n in _TEXT_FIELDS}
    numbers = {n: nullable_floats(cols.get(n, [None] * len(records))) for n in _NUMBER_FIELDS}
    sigma = np.where(np.isfinite(numbers["sigma_px"]), numbers["sigma_px"], DEFAULT_SIGMA_PX)
    table = build_table(texts["id"], texts["camera"], numbers["col"], numbers["row"], scene=texts["scene"],
                        sigma_px=sigma, source=str(path))
    table.scene_path = lyr.GetMetadataItem(SCENE_METADATA_KEY) or ""
    if np.isfinite(numbers["rays"]).all():
        lon, lat, h = np.array(coords, dtype=float).T
        table.apriori = Apriori(lon, lat, h, numbers["rays"], numbers["res_col"], numbers["res_row"],
                                numbers["res_px"])
    return table


def _point_lon_lat_h(geom, to_wgs, path, point_id) -> tuple[float, float, float]:
    """(lon, lat, h) of a feature's point geometry in EPSG:4979; NaN for a missing or empty one."""
    if geom is None or geom.IsEmpty():
        return np.nan, np.nan, np.nan
    if ogr.GT_Flatten(geom.GetGeometryType()) != ogr.wkbPoint:
        raise InputError(f"{path}: tie point {point_id!r} is a {geom.GetGeometryName().lower()}, not a point")
    if to_wgs is not None:
        geom = geom.Clone()
        geom.Transform(to_wgs)
    return geom.GetX(), geom.GetY(), geom.GetZ() if geom.Is3D() else np.nan
