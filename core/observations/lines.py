"""Control lines: ground lines (roads, canals, field boundaries) and their images, as data,
built and checked from raw parts and read from and written to GeoPackage layers. How the bundle
adjustment uses them is :mod:`core.observations.linemodel`.

Data:
- :class:`GroundLines`: polylines of WGS84 (lon, lat) degrees and ellipsoidal heights (m),
  per part; several parts may share an id (a multi-part feature); per-part sigma_across
  (horizontal, m) and sigma_h (height, m).
- :class:`ImageLines`: polylines in pixel coordinates (col, row; GDAL convention: (0, 0) is
  the upper-left corner of the upper-left pixel, rows grow downwards) in a named camera,
  paired to a ground line by ``line_id``; every vertex is one observation with its own sigma
  (px).
- GeoPackage (OGR only): layer ``ground_lines`` (LineString Z, EPSG:4979, fields line_id,
  sigma_across, sigma_h) and layer ``image_lines`` (LineString M in the engineering frame
  "Pushbroom image pixels": x = col, y = -row, as QGIS shows a raw image without
  georeferencing, so y is negative; M = the vertex's sigma in px, 0 or empty = the line's
  sigma_px field; fields line_id, camera, sigma_px).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from osgeo import ogr, osr

from ..errors import InputError
from ..files import OutputSet
from ..geodesy import geodetic_to_ecef
from ..validation import MAX_IMAGE_COORDINATE, PLAUSIBLE_HEIGHTS, implausible_heights
from ..vector_io import LayerData, open_layer, wgs84_3d, write_layers
from .tables import Heights, ellipsoidal_heights, listed, parse_crs, to_lonlat

ogr.UseExceptions()
log = logging.getLogger(__name__)

GROUND_LAYER = "ground_lines"
IMAGE_LAYER = "image_lines"
DEFAULT_SIGMA_ACROSS = 2.0      # m
DEFAULT_SIGMA_H = 3.0           # m
DEFAULT_SIGMA_PX = 1.0          # px: a point clicked along an image line
MAX_SIGMA_M = 1e4
MAX_SIGMA_PX = 1e3
PIXEL_FRAME_WKT = ('LOCAL_CS["Pushbroom image pixels (x = col, y = -row)",LOCAL_DATUM["raw image",32767],'
                   'UNIT["metre",1],AXIS["X",EAST],AXIS["Y",NORTH]]')
M_PER_DEG = 111320.0  # m per degree of latitude, and of longitude at the equator (local plane checks)


# --- the data --------------------------------------------------------------------------------------
@dataclass
class GroundLines:
    """Ground polylines, one row per part. id (k,) str (parts of one feature share it),
    start (k+1,) int offsets of each part's vertices in lon, lat, h (V,) (WGS84 deg,
    ellipsoidal m), sigma_across, sigma_h (k,) m."""
    id: np.ndarray
    start: np.ndarray
    lon: np.ndarray
    lat: np.ndarray
    h: np.ndarray
    sigma_across: np.ndarray
    sigma_h: np.ndarray

    def __post_init__(self):
        self.id = np.asarray(self.id, dtype=str)
        self.start = np.asarray(self.start, dtype=np.int64)
        k = self.id.size
        for name in ("lon", "lat", "h"):
            setattr(self, name, np.asarray(getattr(self, name), dtype=float))
        for name in ("sigma_across", "sigma_h"):
            setattr(self, name, np.broadcast_to(np.asarray(getattr(self, name), dtype=float), (k,)).copy())
        _require_layout(self.start, k, self.lon.size)

    def __len__(self) -> int:
        return int(self.id.size)

    def vertex_part(self) -> np.ndarray:
        """(V,) index of each vertex's part."""
        return np.repeat(np.arange(len(self)), np.diff(self.start))

    def ecef(self) -> np.ndarray:
        """Vertices as ECEF metres (V, 3)."""
        return geodetic_to_ecef(self.lon, self.lat, self.h)

    def keys(self) -> np.ndarray:
        """Sorted unique line ids: what image lines pair to."""
        return np.unique(self.id)


