"""Tie points in the bundle adjustment: which observations enter, their ground start values,
and how the datum of a block with few or no GCPs is held.

A tie point is a ground point of unknown position measured in two or more cameras (or
scenes of a strip). It enters the adjustment as three ground unknowns without a prior
(zero ground weight; with a reference DEM a prior on its height alone, :mod:`core.adjust.tieheights`),
eliminated per point like a weighted GCP (:mod:`core.adjust.normal`),
started from the forward intersection of its onboard rays (:mod:`core.intersection`).
A point seen once carries no geometric information (its ray fixes no ground position), and a
point whose a-priori intersection fails (NaN) has no start value: both are left out, named. A point
whose rays meet at too small an angle to fix its height (:data:`core.model.intersection.MIN_CONVERGENCE`:
consecutive products of one strip) stays in: its rays still tie the products across and along
track. It starts on its first ray at a height: the reference DEM's where there is one, otherwise the
median height of the intersected tie points (the scene's mean height without any); the report counts
them (``from_height``) and the log names a few. Its height is then held by the reference DEM, or
without one by the ridge of the point's near-singular ray block (:mod:`core.adjust.normal`).

Datum (seed 001 with 1 GCP; seed 003 sec. 3.2 with 0 or 4 GCPs): tie points fix the shape of
the block, not where it is. The seven datum components (shift X/Y/Z, three rotations, scale)
must each be held by GCPs or by the onboard pseudo-observations (:func:`datum`); a component
held by neither is a datum defect, refused with its name rather than left to drift.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..geodesy import ecef_to_geodetic, enu_rotation
from ..model.intersection import MIN_CONVERGENCE, intersect
from ..model.sensor import SceneModel, rows_by
from ..observations.tiepoints import TieTable
from ..observations.tables import listed
from ..rotations import ARCSEC
from .parameters import ParameterSet
from .tieheights import TieHeights

log = logging.getLogger(__name__)

SHIFTS = ("shift X", "shift Y", "shift Z")
ROTATIONS = ("roll (rotation about the flight line)", "pitch", "yaw")
SCALE = ("scale",)
YAW_TABLE_STEP = 0.5  # s: trajectory table step of the scenes yaw_hold differences
EDGE = 2.0   # px: measurement noise may put a point at the image border this far outside
# Passes of a weak point's start onto the reference DEM (each puts it on its ray at the DEM's height under
# the last): a near-nadir ray's error shrinks by the slope times the tangent of its view angle per pass
DEM_PASSES = 4
BUNCHED = 0.1  # tie points within this share of the image in both directions are in one corner


@dataclass
class TieSetUp:
    """The tie observations that enter the adjustment. table: the input TieTable (n obs);
    rows (k,) indices into it of the observations used; camera (k,) camera indices; point
    (k,) index into ids / ground; ids (p,) the points used; ground (p,3) ECEF m start values
    (forward intersection on the input scene); left_out: reason -> ids of the points left out
    (``single_ray``: seen by one camera; ``not_intersected``: a-priori intersection failed);
    before (n, 2) px: every input observation's residual (col, row) at that intersection,
    through the input scene (NaN for points left out); heights: the reference DEM that holds
    their heights (:mod:`core.adjust.tieheights`; None: none); from_height: the ids of the points
    started on their first ray at a height (near-parallel rays) and that height's source."""
    table: TieTable
    rows: np.ndarray
    camera: np.ndarray
    point: np.ndarray
    ids: np.ndarray
    ground: np.ndarray
    left_out: dict
    before: np.ndarray
    heights: TieHeights | None = None
    from_height: tuple = (np.zeros(0, str), "")

    @classmethod
    def empty(cls) -> "TieSetUp":
        none = np.zeros(0, np.int64)
        table = TieTable(np.zeros(0, str), np.zeros(0, str), np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0, str))
        return cls(table, none, none, none, np.zeros(0, str), np.zeros((0, 3)), {}, np.zeros((0, 2)))

    def __len__(self) -> int:
        return int(self.rows.size)

    def span(self, scene: SceneModel) -> tuple[float, float] | None:
        """Share of the reference camera's image (columns, rows) the used tie observations in it
        cover (None: none there)."""
        mine = self.camera == 0
        if not mine.any():
            return None
        cam, rows = scene.cameras[0], self.rows[mine]
        return (float(np.ptp(self.table.col[rows])) / cam.cols, float(np.ptp(self.table.row[rows])) / cam.rows)

    def counts(self) -> dict:
        """Points and observations used and left out (with reasons), for the report."""
        return {"points": int(self.ids.size), "observations": int(self.rows.size),
                "input_observations": len(self.table),
                "left_out": {reason: {"points": int(ids.size), "ids": [str(i) for i in ids[:1000]]}
                             for reason, ids in self.left_out.items() if ids.size},
                "from_height": {"points": int(self.from_height[0].size), "height": self.from_height[1],
                                "held_by_dem": self.heights is not None,
                                "min_convergence_deg": float(np.degrees(MIN_CONVERGENCE)),
                                "ids": [str(i) for i in self.from_height[0][:1000]]}}


