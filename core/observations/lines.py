"""Control lines: ground lines (roads, canals, field boundaries) and their images, and the
observation model that lets the bundle adjustment use them beside points.

Observation model (Tommaselli & Marcato Junior 2012, seed 002). Their line coplanarity model
(eq. 4) states that the ray of an image point p_i of a line lies in the plane through the
instantaneous perspective centre PC and the ground line P1 P2:

    N_i . R_j [0, y_i, -f]' = 0,      N_i = (P2 - P1) x (PC - P1).

Here each point the user places along an image line is one image observation (col, row) of
an unknown ground point X_i, as a GCP's, with a *rank-2* ground weight instead of a GCP's
full one: X_i is tied to the nearest point F_i of its ground polyline across the line
horizontally (sigma_across) and in height (sigma_h), and is free along it:

    W_i = a a' / sigma_across^2 + v v' / sigma_h^2          (ECEF, 1/m^2, rank 2)
    e_i = X_i - F_i                                         (misfit, m)

with d the unit direction of F_i's segment, a = unit(d x up) the horizontal across-line
direction and v = a x d (up for a level line, tilted with the slope otherwise); W_i d = 0.
Eliminating X_i per observation (the Schur complement of :mod:`core.adjust.normal`, which
takes any (m,3,3) weight in :class:`core.adjust.normal.GroundPrior`) leaves one constraint
per image point on the orientation: 2 image equations + 2 line equations - 3 unknowns. To
first order it is the coplanarity condition: when the ray misses the line, the eliminated
residual is the image distance, across the image of the line, of the measured point from the
line's image — what eq. 4 measures as an angle (tests/unit/test_lines.py shows both on a
simulated scene). Unlike eq. 4 it needs no straight ground line: a polyline (a curved road)
associates each point with its nearest segment, refreshed every iteration
(:func:`line_constraints` with the current X_i), and the weight also holds the line's height.
Never is a straight line fitted in image space: the image of a straight road is not straight
for a pushbroom sensor (each row has its own perspective centre).

Statistics: a line point adds 2 ground constraints (not a GCP's 3); its redundancy share
follows from the eliminated system. Data snooping tests the across-line residual.

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
from .gcps import Heights, _heights, _listed, _to_lonlat, parse_crs
from ..geodesy import ecef_to_geodetic, enu_rotations, geodetic_to_ecef, up_vector
from ..validation import MAX_IMAGE_COORDINATE, PLAUSIBLE_HEIGHTS, implausible_heights
from ..vector_io import LayerData, open_layer, write_layers

ogr.UseExceptions()
log = logging.getLogger(__name__)

GROUND_LAYER = "ground_lines"
IMAGE_LAYER = "image_lines"
DEFAULT_SIGMA_ACROSS = 2.0      # m
DEFAULT_SIGMA_H = 3.0           # m
DEFAULT_SIGMA_PX = 1.0          # px: a point clicked along an image line
MAX_SIGMA_M = 1e4
MAX_SIGMA_PX = 1e3
MIN_DIRECTION_SPREAD_DEG = 5.0  # lines spreading less leave the along-line direction free
PIXEL_FRAME_WKT = ('LOCAL_CS["Pushbroom image pixels (x = col, y = -row)",LOCAL_DATUM["raw image",32767],'
                   'UNIT["metre",1],AXIS["X",EAST],AXIS["Y",NORTH]]')
_M_PER_DEG = 111320.0


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
    camera (k,) str, start (k+1,) vertex offsets, col, row (V,) GDAL px, sigma_px (V,) px."""
    line_id: np.ndarray
    camera: np.ndarray
    start: np.ndarray
    col: np.ndarray
    row: np.ndarray
    sigma_px: np.ndarray

    def __post_init__(self):
        self.line_id = np.asarray(self.line_id, dtype=str)
        self.camera = np.broadcast_to(np.asarray(self.camera, dtype=str), self.line_id.shape).copy()
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
    heights: where heights come from (:class:`core.gcps.Heights`: the parts' z, a DEM or a
    constant, each with its datum). sigma_across, sigma_h: m, scalars or (k,).

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
        raise InputError(f"{source}: line(s) {_listed(np.unique(vid[bad]))} have empty or non-numeric coordinates")
    lon, lat = _to_lonlat(xy[:, 0], xy[:, 1], crs, vid, source)
    h = _heights(lon, lat, heights, z, vid, source)
    bad = implausible_heights(h)
    if bad.any():
        raise InputError(f"{source}: heights of line(s) {_listed(np.unique(vid[bad]))} are not terrain heights "
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
                      source: str = "image lines") -> ImageLines:
    """Image lines from raw parts: line_ids (k,) (the ground line each pairs to), parts a list
    of k arrays (n_i, 2) of (col, row) GDAL px, camera (k,) or one name, sigma_px: a scalar,
    (k,) per line, or a list of k arrays (n_i,) per vertex (px).

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
        raise InputError(f"{source}: image line(s) {_listed(np.unique(vid[bad]))} have empty or non-numeric "
                         "coordinates")
    bad = (np.abs(cr) > MAX_IMAGE_COORDINATE).any(axis=1)
    if bad.any():
        raise InputError(f"{source}: image line(s) {_listed(np.unique(vid[bad]))} have coordinates beyond any "
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
    return ImageLines(ids, camera, start, cr[keep, 0], cr[keep, 1], sigma[keep])


def _require_vertices(ids, start, source: str) -> None:
    single = np.diff(start) < 2
    if single.any():
        raise InputError(f"{source}: line(s) {_listed(ids[single])} have fewer than two vertices; a line needs at "
                         "least two")


def _require_sigmas(ids, source: str, largest: float, **columns) -> None:
    for name, values in columns.items():
        with np.errstate(invalid="ignore"):
            bad = ~((values > 0) & (values < largest))
        if bad.any():
            raise InputError(f"{source}: {name} of line(s) {_listed(np.unique(ids[bad]))} must be > 0 and below "
                             f"{largest:g} (got {values[bad][0]:g})")


def _local_metres(lon, lat, start) -> tuple[np.ndarray, np.ndarray]:
    """Plane coordinates (m) of vertices about their part's first vertex (for geometry checks)."""
    first = np.repeat(start[:-1], np.diff(start))
    lon0, lat0 = lon[first], lat[first]
    return ((lon - lon0 + 180.0) % 360.0 - 180.0) * _M_PER_DEG * np.cos(np.radians(lat0)), (lat - lat0) * _M_PER_DEG