@dataclass
class ImageLines:
    """Image polylines, one row per part. line_id (k,) str (the ground line it pairs to),
    camera (k,) str, start (k+1,) vertex offsets, col, row (V,) GDAL px, sigma_px (V,) px;
    scene (k,) str: in a block of scenes (:mod:`core.adjust.block`) the name of the product each
    line was measured in ('' when not named: one scene)."""
    line_id: np.ndarray
    camera: np.ndarray
    start: np.ndarray
    col: np.ndarray
    row: np.ndarray
    sigma_px: np.ndarray
    scene: np.ndarray | None = None

    def __post_init__(self):
        self.line_id = np.asarray(self.line_id, dtype=str)
        self.camera = np.broadcast_to(np.asarray(self.camera, dtype=str), self.line_id.shape).copy()
        self.scene = np.char.strip(np.broadcast_to(np.asarray("" if self.scene is None else self.scene, dtype=str),
                                                   self.line_id.shape).copy())
        self.start = np.asarray(self.start, dtype=np.int64)
        self.col, self.row = np.asarray(self.col, dtype=float), np.asarray(self.row, dtype=float)
        self.sigma_px = np.broadcast_to(np.asarray(self.sigma_px, dtype=float), self.col.shape).copy()
        _require_layout(self.start, self.line_id.size, self.col.size)

    def __len__(self) -> int:
        return int(self.line_id.size)

    def vertex_part(self) -> np.ndarray:
        """(V,) index of each vertex's part."""
        return np.repeat(np.arange(len(self)), np.diff(self.start))


def _require_layout(start: np.ndarray, parts: int, vertices: int) -> None:
    if start.shape != (parts + 1,) or start[0] != 0 or start[-1] != vertices or np.any(np.diff(start) < 0):
        raise ValueError(f"vertex offsets {start[:5]}... do not describe {parts} parts of {vertices} vertices")


def _offsets(parts) -> np.ndarray:
    return np.r_[0, np.cumsum([len(p) for p in parts])].astype(np.int64)


# --- building and checking ----------------------------------------------------------------------
def build_ground_lines(ids, parts, *, crs, heights: Heights, sigma_across=DEFAULT_SIGMA_ACROSS,
                       sigma_h=DEFAULT_SIGMA_H, source: str = "ground lines") -> GroundLines:
    """Ground lines from raw parts: ids (k,), parts a list of k arrays (n_i, 2) x, y or (n_i, 3)
    x, y, z in ``crs`` (any EPSG code, WKT or PROJ string; x = easting/longitude).
    heights: where heights come from (:class:`core.observations.tables.Heights`: the parts' z, a
    DEM or a constant, each with its datum). sigma_across, sigma_h: m, scalars or (k,).

    InputError, naming ``source`` and the line ids, for: no CRS (a layer without CRS), a
    vertex that cannot be converted, a part with one vertex, a zero-length or
    self-intersecting part, non-positive sigmas. Consecutive repeated vertices (a double
    click) are dropped.
    """
    ids = np.char.strip(np.asarray(ids, dtype=str))
    if crs is None or not str(crs).strip():
        raise InputError(f"{source}: the line layer has no CRS; set the layer's CRS (e.g. EPSG:4326) so its "
                         "coordinates can be placed on the ground")
    parse_crs(crs, source)
    if (ids == "").any():
        raise InputError(f"{source}: {int((ids == '').sum())} line(s) without an id")
    parts = [np.atleast_2d(np.asarray(p, dtype=float)) for p in parts]
    start = _offsets(parts)
    xy = np.concatenate([p[:, :2] for p in parts]) if parts else np.zeros((0, 2))
    z = np.concatenate([p[:, 2] for p in parts]) if parts and all(p.shape[1] > 2 for p in parts) else None
    vid = np.repeat(ids, np.diff(start))
    _require_vertices(ids, start, source)
    bad = ~np.isfinite(xy).all(axis=1)
    if bad.any():
        raise InputError(f"{source}: line(s) {listed(np.unique(vid[bad]))} have empty or non-numeric coordinates")
    lon, lat = to_lonlat(xy[:, 0], xy[:, 1], crs, vid, source)
    h = ellipsoidal_heights(lon, lat, heights, z, vid, source)
    bad = implausible_heights(h)
    if bad.any():
        raise InputError(f"{source}: heights of line(s) {listed(np.unique(vid[bad]))} are not terrain heights "
                         f"({PLAUSIBLE_HEIGHTS[0]:g} to {PLAUSIBLE_HEIGHTS[1]:g} m ellipsoidal)")
    k = ids.size
    sig_a = np.broadcast_to(np.asarray(sigma_across, dtype=float), (k,))
    sig_h = np.broadcast_to(np.asarray(sigma_h, dtype=float), (k,))
    _require_sigmas(ids, source, MAX_SIGMA_M, sigma_across=sig_a, sigma_h=sig_h)
    x, y = _local_metres(lon, lat, start)
    keep, start = _drop_repeats(ids, start, x, y, source)
    _require_simple(ids, start, x[keep], y[keep], source)
    return GroundLines(ids, start, lon[keep], lat[keep], h[keep], sig_a, sig_h)