def camera_indices(scene: SceneModel, names: np.ndarray) -> np.ndarray:
    """Indices (n,) of the camera names (n,) in ``scene`` (all names must be the scene's)."""
    cams = [c.name for c in scene.cameras]
    order = np.argsort(cams)
    return order[np.searchsorted(np.asarray(cams)[order], names)]


def check_ties(scene: SceneModel, ties: TieTable, gcp_ids: np.ndarray) -> None:
    """Refuse tie observations the adjustment cannot use, naming them: cameras the scene
    lacks, positions outside the camera's image (beyond EDGE px), the same point twice in one camera, and ids
    that are also GCP ids (one id is one ground point: known or unknown, not both)."""
    names = [c.name for c in scene.cameras]
    unknown = ~np.isin(ties.camera, names)
    if unknown.any():
        raise InputError(f"tie points: camera(s) {listed(np.unique(ties.camera[unknown]))} of point(s) "
                         f"{listed(np.unique(ties.id[unknown]))} not in the scene (cameras: {', '.join(names)})",
                         parameter="ties")
    cam = camera_indices(scene, ties.camera)
    cols = np.array([c.cols for c in scene.cameras])[cam]
    rows = np.array([c.rows for c in scene.cameras])[cam]
    outside = (ties.col < -EDGE) | (ties.col > cols + EDGE) | (ties.row < -EDGE) | (ties.row > rows + EDGE)
    if outside.any():
        raise InputError(f"tie points: {int(outside.sum())} observation(s) of point(s) "
                         f"{listed(np.unique(ties.id[outside]))} lie outside their camera's image (by more than "
                         f"{EDGE:g} px)", parameter="ties")
    ids, point = np.unique(ties.id, return_inverse=True)
    pairs, counts = np.unique(point * len(names) + cam, return_counts=True)  # (point, camera) as one integer
    if (counts > 1).any():
        twice = ids[np.unique(pairs[counts > 1] // len(names))]
        raise InputError(f"tie points: point(s) {listed(twice)} are observed more than once in the same camera "
                         "(duplicate observations); keep one observation per point and camera", parameter="ties")
    shared = np.intersect1d(ties.id, gcp_ids)
    if shared.size:
        raise InputError(f"tie points: id(s) {listed(shared)} are also GCP ids; a tie point is a point of unknown "
                         "ground position: give it another id, or measure it as a GCP", parameter="ties")


def set_up_ties(scene: SceneModel, ties: TieTable | None, heights: TieHeights | None = None,
                rays: tuple[np.ndarray, np.ndarray] | None = None) -> TieSetUp:
    """The tie observations used and their points' start values (see the module docstring), their
    heights held to the reference DEM ``heights`` (None: not); warns naming the points left out and
    why. ``rays``: the observations' onboard rays (:func:`core.model.intersection.onboard_rays`)
    when the caller has them."""
    if ties is None or len(ties) == 0:
        return TieSetUp.empty()
    ids, point = ties.points()
    camera = camera_indices(scene, ties.camera)
    start = intersect(scene, camera, ties.col, ties.row, point, ids.size, rays)
    single = start.rays < 2
    source = ""
    if start.weak.any():
        source = start_from_height(scene, ties, camera, point, start, heights)
        log.warning("%d tie point(s) whose rays meet at less than %g° (seen along one line, e.g. by "
                    "consecutive products of one strip) fix no height: they start on their first ray at %s: %s",
                    int(start.weak.sum()), np.degrees(MIN_CONVERGENCE), source, listed(ids[start.weak]))
    failed = ~single & ~np.all(np.isfinite(start.ground), axis=1)
    left_out = {"single_ray": ids[single], "not_intersected": ids[failed]}
    if single.any():
        log.warning("%d tie point(s) seen by one camera only are left out (one ray fixes no ground position): %s",
                    int(single.sum()), listed(ids[single]))
    if failed.any():
        log.warning("%d tie point(s) whose onboard rays could not be intersected are left out: %s",
                    int(failed.sum()), listed(ids[failed]))
    keep = ~(single | failed)
    new_index = np.cumsum(keep) - 1
    rows = np.nonzero(keep[point])[0]
    out = TieSetUp(ties, rows, camera[rows], new_index[point[rows]], ids[keep], start.ground[keep], left_out,
                   start.residuals, heights, (ids[start.weak & keep], source))
    if heights is not None:
        heights.check_covers(out.ground)
    span = out.span(scene)
    if span is not None and max(span) < BUNCHED:
        log.warning("the tie points cover only %.0f%% x %.0f%% of the %s image (one corner): they tie the block "
                    "there only; the rest follows the onboard trajectory and the GCPs", 100 * span[0], 100 * span[1],
                    scene.cameras[0].name)
    return out


def start_from_height(scene: SceneModel, ties: TieTable, camera: np.ndarray, point: np.ndarray, start,
                      heights: TieHeights | None) -> str:
    """Put the weak points of the intersection ``start`` (:class:`core.model.intersection.Intersection`,
    its ground changed in place) on their first observation's ray (``camera``, ``point`` (n,) per
    observation of ``ties``) at a height: the reference DEM's (``heights``), otherwise, and where the
    ray misses the DEM, the median ellipsoidal height of the intersected points, or the scene's mean
    height without any. Returns where the height came from, in words."""
    weak = np.nonzero(start.weak)[0]
    _, first = np.unique(point, return_index=True)  # the first observation of each point (all points have one)
    obs = first[weak]
    fine = np.all(np.isfinite(start.ground), axis=1)
    if fine.any():
        h = float(np.median(ecef_to_geodetic(start.ground[fine])[2]))
        source = f"the median height of the {int(fine.sum())} intersected tie points ({h:.1f} m)"
    else:
        h = float(np.mean(scene.height_range))
        source = f"the scene's mean height ({h:.1f} m; no tie point is intersected)"
    level = np.full(weak.size, h)
    for _ in range(DEM_PASSES if heights is not None else 1):
        ground = on_rays(scene, camera[obs], ties.col[obs], ties.row[obs], level)
        if heights is not None:
            lon, lat, _ = ecef_to_geodetic(ground)
            below = heights.surface.height(lon, lat)
            level = np.where(np.isfinite(below), below, level)
    if heights is not None:
        source = f"the reference DEM's height ({heights.surface.path}; off it, {source})"
    start.ground[weak] = ground
    return source


def on_rays(scene: SceneModel, camera: np.ndarray, col: np.ndarray, row: np.ndarray, height: np.ndarray) -> np.ndarray:
    """ECEF points (k,3) m on the rays of image points (col, row (k,) px in cameras ``camera`` (k,)) at
    ellipsoidal heights ``height`` (k,) m."""
    ground = np.full((col.size, 3), np.nan)
    for c, m in enumerate(rows_by(camera, len(scene.cameras))):
        if m.size:
            ground[m] = scene.image_to_ground(col[m], row[m], height[m], c)
    return ground


RPC_PRIOR = "RPC correction priors"  # the datum source of settings.rpc_sigma
REFERENCE_DEM = "reference DEM"  # the datum source of settings.tie_height_sigma (the tie points' heights)


def datum(n_control: int, position_sigma: float | None, attitude_sigma: float | None,
          n_lines: int = 0, lines_determined: bool = False, rpc_images: int = 0,
          rpc_sigma: float | None = None, tie_height_sigma: float | None = None) -> dict:
    """How the datum (shift X/Y/Z, roll, pitch, yaw, scale) of a block with tie points is held,
    for ``n_control`` control points (at least 3 are checked for spread elsewhere), ``n_lines``
    control lines (``lines_determined``: their directions determine both horizontal directions,
    :func:`core.lines.direction_check`), the onboard pseudo-observations (sigmas None: none; a
    block of RPC images alone has none) and, for a block with ``rpc_images`` RPC images, the prior
    on their corrections (``rpc_sigma``, px: the vendor's stated accuracy) and a reference DEM holding
    the tie points' heights (``tie_height_sigma``, m; :mod:`core.adjust.tieheights`). Raises InputError
    naming the components nothing holds and the setting that would.

    Control points: 3 or more well spread hold all; 2 all but the rotation about the line
    through them; 1 the shifts. Control lines in several directions hold all (each fixes its
    points across the line and in height, and lines spread over the scene fix the rotations
    and the scale as points do); lines that all run one way leave the shift along them, the
    yaw and the scale free and hold the height, roll and pitch only. Onboard positions
    (pseudo-observations of the orbit, hundreds of km above the ground) hold the shifts, the
    scale, pitch and yaw; roll about the flight line leaves them in place, so it needs a GCP
    (off that line), lines or the attitude. Onboard attitude holds the three rotations. The RPC
    images' prior holds all: a move of the whole block moves every image's ground, which their
    corrections would have to follow (tie points alone leave the common part of the images'
    shifts, and with drift or affine terms their common rotation and scale, free). A reference DEM
    holds the height shift and the tilts (roll, pitch) of the tie points' heights."""
    held: dict[str, list[str]] = {c: [] for c in SHIFTS + ROTATIONS + SCALE}
    extra_missing = []

    def hold(source: str, components) -> None:
        for c in components:
            held[c].append(source)

    if n_control >= 2:
        hold("control points", SHIFTS + ROTATIONS + SCALE)
    elif n_control == 1:
        hold("control points", SHIFTS)
    if n_lines:
        hold("control lines", SHIFTS + ROTATIONS + SCALE if lines_determined else SHIFTS[2:] + ROTATIONS[:2])
    if position_sigma is not None:
        hold("onboard positions", SHIFTS + SCALE + ROTATIONS[1:] + (ROTATIONS[:1] if n_control else ()))
    if attitude_sigma is not None:
        hold("onboard attitude", ROTATIONS)
    if rpc_images and rpc_sigma is not None:
        hold(RPC_PRIOR, SHIFTS + ROTATIONS + SCALE)
    if tie_height_sigma is not None:
        hold(REFERENCE_DEM, SHIFTS[2:] + ROTATIONS[:2])
    if n_control == 2 and position_sigma is None and attitude_sigma is None and not (n_lines and lines_determined) \
            and not (rpc_images and rpc_sigma is not None):
        extra_missing.append("rotation about the line through the 2 control points")
    missing = [c for c, sources in held.items() if not sources] + extra_missing
    if missing:
        _refuse_datum(missing, n_control, position_sigma, attitude_sigma, n_lines, lines_determined, rpc_images)
    sources = {s for v in held.values() for s in v}
    named = [name for name, present in (("control points", "control points" in sources),
                                        ("control lines", "control lines" in sources),
                                        ("onboard pseudo-observations", any(s.startswith("onboard") for s in sources)),
                                        (f"{RPC_PRIOR} ({rpc_sigma} px, the RPC images' stated accuracy)",
                                         RPC_PRIOR in sources),
                                        (f"{REFERENCE_DEM} ({tie_height_sigma:g} m, TIE_HEIGHT_SIGMA)"
                                         if tie_height_sigma is not None else "", REFERENCE_DEM in sources))
             if present]
    by = named[0] if len(named) == 1 else ", ".join(named[:-1]) + " and " + named[-1]
    out = {"held_by": by, "control_points": n_control, "control_lines": n_lines, "components": held}
    absolute = " and ".join(filter(None, (
        "the onboard orbit and attitude (the pseudo-observations' sigmas)" if position_sigma or attitude_sigma else "",
        "the RPC images' stated accuracy (RPC_SIGMA)" if RPC_PRIOR in sources else "",
        "in height the reference DEM's (TIE_HEIGHT_SIGMA)" if REFERENCE_DEM in sources else "")))
    if not n_control and not n_lines:
        out["note"] = ("no control points: the tie points fix the block's relative geometry only; its absolute "
                       f"accuracy is that of {absolute}")
    elif n_control < 3:
        rest = " and ".join(name for name in named if name != "control points")
        who = f"{n_control} control point(s): the datum components they do not hold are" if n_control else \
            "no control points: the datum is"
        out["note"] = (f"{who} held by the {rest}"
                       + (", at the onboard accuracy" if rest == "onboard pseudo-observations" else ""))
    return out


def _refuse_datum(missing: list[str], n_control: int, position_sigma, attitude_sigma, n_lines: int,
                  lines_determined: bool, rpc_images: int) -> None:
    """The InputError of a datum defect: the components nothing holds and what would hold them."""
    trajectories = not rpc_images or position_sigma is not None or attitude_sigma is not None
    need = []
    if trajectories and any(c in SHIFTS + SCALE for c in missing):
        need.append("POSITION_SIGMA (onboard position accuracy, m)")
    if trajectories and any(c not in SHIFTS + SCALE for c in missing):
        need.append("ATTITUDE_SIGMA (onboard attitude accuracy)")
    if rpc_images:
        need.append("RPC_SIGMA (the vendor's stated accuracy of the RPC images, px)")
    pseudo = [name for name, s in (("positions", position_sigma), ("attitude", attitude_sigma)) if s is not None]
    given = "onboard pseudo-observations of the " + " and ".join(pseudo) if pseudo else \
        "no onboard pseudo-observations"
    if rpc_images:
        given += f" and no prior on the corrections of its {rpc_images} RPC image(s)"
    lines = f", {n_lines} control line(s)" + ("" if lines_determined else " all running one way") \
        if n_lines else ""
    raise InputError(
        f"datum defect: with {n_control} control point(s){lines} and {given}, the tie points fix the block's "
        f"shape but not {', '.join(missing)}; the adjustment would drift freely in them. Give "
        f"{' or '.join(need) if rpc_images else ' and '.join(need)}, or at least 3 well spread GCPs",
        parameter="settings.rpc_sigma" if rpc_images and not trajectories else "")


def yaw_hold(params: ParameterSet, covariance: np.ndarray, grid: int = 3) -> dict:
    """How well the solution holds the block's yaw (its rotation about the vertical through the
    first camera's image centre), from the posterior covariance ``covariance`` (k,k) of the
    unknowns ``params.free`` (sigma0^2 Q, SI units) at the current (adjusted) values.

    The rotation is read from the ground a ``grid`` x ``grid`` lattice of the first camera's
    image sees at the scene's mean height: theta = sum(e dn - n de) / sum(e^2 + n^2) over the
    points' local east/north (m) about their centre, a linear function of the unknowns whose
    gradient is taken by central differences of one posterior sigma each. Returns sigma_arcsec,
    edge_m (its displacement at the lattice point farthest from the centre: the scene's corner)
    and radius_m (that distance)."""
    scene = params.scene
    cam = scene.cameras[0]
    col, row = (a.ravel() for a in np.meshgrid(np.linspace(0, cam.cols, grid), np.linspace(0, cam.rows, grid)))
    height = np.full(col.size, float(np.mean(scene.height_range)))
    base = params.values()
    free = params.free
    step = np.sqrt(np.clip(covariance.diagonal(), 0.0, None))

    def ground(values: np.ndarray) -> np.ndarray:
        params.set_values(values)
        scene = params.adjusted_scene()
        # A coarse trajectory table: tabulating the whole strip at its fine step for 9 points
        # would cost a quarter second per parameter; the interpolation error is common to the
        # two sides of each difference (the same grid), so it cancels.
        for platform in filter(None, (scene.platform_of(c) for c in range(len(scene.cameras)))):
            platform.cache_step = YAW_TABLE_STEP  # an RPC image of a block has none
        return scene.image_to_ground(col, row, height, 0)

    try:
        g0 = ground(base)
        lon, lat, _ = ecef_to_geodetic(g0.mean(axis=0))
        to_en = enu_rotation(float(lon), float(lat))[:2]                     # (2,3) east, north rows
        en = (g0 - g0.mean(axis=0)) @ to_en.T                                 # (p,2) m
        weights = np.stack([-en[:, 1], en[:, 0]], axis=1) / np.sum(en ** 2)   # d theta / d(east, north)
        gradient = np.zeros(free.size)
        # the others (another scene's trajectory in a block, other cameras' terms) move nothing here
        for j in np.nonzero((step > 0) & params.imaged_by(0)[free])[0]:
            up, down = base.copy(), base.copy()
            up[free[j]] += step[j]
            down[free[j]] -= step[j]
            moved = (ground(up) - ground(down)) @ to_en.T / (2.0 * step[j])
            gradient[j] = np.sum(weights * moved)
    finally:
        params.set_values(base)
    sigma = float(np.sqrt(max(gradient @ covariance @ gradient, 0.0)))
    radius = float(np.sqrt(np.sum(en ** 2, axis=1)).max())
    return {"sigma_arcsec": sigma / ARCSEC, "edge_m": sigma * radius, "radius_m": radius}


def yaw_sentence(yaw: dict) -> str:
    """The yaw figure of :func:`yaw_hold` in words."""
    return (f"the yaw (block rotation about the vertical) is held to {yaw['sigma_arcsec']:.1f} arcsec (posterior "
            f"sigma), {yaw['edge_m']:.2f} m at the scene's corners {yaw['radius_m'] / 1000:.1f} km from its centre")