def _drop_repeats(ids, start, x, y, source: str) -> tuple[np.ndarray, np.ndarray]:
    """(keep mask (V,), new start) without consecutive repeated vertices; InputError for parts
    that have no length."""
    part = np.repeat(np.arange(ids.size), np.diff(start))
    keep = np.ones(x.size, bool)
    keep[1:] = ~((part[1:] == part[:-1]) & (x[1:] == x[:-1]) & (y[1:] == y[:-1]))
    counts = np.bincount(part[keep], minlength=ids.size)
    if (counts < 2).any():
        raise InputError(f"{source}: line(s) {_listed(ids[counts < 2])} have zero length (all vertices at one place)")
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
        raise InputError(f"{source}: line(s) {_listed(crossing)} intersect themselves; split them where they cross")


# --- pairing ---------------------------------------------------------------------------------------
@dataclass
class LineObservations:
    """n image points of lines: key (n,) index into keys (K,) (sorted ground line ids, as
    :func:`LineSegments.from_lines`), camera (n,) str, col, row (n,) GDAL px, sigma_px (n,) px,
    image_line (n,) the image-line part and vertex (n,) the vertex index in ImageLines."""
    keys: np.ndarray
    key: np.ndarray
    camera: np.ndarray
    col: np.ndarray
    row: np.ndarray
    sigma_px: np.ndarray
    image_line: np.ndarray
    vertex: np.ndarray

    def __len__(self) -> int:
        return int(self.col.size)


def pair(image: ImageLines, ground: GroundLines, source: str = "image lines") -> LineObservations:
    """One observation per image-line vertex, paired to its ground line by id. InputError
    naming the image lines whose id is no ground line's; ground lines no image line shows are
    legitimate (a road map covers more) and only logged."""
    keys = ground.keys()
    unknown = ~np.isin(image.line_id, keys)
    if unknown.any():
        raise InputError(f"{source}: line id(s) {_listed(np.unique(image.line_id[unknown]))} pair with no ground "
                         f"line (ground line ids: {_listed(keys)})")
    unused = ~np.isin(keys, image.line_id)
    if unused.any():
        log.info("%d ground line(s) shown on no image line: %s", int(unused.sum()), _listed(keys[unused]))
    part = image.vertex_part()
    return LineObservations(keys, np.searchsorted(keys, image.line_id[part]), image.camera[part], image.col.copy(),
                            image.row.copy(), image.sigma_px.copy(), part, np.arange(part.size))