def build_image_lines(line_ids, parts, camera, sigma_px=DEFAULT_SIGMA_PX,
                      source: str = "image lines", scene=None) -> ImageLines:
    """Image lines from raw parts: line_ids (k,) (the ground line each pairs to), parts a list
    of k arrays (n_i, 2) of (col, row) GDAL px, camera (k,) or one name, sigma_px: a scalar,
    (k,) per line, or a list of k arrays (n_i,) per vertex (px); scene (k,) or one name: the
    product of a block each line was measured in (None: '', one scene).

    InputError, naming ``source`` and the line ids, for: a part with one vertex, empty or
    non-numeric coordinates, coordinates no image reaches, a zero-length or self-intersecting
    part, sigmas that are not positive. Consecutive repeated vertices are dropped.
    """
    ids = np.char.strip(np.asarray(line_ids, dtype=str))
    if (ids == "").any():
        raise InputError(f"{source}: {int((ids == '').sum())} image line(s) without a line id (the id of the "
                         "ground line it shows)")
    parts = [np.atleast_2d(np.asarray(p, dtype=float)) for p in parts]
    start = _offsets(parts)
    _require_vertices(ids, start, source)
    cr = np.concatenate([p[:, :2] for p in parts]) if parts else np.zeros((0, 2))
    vid = np.repeat(ids, np.diff(start))
    bad = ~np.isfinite(cr).all(axis=1)
    if bad.any():
        raise InputError(f"{source}: image line(s) {listed(np.unique(vid[bad]))} have empty or non-numeric "
                         "coordinates")
    bad = (np.abs(cr) > MAX_IMAGE_COORDINATE).any(axis=1)
    if bad.any():
        raise InputError(f"{source}: image line(s) {listed(np.unique(vid[bad]))} have coordinates beyond any "
                         f"image (|value| > {MAX_IMAGE_COORDINATE:g} px)")
    if isinstance(sigma_px, (list, tuple)):
        sigma = np.concatenate([np.broadcast_to(np.asarray(s, dtype=float), (len(p),))
                                for s, p in zip(sigma_px, parts)])
    else:
        s = np.asarray(sigma_px, dtype=float)
        sigma = np.repeat(np.broadcast_to(s, (ids.size,)), np.diff(start)) if s.ndim <= 1 and s.size in (1, ids.size) \
            else s
    _require_sigmas(vid, source, MAX_SIGMA_PX, sigma_px=sigma)
    keep, start = _drop_repeats(ids, start, cr[:, 0], cr[:, 1], source)
    _require_simple(ids, start, cr[keep, 0], cr[keep, 1], source)
    return ImageLines(ids, camera, start, cr[keep, 0], cr[keep, 1], sigma[keep], scene)


