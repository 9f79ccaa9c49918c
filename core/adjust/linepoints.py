"""Control lines in the bundle adjustment: line points as a third kind of point beside GCPs
and tie points (Tommaselli & Marcato Junior 2012, seed 002; the model is in :mod:`core.lines`).

Each point the user placed along an image line is one image observation (col, row) of a
ground point with three unknowns, eliminated per point like a GCP's (:mod:`core.adjust.normal`),
whose prior is the rank-2 weight of :func:`core.lines.line_constraints`: tied to the nearest
point of its ground polyline across the line (horizontal, sigma_across) and in height
(sigma_h), free along it. The association with the nearest segment is refreshed every time
the prior is evaluated (every iteration). Start values: each ray meets the surface of its
line's height (:func:`core.lines.start_points`).

Statistics. A line point adds 2 image + 2 line equations for 3 unknowns: one redundancy.
The along-line component of its image residual is absorbed by the free ground point, so the
image residual lies across the image of the line: data snooping of the point's image
residual is the test of its across-line residual. The variance components of the line group
are estimated for the across-line ("lines_across") and the height ("lines_height")
constraints, over the inlier points of the lines not flagged.

Wrong lines. A line from another road (or shifted in the map) moves all its points the same
way. Each point is tested by its across-line normalised residual w = d / (sigma_across
sqrt(r)) (d the misfit across the line, r its redundancy number; :func:`point_scores`). A line is named wrong as a
whole (:func:`flag_lines`) when more than half of its points fail the test, or when its
points that pass it fail together the chi-square test of their squared w at the
adjustment's alpha; as in iterated data snooping, each robust pass names only the worst
of the lines failing anew (those whose RMS w is within a factor 2 of the largest). Its
across-line constraint is then released as a unit (sigma_across
times RELEASE): its points become free single rays held at the line's height, with no
influence on the orientation, and their misfit d is then the across-line distance where
their rays meet the line's height. The test is repeated every robust pass on that misfit, so
a line released by a distorted first solution (e.g. while a wrong line kilometres off still
pulls it) comes back when it fits. Released lines are reported with their ids.

Directions. Lines fix positions across themselves only: when all run one way, a shift along
them is left to the points (or the onboard sigmas). :func:`core.lines.direction_check` of the
points' segments decides; the undetermined direction is named.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from ..geodesy import ecef_to_geodetic, enu_rotations
from ..observations.linemodel import (LineConstraint, LineObservations, LineSegments, azimuths, check_image_lines,
                                      check_in_scene, direction_check, line_constraints, lines_outside,
                                      nearest_segments, pair, segment_directions, start_points)
from ..observations.lines import GroundLines, ImageLines
from ..observations.tables import listed


log = logging.getLogger(__name__)

ACROSS_GROUP = "lines_across"
HEIGHT_GROUP = "lines_height"
RELEASE = 1e4          # factor on sigma_across of a line named wrong
SCREEN_MADS = 10.0      # a-priori screening: robust standard deviations of the lines' misfits
SCREEN_MIN_M = 50.0     # m: and at least this


@dataclass
class ControlLines:
    """The control lines of an adjustment: ground polylines and the image lines paired to
    them by id (:mod:`core.lines`)."""
    ground: GroundLines
    image: ImageLines


@dataclass
class LineSetUp:
    """The line points that enter the adjustment: obs (n points, :class:`core.lines.LineObservations`),
    seg (the ground lines' segments), camera (n,) camera indices, ground (n,3) ECEF m start
    values."""
    obs: LineObservations
    seg: LineSegments | None
    camera: np.ndarray
    ground: np.ndarray

    @classmethod
    def empty(cls) -> "LineSetUp":
        none = np.zeros(0)
        obs = LineObservations(np.zeros(0, str), np.zeros(0, np.int64), np.zeros(0, str), none, none, none,
                               np.zeros(0, np.int64), np.zeros(0, np.int64))
        return cls(obs, None, np.zeros(0, np.int64), np.zeros((0, 3)))

    def __len__(self) -> int:
        return len(self.obs)

    def line_ids(self) -> np.ndarray:
        """(n,) the ground line id of each point."""
        return self.obs.keys[self.obs.key]

    def constraints(self, x: np.ndarray, scale: dict, released: np.ndarray | None = None) -> LineConstraint:
        """The rank-2 priors of the points at ground positions x (n,3) ECEF m, with the line
        groups' variance-component factors in ``scale``; the across-line sigma of the lines
        ``released`` (K,) bool times RELEASE."""
        across = scale.get(ACROSS_GROUP, 1.0)
        if released is not None and released.any():
            across = across * np.where(released[self.obs.key], RELEASE, 1.0)
        return line_constraints(self.seg, self.obs.key, x, across, scale.get(HEIGHT_GROUP, 1.0))


def check_lines(scene, lines: ControlLines) -> None:
    """InputError naming image lines of unknown cameras or outside their image, ids that pair
    no ground line, and paired ground lines outside the scene."""
    check_image_lines(lines.image, scene)
    pair(lines.image, lines.ground)
    check_in_scene(lines.ground, scene, ids=np.unique(lines.image.line_id))


def datum_lines(lines: ControlLines | None) -> tuple[int, bool]:
    """(ground lines paired with image lines, whether their directions determine both horizontal
    directions): what the control lines can hold of a block's datum (:func:`core.adjust.ties.datum`)."""
    if lines is None or len(lines.image) == 0:
        return 0, False
    obs = pair(lines.image, lines.ground)
    ground = subset_lines(lines.ground, np.isin(lines.ground.id, obs.keys[np.unique(obs.key)]))
    return int(np.unique(ground.id).size), segment_directions(LineSegments.from_lines(ground)).determined


def set_up_lines(scene, lines: ControlLines | None) -> LineSetUp:
    """The line points (one per image-line vertex) and their start values."""
    if lines is None or len(lines.image) == 0:
        return LineSetUp.empty()
    obs = pair(lines.image, lines.ground)
    used = np.isin(lines.ground.id, obs.keys[np.unique(obs.key)])
    ground = subset_lines(lines.ground, used)
    seg = LineSegments.from_lines(ground)
    obs.key = np.searchsorted(seg.keys, obs.keys[obs.key])
    obs.keys = seg.keys
    camera = np.array([scene.camera_index(str(c)) for c in obs.camera], dtype=np.int64)
    return LineSetUp(obs, seg, camera, start_points(scene, obs, seg))


def subset_lines(ground: GroundLines, keep: np.ndarray) -> GroundLines:
    """The parts ``keep`` (k,) of ``ground``."""
    vertex = keep[ground.vertex_part()]
    counts = np.diff(ground.start)[keep]
    return GroundLines(ground.id[keep], np.r_[0, np.cumsum(counts)], ground.lon[vertex], ground.lat[vertex],
                       ground.h[vertex], ground.sigma_across[keep], ground.sigma_h[keep])


def screen(scene, setup: LineSetUp) -> np.ndarray:
    """(K,) lines whose a-priori misfit is grossly wrong (a line paired to a road kilometres off
    would otherwise pull the first solution far enough to hide itself among the others): the
    points' a-priori across-line offsets (rays through the onboard ``scene``, m) are fitted
    by an affine horizontal displacement field (the onboard error: shift, rotation, scale),
    iteratively trimmed; a line whose median residual exceeds SCREEN_MADS robust standard
    deviations of the lines' medians (and SCREEN_MIN_M) starts released. It comes back in the
    first pass where it fits (:func:`flag_lines`)."""
    offsets = ray_offsets(scene, setup)[:, 0]
    c = line_constraints(setup.seg, setup.obs.key, setup.ground)
    lon, lat, _ = ecef_to_geodetic(c.foot)
    east_north = np.einsum("nij,nj->ni", enu_rotations(lon, lat), c.across)[:, :2]
    p = np.einsum("nij,nj->ni", enu_rotations(lon[:1], lat[:1])[0][None], c.foot - c.foot[:1])[:, :2] / 1e4
    design = np.concatenate([east_north, east_north[:, :1] * p, east_north[:, 1:] * p], axis=1)  # (n, 6)
    key, k = setup.obs.key, setup.obs.keys.size
    keep = np.ones(offsets.size, bool)
    for _ in range(5):
        coef, *_ = np.linalg.lstsq(design[keep], offsets[keep], rcond=None)
        residual = offsets - design @ coef
        median = group_median(np.abs(residual), key, k)
        spread = 1.4826 * np.median(median)
        gross = median > max(SCREEN_MADS * spread, SCREEN_MIN_M)
        keep = ~gross[key]
    if gross.any():
        log.info("control lines %s start released: their a-priori misfit is grossly larger than the others'",
                 listed(setup.obs.keys[gross]))
    return gross


def group_median(values: np.ndarray, key: np.ndarray, k: int) -> np.ndarray:
    """Median (k,) of values (n,) per group key (n,) in [0, k) (0 for empty groups)."""
    order = np.lexsort((values, key))
    count = np.bincount(key, minlength=k)
    start = np.r_[0, np.cumsum(count)[:-1]]
    ordered = values[order]
    low = ordered[np.minimum(start + (count - 1) // 2, max(values.size - 1, 0))]
    high = ordered[np.minimum(start + count // 2, max(values.size - 1, 0))]
    return np.where(count > 0, 0.5 * (low + high), 0.0)


# --- statistics ------------------------------------------------------------------------------------


# --- checks against a scene and the report -------------------------------------------------------------
def ray_offsets(scene, setup: LineSetUp) -> np.ndarray:
    """(n, 2) per line point the across-line (horizontal) and height distance (m) of the point
    where its ray through ``scene`` meets its line's height, from the line: the a-priori (input
    scene) or a-posteriori (adjusted scene) misfit of the image line."""
    x = start_points(scene, setup.obs, setup.seg)
    c = line_constraints(setup.seg, setup.obs.key, x)
    return np.stack([c.d_across, c.d_normal], axis=1)


def per_line(setup: LineSetUp, across: np.ndarray, flagged_points: np.ndarray,
             flagged_lines: np.ndarray | None = None) -> dict:
    """Per ground line id with points (K,): line_id, points, rms and max of |across| (m),
    points flagged, flagged (the line named wrong)."""
    key, k = setup.obs.key, setup.obs.keys.size
    n = np.bincount(key, minlength=k)
    with np.errstate(invalid="ignore", divide="ignore"):
        rms = np.sqrt(np.bincount(key, weights=across ** 2, minlength=k) / n)
    largest = np.zeros(k)
    np.maximum.at(largest, key, np.abs(across))
    has = n > 0
    out = {"line_id": setup.obs.keys, "points": n, "rms_across_m": rms, "max_across_m": largest,
           "points_flagged": np.bincount(key, weights=flagged_points, minlength=k).astype(int),
           "flagged": np.zeros(k, bool) if flagged_lines is None else flagged_lines}
    return {name: values[has] for name, values in out.items()}


def directions(setup: LineSetUp, n_control: int) -> dict:
    """Whether the line points' lines determine both horizontal directions (weighted by
    1/sigma_across^2 per point), with a message naming the free direction; ``held`` says
    whether control points hold it anyway."""
    s, _ = nearest_segments(setup.seg, setup.obs.key, setup.ground)
    d = setup.seg.b[s] - setup.seg.a[s]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    check = direction_check(azimuths(0.5 * (setup.seg.a[s] + setup.seg.b[s]), d), setup.seg.sigma_across[s] ** -2.0)
    out = {"azimuth_deg": check.azimuth_deg, "spread_deg": check.spread_deg, "determined": check.determined,
           "message": check.message, "held_by_control_points": bool(not check.determined and n_control >= 3)}
    if not check.determined:
        out["message"] += (f"; the {n_control} control points hold it" if n_control >= 3 else
                           "; with fewer than 3 control points only the onboard sigmas hold it")
    return out


def check_against_scene(scene, lines: ControlLines) -> tuple[dict, dict, np.ndarray]:
    """What ``pushbroom:importlines`` writes: the lines checked (InputError as
    :func:`check_image_lines` / :func:`core.lines.pair`), per image vertex (n,) the a-priori
    across-line and height offsets (m, rays through ``scene``) and per ground line (K of the
    paired lines) their RMS and max, and the ids of ground lines outside every camera's
    footprint (sorted; legitimate when no image line pairs them)."""
    check_lines(scene, lines)
    setup = set_up_lines(scene, lines)
    offsets = ray_offsets(scene, setup)
    points = {"line_id": setup.line_ids(), "across_m": offsets[:, 0], "height_m": offsets[:, 1]}
    table = per_line(setup, offsets[:, 0], np.zeros(len(setup), bool))
    return points, table, lines_outside(lines.ground, scene)