# --- segments, association and the rank-2 constraint ----------------------------------------------
@dataclass
class LineSegments:
    """The segments of ground lines, grouped by line id: keys (K,) sorted ids, key_start
    (K+1,) offsets into the segment arrays, a, b (S,3) ECEF end points (m), part (S,) the
    GroundLines part, sigma_across, sigma_h (S,) m."""
    keys: np.ndarray
    key_start: np.ndarray
    a: np.ndarray
    b: np.ndarray
    part: np.ndarray
    sigma_across: np.ndarray
    sigma_h: np.ndarray

    @classmethod
    def from_lines(cls, ground: GroundLines) -> "LineSegments":
        xyz = ground.ecef()
        vpart = ground.vertex_part()
        first = np.nonzero(vpart[1:] == vpart[:-1])[0]   # segment = vertex i -> i + 1 of one part
        part = vpart[first]
        keys = ground.keys()
        key = np.searchsorted(keys, ground.id[part])
        order = np.argsort(key, kind="stable")
        first, part, key = first[order], part[order], key[order]
        key_start = np.searchsorted(key, np.arange(keys.size + 1)).astype(np.int64)
        return cls(keys, key_start, xyz[first], xyz[first + 1], part, ground.sigma_across[part],
                   ground.sigma_h[part])


@dataclass
class LineConstraint:
    """The rank-2 ground constraint of n line points at ground points x (n,3) ECEF m:
    segment (n,) chosen segment, foot (n,3) nearest point on it (ECEF m), along, across,
    normal (n,3) unit ECEF directions (along the segment; horizontal across it; a x d, up for a
    level line), weight (n,3,3) ECEF 1/m^2 (zero along the line), misfit (n,3) = x - foot (m),
    d_across, d_normal (n,) m: the misfit's signed across-line and normal components."""
    segment: np.ndarray
    foot: np.ndarray
    along: np.ndarray
    across: np.ndarray
    normal: np.ndarray
    weight: np.ndarray
    misfit: np.ndarray
    d_across: np.ndarray
    d_normal: np.ndarray