def _require_vertices(ids, start, source: str) -> None:
    single = np.diff(start) < 2
    if single.any():
        raise InputError(f"{source}: line(s) {listed(ids[single])} have fewer than two vertices; a line needs at "
                         "least two")


def _require_sigmas(ids, source: str, largest: float, **columns) -> None:
    for name, values in columns.items():
        with np.errstate(invalid="ignore"):
            bad = ~((values > 0) & (values < largest))
        if bad.any():
            raise InputError(f"{source}: {name} of line(s) {listed(np.unique(ids[bad]))} must be > 0 and below "
                             f"{largest:g} (got {values[bad][0]:g})")


def _local_metres(lon, lat, start) -> tuple[np.ndarray, np.ndarray]:
    """Plane coordinates (m) of vertices about their part's first vertex (for geometry checks)."""
    first = np.repeat(start[:-1], np.diff(start))
    lon0, lat0 = lon[first], lat[first]
    return ((lon - lon0 + 180.0) % 360.0 - 180.0) * M_PER_DEG * np.cos(np.radians(lat0)), (lat - lat0) * M_PER_DEG


def _drop_repeats(ids, start, x, y, source: str) -> tuple[np.ndarray, np.ndarray]:
    """(keep mask (V,), new start) without consecutive repeated vertices; InputError for parts
    that have no length."""
    part = np.repeat(np.arange(ids.size), np.diff(start))
    keep = np.ones(x.size, bool)
    keep[1:] = ~((part[1:] == part[:-1]) & (x[1:] == x[:-1]) & (y[1:] == y[:-1]))
    counts = np.bincount(part[keep], minlength=ids.size)
    if (counts < 2).any():
        raise InputError(f"{source}: line(s) {listed(ids[counts < 2])} have zero length (all vertices at one place)")
    if (~keep).any():
        log.info("%s: %d repeated vertices dropped", source, int((~keep).sum()))
    return keep, np.r_[0, np.cumsum(counts)].astype(np.int64)


def _require_simple(ids, start, x, y, source: str) -> None:
    """InputError for parts that cross or touch themselves (a closed ring is accepted)."""
    crossing = []
    for i in range(ids.size):  # one GEOS test per line, not per vertex
        geom = ogr.Geometry(ogr.wkbLineString)
        for px, py in zip(x[start[i]:start[i + 1]].tolist(), y[start[i]:start[i + 1]].tolist()):
            geom.AddPoint_2D(px, py)
        if not geom.IsSimple():
            crossing.append(ids[i])
    if crossing:
        raise InputError(f"{source}: line(s) {listed(crossing)} intersect themselves; split them where they cross")


# --- GeoPackage ----------------------------------------------------------------------------------
def pixel_frame() -> osr.SpatialReference:
    """The engineering frame of image-line layers: x = col, y = -row (GDAL px)."""
    srs = osr.SpatialReference()
    srs.SetFromUserInput(PIXEL_FRAME_WKT)
    return srs


def ground_layer(ground: GroundLines, extra: dict | None = None) -> LayerData:
    """The ``ground_lines`` layer of ``ground`` (extra: {field: (k,) array})."""
    geoms = []
    for i in range(len(ground)):
        sl = slice(ground.start[i], ground.start[i + 1])
        coords = ", ".join(f"{a!r} {b!r} {c!r}" for a, b, c in zip(ground.lon[sl].tolist(), ground.lat[sl].tolist(),
                                                                       ground.h[sl].tolist()))
        geoms.append(f"LINESTRING Z ({coords})")
    columns = {"line_id": ground.id, "sigma_across": ground.sigma_across, "sigma_h": ground.sigma_h, **(extra or {})}
    return LayerData(GROUND_LAYER, wgs84_3d(), ogr.wkbLineString25D, columns, geoms)


