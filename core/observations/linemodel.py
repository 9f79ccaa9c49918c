"""Control lines in the bundle adjustment: the observation model that lets it use lines beside
points, pairing image lines with ground lines, start values, checks against a scene and the check
that the lines determine both horizontal directions. The data are :mod:`core.observations.lines`.

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
line's image — what eq. 4 measures as an angle (tests/unit/observations/test_lines.py shows both on a
simulated scene). Unlike eq. 4 it needs no straight ground line: a polyline (a curved road)
associates each point with its nearest segment, refreshed every iteration
(:func:`line_constraints` with the current X_i), and the weight also holds the line's height.
Never is a straight line fitted in image space: the image of a straight road is not straight
for a pushbroom sensor (each row has its own perspective centre).

Statistics: a line point adds 2 ground constraints (not a GCP's 3); its redundancy share
follows from the eliminated system. Data snooping tests the across-line residual.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from osgeo import ogr

from ..errors import InputError
from ..geodesy import ecef_to_geodetic, enu_rotations, up_vector
from .lines import GroundLines, ImageLines
from .tables import listed

ogr.UseExceptions()
log = logging.getLogger(__name__)

MIN_DIRECTION_SPREAD_DEG = 5.0  # lines spreading less leave the along-line direction free


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
        raise InputError(f"{source}: line id(s) {listed(np.unique(image.line_id[unknown]))} pair with no ground "
                         f"line (ground line ids: {listed(keys)})")
    unused = ~np.isin(keys, image.line_id)
    if unused.any():
        log.info("%d ground line(s) shown on no image line: %s", int(unused.sum()), listed(keys[unused]))
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
            raise InputError(f"image points of line(s) {listed(np.unique(obs.keys[obs.key[missed]]))} see no ground "
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
        raise InputError(f"{source}: camera(s) {listed(np.unique(image.camera[unknown]))} of line(s) "
                         f"{listed(np.unique(image.line_id[unknown]))} are not in the scene (cameras: "
                         f"{', '.join(names)})")
    part = image.vertex_part()
    cols = np.array([scene.cameras[names.index(c)].cols for c in image.camera], float)[part]
    rows = np.array([scene.cameras[names.index(c)].rows for c in image.camera], float)[part]
    out = (image.col < 0) | (image.col > cols) | (image.row < 0) | (image.row > rows)
    if out.any():
        raise InputError(f"{source}: vertices of image line(s) {listed(np.unique(image.line_id[part[out]]))} lie "
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
        raise InputError(f"{source}: line(s) {listed(out)} lie outside the scene (no camera sees them)")


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