def nearest_segments(seg: LineSegments, key: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(segment (n,), t (n,) in [0, 1]) of the nearest segment of each point's line ``key``
    (n,) to the ECEF points x (n,3), by horizontal distance (the local vertical at x removed,
    so a wrong height does not change the association); t places the foot a + t (b - a)."""
    key = np.asarray(key, dtype=np.int64)
    x = np.asarray(x, dtype=float)
    first, counts = seg.key_start[key], seg.key_start[key + 1] - seg.key_start[key]
    n = key.size
    obs = np.repeat(np.arange(n), counts)                            # every (point, candidate) pair
    offsets = np.r_[0, np.cumsum(counts)[:-1]]
    cand = first[obs] + np.arange(obs.size) - offsets[obs]
    lon, lat, _ = ecef_to_geodetic(x)
    up = up_vector(lon, lat)[obs]
    d = seg.b[cand] - seg.a[cand]
    w = x[obs] - seg.a[cand]
    dh = d - np.einsum("ni,ni->n", d, up)[:, None] * up
    wh = w - np.einsum("ni,ni->n", w, up)[:, None] * up
    t = np.clip(np.einsum("ni,ni->n", wh, dh) / np.einsum("ni,ni->n", dh, dh), 0.0, 1.0)
    dist2 = np.einsum("ni,ni->n", wh - t[:, None] * dh, wh - t[:, None] * dh)
    best = np.minimum.reduceat(dist2, offsets)
    winner = np.nonzero(dist2 == best[obs])[0]
    _, pick = np.unique(obs[winner], return_index=True)              # the first of equal candidates
    chosen = winner[pick]
    return cand[chosen], t[chosen]


def line_constraints(seg: LineSegments, key: np.ndarray, x: np.ndarray, across_factor: float = 1.0,
                     height_factor: float = 1.0) -> LineConstraint:
    """The rank-2 constraint (see the module docstring) of points x (n,3) ECEF on their lines
    ``key`` (n,): association with the nearest segment at the current x (call it every
    iteration), W = a a'/(sigma_across f_a)^2 + v v'/(sigma_h f_h)^2, misfit x - foot.
    across_factor, height_factor: variance-component factors on the stated sigmas."""
    x = np.asarray(x, dtype=float)
    s, t = nearest_segments(seg, key, x)
    d = seg.b[s] - seg.a[s]
    foot = seg.a[s] + t[:, None] * d
    along = d / np.linalg.norm(d, axis=1, keepdims=True)
    lon, lat, _ = ecef_to_geodetic(foot)
    across = np.cross(along, up_vector(lon, lat))
    across /= np.linalg.norm(across, axis=1, keepdims=True)
    normal = np.cross(across, along)
    wa = 1.0 / (seg.sigma_across[s] * across_factor) ** 2
    wn = 1.0 / (seg.sigma_h[s] * height_factor) ** 2
    weight = (wa[:, None, None] * across[:, :, None] * across[:, None, :]
              + wn[:, None, None] * normal[:, :, None] * normal[:, None, :])
    misfit = x - foot
    return LineConstraint(s, foot, along, across, normal, weight, misfit, np.einsum("ni,ni->n", misfit, across),
                          np.einsum("ni,ni->n", misfit, normal))


def start_points(scene, obs: LineObservations, seg: LineSegments, iterations: int = 6,
                 tol: float = 0.01) -> np.ndarray:
    """Start values (n,3) ECEF m of the line points' ground: each image point's ray through
    ``scene`` meets the surface of its line's height (first the line's mean height, then the
    height of the nearest point of the line, until it changes by less than tol m). InputError
    naming the lines whose rays miss the Earth."""
    n = len(obs)
    h = np.empty(n)
    seg_h = 0.5 * (ecef_to_geodetic(seg.a)[2] + ecef_to_geodetic(seg.b)[2])
    mean_h = np.add.reduceat(seg_h, seg.key_start[:-1]) / np.diff(seg.key_start)
    h[:] = mean_h[obs.key]
    cam = np.array([scene.camera_index(str(c)) for c in obs.camera]) if n else np.zeros(0, int)
    x = np.full((n, 3), np.nan)
    for _ in range(iterations):
        for c in np.unique(cam):
            m = cam == c
            x[m] = scene.image_to_ground(obs.col[m], obs.row[m], h[m], int(c))
        missed = ~np.isfinite(x).all(axis=1)
        if missed.any():
            raise InputError(f"image points of line(s) {_listed(np.unique(obs.keys[obs.key[missed]]))} see no ground "
                             "(their rays miss the Earth)")
        s, t = nearest_segments(seg, obs.key, x)
        new_h = ecef_to_geodetic(seg.a[s] + t[:, None] * (seg.b[s] - seg.a[s]))[2]
        done = np.max(np.abs(new_h - h)) < tol
        h = new_h
        if done:
            break
    return x


def coplanarity_residual(scene, camera, col, row, p1: np.ndarray, p2: np.ndarray) -> np.ndarray:
    """Seed 002 eq. 4 for image points (col, row) (n,) of camera ``camera``: the sine of the
    angle (rad) between each point's ray and the plane through the perspective centre PC and
    the straight ground line p1 -> p2 (ECEF, (3,) or (n,3)): N . u / |N| with
    N = (p2 - p1) x (PC - p1), u the unit ray (the geometric direction: velocity aberration
    removed, as eq. 4 is a condition on straight rays; refraction, a few microradians off
    nadir, is left in)."""
    _, pc, v, u = scene.line_of_sight(col, row, scene.camera_index(camera))
    u = scene._geometric_ray(pc, v, u, np.linalg.norm(np.asarray(p1, float) - pc, axis=-1))
    normal = np.cross(np.asarray(p2, float) - p1, pc - np.asarray(p1, float))
    return np.einsum("ni,ni->n", normal, u) / np.linalg.norm(normal, axis=1)


# --- checks against a scene -----------------------------------------------------------------------
def check_image_lines(image: ImageLines, scene, source: str = "image lines") -> None:
    """InputError naming image lines whose camera the scene lacks or whose vertices lie
    outside their camera's image."""
    names = [c.name for c in scene.cameras]
    unknown = ~np.isin(image.camera, names)
    if unknown.any():
        raise InputError(f"{source}: camera(s) {_listed(np.unique(image.camera[unknown]))} of line(s) "
                         f"{_listed(np.unique(image.line_id[unknown]))} are not in the scene (cameras: "
                         f"{', '.join(names)})")
    part = image.vertex_part()
    cols = np.array([scene.cameras[names.index(c)].cols for c in image.camera], float)[part]
    rows = np.array([scene.cameras[names.index(c)].rows for c in image.camera], float)[part]
    out = (image.col < 0) | (image.col > cols) | (image.row < 0) | (image.row > rows)
    if out.any():
        raise InputError(f"{source}: vertices of image line(s) {_listed(np.unique(image.line_id[part[out]]))} lie "
                         "outside the image")