def image_layer(image: ImageLines, extra: dict | None = None) -> LayerData:
    """The ``image_lines`` layer of ``image``: LineString M (x = col, y = -row, M = sigma px);
    the field sigma_px holds each line's median vertex sigma; the field ``scene`` (the product of a
    block each line was measured in) only when a line names one, so that a single scene's layer
    keeps the fields it always had."""
    geoms = []
    sigma = np.zeros(len(image))
    for i in range(len(image)):
        sl = slice(image.start[i], image.start[i + 1])
        sigma[i] = float(np.median(image.sigma_px[sl]))
        coords = ", ".join(f"{c!r} {-r!r} {s!r}" for c, r, s in zip(image.col[sl].tolist(), image.row[sl].tolist(),
                                                                       image.sigma_px[sl].tolist()))
        geoms.append(f"LINESTRING M ({coords})")
    scene = {"scene": image.scene} if (image.scene != "").any() else {}
    columns = {"line_id": image.line_id, "camera": image.camera, "sigma_px": sigma, **scene, **(extra or {})}
    return LayerData(IMAGE_LAYER, pixel_frame(), ogr.wkbLineStringM, columns, geoms)


def write_gpkg(path, ground: GroundLines | None = None, image: ImageLines | None = None,
               extra_ground: dict | None = None, extra_image: dict | None = None, extra_layers=(),
               files: OutputSet | None = None) -> None:
    """One GeoPackage with the layers ``ground_lines`` and/or ``image_lines`` (and any further
    :class:`core.vector_io.LayerData`), written completely or not at all."""
    layers = ([ground_layer(ground, extra_ground)] if ground is not None else []) + \
        ([image_layer(image, extra_image)] if image is not None else []) + list(extra_layers)
    write_layers(path, layers, files)


def _parts(geom, fid, path) -> list:
    """(xyz (n, 2|3) as stored, m (n,) or None) of the parts of a line geometry."""
    flat = ogr.GT_Flatten(geom.GetGeometryType())
    if flat == ogr.wkbLineString:
        n = geom.GetPointCount()
        xyz = np.array(geom.GetPoints() or [], dtype=float).reshape(n, -1)
        m = np.array([geom.GetM(i) for i in range(n)], dtype=float) if geom.IsMeasured() else None
        return [(xyz[:, :3] if geom.Is3D() else xyz[:, :2], m)]
    if flat == ogr.wkbMultiLineString:
        return [p for k in range(geom.GetGeometryCount()) for p in _parts(geom.GetGeometryRef(k), fid, path)]
    raise InputError(f"{path}: feature {fid} is a {geom.GetGeometryName().lower()}, not a line")


def _features(path, layer, fields: dict):
    """(values {key: list per part}, parts [(xyz, m)], srs, data source) of a line layer:
    fields {key: field name or None}; a None id field gives feature ids."""
    ds, lyr = open_layer(path, layer)
    defn = lyr.GetLayerDefn()
    names = [defn.GetFieldDefn(i).GetName() for i in range(defn.GetFieldCount())]
    for key, name in fields.items():
        if name is not None and name not in names:
            raise InputError(f"{path}: layer {lyr.GetName()!r} has no field {name!r} (fields: {', '.join(names)})")
    values, parts = {k: [] for k in fields}, []
    for feat in lyr:  # OGR reads feature by feature
        geom = feat.GetGeometryRef()
        if geom is None:
            raise InputError(f"{path}: feature {feat.GetFID()} has no geometry")
        for p in _parts(geom, feat.GetFID(), path):
            parts.append(p)
            for key, name in fields.items():
                v = feat.GetField(name) if name is not None and feat.IsFieldSetAndNotNull(name) else None
                values[key].append(str(feat.GetFID()) if key == "id" and name is None else v)
    if not parts:
        raise InputError(f"{path}: layer {lyr.GetName()!r} holds no lines")
    srs = lyr.GetSpatialRef()
    return values, parts, srs, ds