def lines_outside(ground: GroundLines, scene, samples: int = 65) -> np.ndarray:
    """Ids (sorted) of ground lines none of whose parts reaches any camera's footprint (the
    image border seen at the lines' mean height)."""
    h = float(np.mean(ground.h))
    footprints = []
    for k, cam in enumerate(scene.cameras):
        s = np.linspace(0.0, 1.0, samples)
        col = np.concatenate([s * cam.cols, np.full_like(s, cam.cols), (1 - s) * cam.cols, np.zeros_like(s)])
        row = np.concatenate([np.zeros_like(s), s * cam.rows, np.full_like(s, cam.rows), (1 - s) * cam.rows])
        lon, lat, _ = ecef_to_geodetic(scene.image_to_ground(col, row, h, k))
        ring = ogr.Geometry(ogr.wkbLinearRing)
        for a, b in zip(lon.tolist() + lon[:1].tolist(), lat.tolist() + lat[:1].tolist()):
            ring.AddPoint_2D(a, b)
        poly = ogr.Geometry(ogr.wkbPolygon)
        poly.AddGeometry(ring)
        footprints.append(poly)
    inside = set()
    for i in range(len(ground)):  # one GEOS test per line and camera
        geom = ogr.Geometry(ogr.wkbLineString)
        sl = slice(ground.start[i], ground.start[i + 1])
        for a, b in zip(ground.lon[sl].tolist(), ground.lat[sl].tolist()):
            geom.AddPoint_2D(a, b)
        if any(f.Intersects(geom) for f in footprints):
            inside.add(str(ground.id[i]))
    return np.array(sorted(set(ground.id.tolist()) - inside), dtype=str)


def check_in_scene(ground: GroundLines, scene, ids=None, source: str = "ground lines") -> None:
    """InputError naming the ground lines (all, or those with ``ids``: the paired ones)
    outside every camera's footprint."""
    out = lines_outside(ground, scene)
    if ids is not None:
        out = out[np.isin(out, np.asarray(ids, dtype=str))]
    if out.size:
        raise InputError(f"{source}: line(s) {_listed(out)} lie outside the scene (no camera sees them)")


# --- directions --------------------------------------------------------------------------------------
@dataclass
class DirectionCheck:
    """How the lines' across-line constraints spread over horizontal directions.
    azimuth_deg: the direction the lines run along, in [0, 180) (clockwise from north);
    spread_deg: atan(sqrt(lambda_min / lambda_max)) of the across-line information (about the
    RMS angle of the lines about that direction); determined: spread >= the threshold;
    message: for the report, naming the undetermined direction when not determined."""
    azimuth_deg: float
    spread_deg: float
    determined: bool
    message: str


def direction_check(azimuth, weight=None, min_spread_deg: float = MIN_DIRECTION_SPREAD_DEG) -> DirectionCheck:
    """Whether lines running along azimuths (n,) rad (clockwise from north) with weights (n,)
    (e.g. 1/sigma_across^2 of each point) determine both horizontal directions: lines alone
    fix only positions across themselves, so when they all run one way a shift along them is
    free (unless points fix it)."""
    az = np.asarray(azimuth, dtype=float)
    w = np.ones_like(az) if weight is None else np.asarray(weight, dtype=float)
    if az.size == 0:
        return DirectionCheck(float("nan"), 0.0, False, "no lines")
    across = np.stack([np.cos(az), -np.sin(az)], axis=1)           # (east, north) across each line
    info = np.einsum("n,ni,nj->ij", w, across, across)
    values, vectors = np.linalg.eigh(info)
    weak = vectors[:, 0]                                             # (east, north) least determined
    azimuth_deg = float(np.degrees(np.arctan2(weak[0], weak[1])) % 180.0)
    spread = float(np.degrees(np.arctan(np.sqrt(max(values[0], 0.0) / values[1])))) if values[1] > 0 else 0.0
    determined = spread >= min_spread_deg
    message = (f"the lines run in directions spread by {spread:.1f} deg: both horizontal directions are determined"
               if determined else
               f"all lines run within {spread:.1f} deg of azimuth {azimuth_deg:.1f} deg (clockwise from north): a "
               f"shift along azimuth {azimuth_deg:.1f} deg is not determined by the lines; add points or lines "
               "running across them")
    return DirectionCheck(azimuth_deg, spread, determined, message)


def azimuths(foot: np.ndarray, along: np.ndarray) -> np.ndarray:
    """Azimuths (n,) rad clockwise from north of ECEF directions ``along`` (n,3) at ``foot`` (n,3)."""
    lon, lat, _ = ecef_to_geodetic(foot)
    enu = np.einsum("nij,nj->ni", enu_rotations(lon, lat), along)
    return np.arctan2(enu[:, 0], enu[:, 1])


def segment_directions(seg: LineSegments) -> DirectionCheck:
    """:func:`direction_check` of all segments weighted by length / sigma_across^2."""
    d = seg.b - seg.a
    length = np.linalg.norm(d, axis=1)
    return direction_check(azimuths(0.5 * (seg.a + seg.b), d / length[:, None]), length / seg.sigma_across ** 2)


# --- GeoPackage ----------------------------------------------------------------------------------
def _wgs84_3d() -> osr.SpatialReference:
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(4979)
    srs.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    return srs


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
    return LayerData(GROUND_LAYER, _wgs84_3d(), ogr.wkbLineString25D, columns, geoms)


def image_layer(image: ImageLines, extra: dict | None = None) -> LayerData:
    """The ``image_lines`` layer of ``image``: LineString M (x = col, y = -row, M = sigma px);
    the field sigma_px holds each line's median vertex sigma."""
    geoms = []
    sigma = np.zeros(len(image))
    for i in range(len(image)):
        sl = slice(image.start[i], image.start[i + 1])
        sigma[i] = float(np.median(image.sigma_px[sl]))
        coords = ", ".join(f"{c!r} {-r!r} {s!r}" for c, r, s in zip(image.col[sl].tolist(), image.row[sl].tolist(),
                                                                       image.sigma_px[sl].tolist()))
        geoms.append(f"LINESTRING M ({coords})")
    columns = {"line_id": image.line_id, "camera": image.camera, "sigma_px": sigma, **(extra or {})}
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
                     sigma_px: float = DEFAULT_SIGMA_PX) -> ImageLines:
    """Image lines from a line layer in the pixel frame (x = col, y = -row): the ground line
    id from ``id_field``, the camera from ``camera_field`` (or ``camera`` for all), each
    vertex's sigma from its M value when > 0, else the line's sigma_px field, else
    ``sigma_px``. A vertex with y > 0 is refused: the layer is not in the pixel frame."""
    ds, lyr = open_layer(path, layer)
    present = [lyr.GetLayerDefn().GetFieldDefn(i).GetName() for i in range(lyr.GetLayerDefn().GetFieldCount())]
    ds = lyr = None
    fields = {"id": id_field, "camera": camera_field if camera_field in present else None,
              "sigma": "sigma_px" if "sigma_px" in present else None}
    values, parts, _, ds = _features(path, layer, fields)
    ids = np.array(["" if v is None else str(v) for v in values["id"]])
    positive = [i for i, (p, _) in enumerate(parts) if (p[:, 1] > 1e-9).any()]
    if positive:
        raise InputError(f"{path}: image line(s) {_listed(ids[positive])} have y > 0; image lines are stored as "
                         "x = column, y = -row (the pixel frame QGIS shows for a raw image), so y is negative")
    cams = np.array([camera or ("" if v is None else str(v)) for v in values["camera"]])
    sigmas = []
    for (p, m), s in zip(parts, values["sigma"]):
        line_sigma = sigma_px if s is None or not s > 0 else float(s)
        m = np.zeros(len(p)) if m is None else m
        sigmas.append(np.where(np.isfinite(m) & (m > 0), m, line_sigma))
    return build_image_lines(ids, [np.stack([p[:, 0], -p[:, 1]], axis=1) for p, _ in parts], cams, sigmas, str(path))