def read_ground_lines(path, layer: str | None = GROUND_LAYER, id_field: str | None = "line_id",
                      heights: Heights | None = None, sigma_across: float = DEFAULT_SIGMA_ACROSS,
                      sigma_h: float = DEFAULT_SIGMA_H, sigma_across_field: str | None = "sigma_across",
                      sigma_h_field: str | None = "sigma_h") -> GroundLines:
    """Ground lines from any OGR line layer (LineString or MultiLineString, 2D or 3D) in any
    CRS: ids from ``id_field`` (None: feature ids), heights as ``heights`` says (default: the
    geometry's Z, ellipsoidal), sigmas from the fields when present and set, else the given
    values. Defaults read the layer :func:`write_gpkg` writes. A layer without CRS is refused."""
    fields = {"id": id_field, "sigma_across": sigma_across_field, "sigma_h": sigma_h_field}
    ds, lyr = open_layer(path, layer)
    present = [lyr.GetLayerDefn().GetFieldDefn(i).GetName() for i in range(lyr.GetLayerDefn().GetFieldCount())]
    ds = lyr = None
    fields = {k: (v if (k == "id" or v in present) else None) for k, v in fields.items()}
    values, parts, srs, ds = _features(path, layer, fields)
    heights = heights or Heights("z", "ellipsoid")
    if heights.source == "z" and any(p.shape[1] < 3 for p, _ in parts):
        raise InputError(f"{path}: the lines have no Z values; take their heights from a DEM or a constant")
    crs = srs.ExportToWkt() if srs is not None else None  # layer coordinates are x = easting/longitude
    sig_a = np.array([sigma_across if v is None else v for v in values["sigma_across"]], dtype=float)
    sig_h = np.array([sigma_h if v is None else v for v in values["sigma_h"]], dtype=float)
    return build_ground_lines(values["id"], [p for p, _ in parts], crs=crs, heights=heights, sigma_across=sig_a,
                              sigma_h=sig_h, source=str(path))


def read_image_lines(path, layer: str | None = IMAGE_LAYER, id_field: str = "line_id",
                     camera_field: str | None = "camera", camera: str = "",
                     sigma_px: float = DEFAULT_SIGMA_PX, scene_field: str | None = "scene") -> ImageLines:
    """Image lines from a line layer in the pixel frame (x = col, y = -row): the ground line
    id from ``id_field``, the camera from ``camera_field`` (or ``camera`` for all), the product
    of a block each line was measured in from ``scene_field`` when the layer has it (else, and
    where NULL, ''), each vertex's sigma from its M value when > 0, else the line's sigma_px
    field, else ``sigma_px``. A vertex with y > 0 is refused: the layer is not in the pixel
    frame."""
    ds, lyr = open_layer(path, layer)
    present = [lyr.GetLayerDefn().GetFieldDefn(i).GetName() for i in range(lyr.GetLayerDefn().GetFieldCount())]
    ds = lyr = None
    fields = {"id": id_field, "camera": camera_field if camera_field in present else None,
              "sigma": "sigma_px" if "sigma_px" in present else None,
              "scene": scene_field if scene_field in present else None}
    values, parts, _, ds = _features(path, layer, fields)
    ids = np.array(["" if v is None else str(v) for v in values["id"]])
    positive = [i for i, (p, _) in enumerate(parts) if (p[:, 1] > 1e-9).any()]
    if positive:
        raise InputError(f"{path}: image line(s) {listed(ids[positive])} have y > 0; image lines are stored as "
                         "x = column, y = -row (the pixel frame QGIS shows for a raw image), so y is negative")
    cams = np.array([camera or ("" if v is None else str(v)) for v in values["camera"]])
    sigmas = []
    for (p, m), s in zip(parts, values["sigma"]):
        line_sigma = sigma_px if s is None or not s > 0 else float(s)
        m = np.zeros(len(p)) if m is None else m
        sigmas.append(np.where(np.isfinite(m) & (m > 0), m, line_sigma))
    scenes = np.array(["" if v is None else str(v) for v in values["scene"]], dtype=str)
    return build_image_lines(ids, [np.stack([p[:, 0], -p[:, 1]], axis=1) for p, _ in parts], cams, sigmas, str(path),
                             scene=scenes)
