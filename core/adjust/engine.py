"""Self-calibrating bundle adjustment of one scene (or strip) from ground control points and
tie points (ground points of unknown position, :mod:`core.adjust.ties`).

Gauss-Newton with Levenberg-Marquardt damping on the reduced normal equations (ground
points eliminated, :mod:`core.adjust.normal`), analytic derivatives (:mod:`core.adjust.model`).
Onboard GPS and star-tracker values enter as pseudo-observations of the trajectory
corrections at the knots (seed 000 eq. 7-8); weighted interior parameters as
pseudo-observations of value 0. Before solving, the parameters are checked for
determinability: sets that the observations cannot separate (seed 000 Table II schemes 1-2)
are named, and one parameter of each set is fixed (or the run stops, as the settings say).
Gross errors: selection-weight iteration from posterior variances (Li Deren), or iterated
Baarda data snooping; either way, observations whose normalised residual w exceeds the
critical value at the end are flagged (never deleted from the input).
"""
from __future__ import annotations

import logging
import math
from dataclasses import asdict, dataclass, field
from typing import Callable

import numpy as np
from scipy import linalg, stats

from ..errors import Cancelled, ConvergenceError, InputError, NoDescentError
from ..observations.gcps import GcpTable, resolve_cameras
from ..geodesy import ecef_to_geodetic, enu_rotations, geodetic_to_ecef, up_vector
from ..model.sensor import SceneModel
from ..observations.tiepoints import TieTable
from ..model.timebasis import TimeBasis
from .checkpoints import blunder_test, intersection_accuracy, model_error_message, summary_lines
from .model import Jacobian, Model, build_observations
from .normal import GroundPrior, Linearization, System, assemble, back_substitute, groups, point_couplings
from .parameters import ANGLES, CAMERA_TERMS, ParameterSet
from .selection import SELECTION, conventional_instead, interior_free, select_interior
from .ties import TieSetUp, camera_indices, check_ties, datum, set_up_ties, yaw_hold, yaw_sentence
from . import linepoints
from .linepoints import (ControlLines, LineSetUp, check_lines, datum_lines, flag_lines, line_statistics,
                         set_up_lines)
from .robust import (COMPONENT_TOLERANCE, breakdown, component_report, components, critical as _critical, image_group,
                     inliers, rescale, robust_scale, robust_weights, stated_sigma0, truncation)

log = logging.getLogger(__name__)

ROBUST = ("none", "selection", "snooping")
CAMERA_TRAJECTORY = ("shared", "per_camera")
SINGULAR = 1e-11           # trajectory: smallest / largest eigenvalue of the correlation-scaled matrix
STEP_TOLERANCE = 1e-3     # px: a step changing no image residual more than this is converged
SIGMA_TOLERANCE = 1e-3    # a step below this share of every parameter's a-priori sigma is converged
PROMISE_SHARE = 1e-3      # a refused step that promised more than this share of the cost: not converged
# Interior: share of a combination's information left with the trajectory free. Measured on
# CBERS-02B: non-determinable sets keep <= 1.3e-5 (the middle chip's stagger barely separates
# yaw from a common chip rotation), the weakest determinable term (focal length) >= 1.6e-3.
INTERIOR_SINGULAR = 1e-4


@dataclass
class AdjustmentSettings:
    """How to adjust.

    position_model / attitude_model: 'polynomial' (order 0-2), 'lagrange' (orientation
    images every *_interval s) or 'spline' (piecewise quadratics every *_interval s).
    position_sigma (m) / attitude_sigma (rad): accuracy of the onboard GPS / star trackers,
    pseudo-observations of the corrections at the knots; None: no pseudo-observations.
    camera_trajectory: 'shared' (one trajectory correction for all cameras; with installation
    angles free in ``interior`` this is seed 003's Plans B-D, by the attitude order 0/1/2) or
    'per_camera' (one correction per camera, each with its own pseudo-observations: Plan A).
    interior: free/weighted interior and installation parameters (see
    :func:`core.adjust.parameters.parse_interior`). ground: 'weighted' (GCP sigmas) or 'fixed'.
    robust: 'none', 'selection' or 'snooping'; alpha: significance of the outlier test.
    on_singular: 'fix' (fix one parameter of each non-determinable set and go on) or 'stop'.
    max_iterations: Gauss-Newton iterations per solution; max_robust_iterations: passes of
    the robust / variance component loop. variance_components: estimate a factor on the stated
    sigmas per observation group and test outliers against it (see :mod:`core.adjust.robust`);
    False trusts the stated sigmas. interior_selection: 'significant' removes interior
    parameters the control cannot support and falls back to no self-calibration when it is
    not significantly better (:mod:`core.adjust.selection`); 'keep' keeps the set as given.
    """
    position_model: str = "polynomial"
    position_order: int = 1
    position_interval: float = 20.0
    attitude_model: str = "polynomial"
    attitude_order: int = 2
    attitude_interval: float = 20.0
    position_sigma: float | None = 100.0
    attitude_sigma: float | None = None
    camera_trajectory: str = "shared"
    interior: str = ""
    ground: str = "weighted"
    robust: str = "selection"
    alpha: float = 0.001
    on_singular: str = "fix"
    max_iterations: int = 30
    max_robust_iterations: int = 12
    variance_components: bool = True
    rpc_correction: str = "drift"
    interior_selection: str = "significant"

    def validate(self) -> None:
        if self.ground not in ("weighted", "fixed"):
            raise InputError(f"ground must be 'weighted' or 'fixed' (got {self.ground!r})")
        if self.robust not in ROBUST:
            raise InputError(f"robust method must be one of {', '.join(ROBUST)} (got {self.robust!r})")
        if self.camera_trajectory not in CAMERA_TRAJECTORY:
            raise InputError(f"camera trajectory must be one of {', '.join(CAMERA_TRAJECTORY)} "
                             f"(got {self.camera_trajectory!r})")
        if self.on_singular not in ("fix", "stop"):
            raise InputError(f"on_singular must be 'fix' or 'stop' (got {self.on_singular!r})")
        if not 0 < self.alpha < 0.5:
            raise InputError(f"alpha must be between 0 and 0.5 (got {self.alpha})")
        for name in ("position_sigma", "attitude_sigma"):
            v = getattr(self, name)
            if v is not None and not v > 0:
                raise InputError(f"{name} must be positive or empty (got {v})")
        if self.rpc_correction not in ("shift", "drift", "affine"):
            raise InputError(f"RPC correction must be shift, drift or affine (got {self.rpc_correction!r})")
        if self.interior_selection not in SELECTION:
            raise InputError(f"interior_selection must be one of {', '.join(SELECTION)} "
                             f"(got {self.interior_selection!r})")


@dataclass
class AdjustmentResult:
    """scene: the adjusted scene; report: JSON-ready statistics; points: per input row
    (control and check) arrays: id, role, camera, col, row, res_col, res_row (px,
    predicted - measured), res_px, w_col, w_row (normalised residuals), redundancy, weight
    (final weight factor), flagged (bool); for check points the residuals are those of the
    adjusted scene's ground -> image. tie_points: per input tie observation (input order)
    arrays: id, camera, col, row, res_col, res_row (px), w_col, w_row, weight, flagged, and the
    adjusted ground position of its point lon, lat (deg), h (ellipsoidal m); NaN for the
    observations of points left out (empty without tie points). lines: per line point (one per
    image-line vertex) arrays: line_id, camera, col, row, res_col, res_row (px), w_col, w_row,
    weight, across_m / height_m (m: where the point's ray through the adjusted scene meets its
    line's height, across the line and in height), across_before_m (the same through the input
    scene), flagged (the point or its line), line_flagged, lon, lat, h of its adjusted ground
    point; per line in report["lines"]["per_line"] (empty without lines)."""
    scene: SceneModel
    report: dict
    points: dict = field(default_factory=dict)
    tie_points: dict = field(default_factory=dict)
    lines: dict = field(default_factory=dict)


class _Problem:
    """The data and unknowns of one adjustment, and one linearisation of it."""

    def __init__(self, scene: SceneModel, table: GcpTable, settings: AdjustmentSettings,
                 ties: TieSetUp | None = None, lines: LineSetUp | None = None):
        self.scene, self.settings = scene, settings
        ties = ties or TieSetUp.empty()
        lines = lines or LineSetUp.empty()
        t_min, t_max = scene.time_span()
        self.params = ParameterSet(
            scene,
            TimeBasis.covering(settings.position_model, t_min, t_max, settings.position_order, settings.position_interval),
            TimeBasis.covering(settings.attitude_model, t_min, t_max, settings.attitude_order, settings.attitude_interval),
            settings.interior, per_camera=settings.camera_trajectory == "per_camera")
        _start_from_existing_correction(scene, self.params)
        control = np.nonzero(table.role == "control")[0]
        ids, first, point = np.unique(table.id[control], return_index=True, return_inverse=True)
        sel = control[first]
        self._set_up_ground(table, sel, ties.ground, lines)
        # GCP observations, then tie observations (their points after the GCPs'), then line points
        kind = np.repeat([0, 1, 2], [control.size, len(ties), len(lines)])
        obs = build_observations(scene, self.params,
                                 np.r_[camera_indices(scene, table.camera[control]), ties.camera, lines.camera],
                                 np.r_[table.col[control], ties.table.col[ties.rows], lines.obs.col],
                                 np.r_[table.row[control], ties.table.row[ties.rows], lines.obs.row],
                                 np.r_[point, sel.size + ties.point, self.line_first + np.arange(len(lines))],
                                 np.r_[table.sigma_px[control], ties.table.sigma_px[ties.rows], lines.obs.sigma_px],
                                 self.ground)
        # Observations sorted by what decides their parameter columns, so that observations
        # sharing columns are contiguous whatever the free parameters: groups are slices.
        order = np.lexsort((obs.att_first, obs.pos_first, obs.chip, obs.camera))
        self.obs = obs.select(order)
        self.is_tie, self.is_line = kind[order] == 1, kind[order] == 2
        # rows of the GCP table, of the tie table for ties, of the line points for lines
        self.rows = np.r_[control, ties.rows, np.arange(len(lines))][order]
        self.line_obs = np.empty(len(lines), np.int64)  # each line point's observation
        self.line_obs[self.rows[self.is_line]] = np.nonzero(self.is_line)[0]
        self.ties = ties
        self.factor = np.ones((len(self.obs), 2))  # robust weight factors per residual row
        self.scale: dict[str, float] = {}  # variance component factor on the stated sigmas, per group
        self.rescaled()
        self.structure()

    # --- sigmas: stated, times the variance component factor of their group ----------------
    def rescaled(self) -> None:
        """Ground weights (m,3,3) ECEF from the stated sigmas and the current factors."""
        s = np.array([self.scale.get("ground_xy", 1.0)] * 2 + [self.scale.get("ground_z", 1.0)])
        self.ground_weight = np.einsum("mki,mk,mkj->mij", self.enu, 1.0 / (self.ground_sigma * s) ** 2, self.enu)

    def image_sigma(self) -> np.ndarray:
        """(n,) px: each image observation's stated sigma times its camera's factor."""
        factors = np.array([self.scale.get(image_group(c.name), 1.0) for c in self.scene.cameras])
        return self.obs.sigma * factors[self.obs.camera]

    def stated_sigma(self, group: str) -> tuple[float | None, str]:
        """The median stated sigma of a group and its unit (None for interior pseudo-observations,
        whose sigmas have several units)."""
        for c, cam in enumerate(self.scene.cameras):
            if group == image_group(cam.name):
                return float(np.median(self.obs.sigma[self.obs.camera == c])), "px"
        if group.startswith("ground"):
            return float(np.median(self.ground_sigma[:, 2 if group == "ground_z" else 0])), "m"
        if group in (linepoints.ACROSS_GROUP, linepoints.HEIGHT_GROUP):
            seg = self.lines.seg
            return float(np.median(seg.sigma_across if group == linepoints.ACROSS_GROUP else seg.sigma_h)), "m"
        s = self.settings
        return {"position pseudo-observations": (s.position_sigma, "m"),
                "attitude pseudo-observations": (s.attitude_sigma, "rad")}.get(group, (None, ""))

    # --- unknowns and their columns -------------------------------------------------------
    def _set_up_ground(self, table: GcpTable, sel: np.ndarray, tie_ground: np.ndarray | None = None,
                       lines: LineSetUp | None = None) -> None:
        """Ground points: the control points ``sel`` (rows of ``table``, one per point), then the
        tie points (start values ``tie_ground`` (t, 3) ECEF m), then the line points of ``lines``
        (from ``line_first``; their prior is the lines', :meth:`ground_prior`). ground0 / ground (m, 3) ECEF m:
        measured (start) and current positions; for weighted ground the control points' ENU
        rotations and stated east, north, up sigmas (m, (n, 3)). The ground unknowns are the
        weighted control points and all tie points (which have no prior): ``estimated`` (k,)
        their indices in ground, ``ground_point`` (m,) each point's unknown index or -1."""
        tie_ground = np.zeros((0, 3)) if tie_ground is None else tie_ground
        self.lines = lines or LineSetUp.empty()
        # lines named wrong as a whole (released); grossly wrong ones from the start
        self.line_flagged = linepoints.screen(self.scene, self.lines) if len(self.lines) else \
            np.zeros(0, bool)
        self.n_control = int(sel.size)
        self.line_first = int(sel.size + tie_ground.shape[0])
        self.ground0 = np.concatenate([geodetic_to_ecef(table.lon[sel], table.lat[sel], table.h[sel]).reshape(-1, 3),
                                       tie_ground, self.lines.ground])
        self.ground = self.ground0.copy()
        self.weighted = self.settings.ground == "weighted"
        self.enu = enu_rotations(table.lon[sel], table.lat[sel]) if self.weighted else np.zeros((0, 3, 3))
        self.ground_sigma = np.stack([table.sigma_xy[sel], table.sigma_xy[sel], table.sigma_z[sel]], 1) \
            if self.weighted else np.zeros((0, 3))
        self.estimated = np.arange(self.n_control * (not self.weighted), self.ground0.shape[0])
        self.ground_point = -np.ones(self.ground0.shape[0], np.int64)
        self.ground_point[self.estimated] = np.arange(self.estimated.size)

    def counts(self) -> tuple[int, int]:
        """(equations, unknowns): image rows, ground priors and pseudo-observations against the
        free parameters and the ground unknowns."""
        n_eq = 2 * len(self.obs) + 3 * self.enu.shape[0] + 2 * len(self.lines) + \
            sum(p.B.shape[0] for p in self.pseudo())
        return n_eq, int(self.params.free.size) + 3 * int(self.estimated.size)

    def structure(self) -> None:
        """Unknown numbering and each observation's columns (after a change of the free set)."""
        params = self.params
        free = params.free
        self.unknown = -np.ones(len(params.params), dtype=np.int64)
        self.unknown[free] = np.arange(free.size)
        obs = self.obs
        pos = params.block_indices("position")
        att = params.block_indices("attitude")
        wp, wa = obs.pos_weights.shape[1], obs.att_weights.shape[1]
        cols = [pos[obs.pos_first[:, None] + np.arange(wp)].reshape(-1, 3 * wp),
                att[obs.att_first[:, None] + np.arange(wa)].reshape(-1, 3 * wa)]
        inst = np.stack([params.camera_indices(c, "installation", ANGLES) for c in range(len(params.scene.cameras))])
        cams = np.stack([params.camera_indices(c, "camera", CAMERA_TERMS) for c in range(len(params.scene.cameras))])
        chip = -np.ones((len(obs), 4), dtype=np.int64)
        for c, cam in enumerate(params.scene.cameras):
            for k in range(len(cam.chips)):
                _, idx = params.chip_indices(c, k)
                chip[(obs.camera == c) & (obs.chip == k), :idx.size] = idx
        cols += [inst[obs.camera], chip, cams[obs.camera]]
        param_cols = np.concatenate(cols, axis=1)
        columns = np.where(param_cols >= 0, self.unknown[np.maximum(param_cols, 0)], -1)
        # Only the column slots some observation uses (fixed terms cost nothing then).
        self.slots = np.nonzero((columns >= 0).any(axis=0))[0]
        self.columns = columns[:, self.slots]
        self.groups = groups(self.columns)

    def values(self, jac: Jacobian) -> np.ndarray:
        """Jacobian values (n, 2, q) in the column layout of :meth:`structure`."""
        obs = self.obs
        wp, wa = obs.pos_weights.shape[1], obs.att_weights.shape[1]
        out = np.empty((len(obs), 2, self.slots.size))
        for j, slot in enumerate(self.slots):
            if slot < 3 * wp:
                out[:, :, j] = jac.S[:, :, slot % 3] * obs.pos_weights[:, slot // 3, None]
            elif slot < 3 * (wp + wa):
                k = slot - 3 * wp
                out[:, :, j] = jac.angles[:, :, k % 3] * obs.att_weights[:, k // 3, None]
            else:
                k = slot - 3 * (wp + wa)
                block, k = ((jac.installation, k) if k < 3 else (jac.chip, k - 3) if k < 7 else (jac.camera, k - 7))
                out[:, :, j] = block[:, :, k]
        return out

    # --- one linearisation --------------------------------------------------------------------
    def weights(self) -> np.ndarray:
        return self.factor / self.image_sigma()[:, None] ** 2

    def linearize(self) -> tuple[Linearization, GroundPrior | None]:
        r, jac = Model(self.scene, self.params).linearize(self.obs, self.ground[self.obs.point])
        return Linearization(r, self.weights(), self.columns, self.values(jac), jac.ground,
                             self.ground_point[self.obs.point]), self.ground_prior()

    def ground_prior(self) -> GroundPrior | None:
        """The ground unknowns' prior: the weighted control points' stated weights, zero for tie
        points, the rank-2 line constraints at the current ground for line points (the nearest
        segment refreshed) (None without ground unknowns)."""
        if self.estimated.size == 0:
            return None
        weight = np.concatenate([self.ground_weight, np.zeros((self.estimated.size - self.enu.shape[0], 3, 3))])
        misfit = (self.ground - self.ground0)[self.estimated]
        if len(self.lines):
            c = self.lines.constraints(self.line_ground(), self.scale, self.line_flagged)
            weight[-len(self.lines):], misfit[-len(self.lines):] = c.weight, c.misfit
        return GroundPrior(weight, misfit)

    def line_ground(self) -> np.ndarray:
        """(n, 3) ECEF m: the line points' current ground positions."""
        return self.ground[self.line_first:]

    def residuals(self) -> np.ndarray:
        return Model(self.scene, self.params).residuals(self.obs, self.ground[self.obs.point])

    def cost(self) -> float:
        r = self.residuals()
        c = float(np.sum(self.weights() * r * r))
        if self.weighted:
            e = (self.ground - self.ground0)[:self.n_control]
            c += float(np.einsum("mi,mij,mj->", e, self.ground_weight, e))
        if len(self.lines):
            line = self.lines.constraints(self.line_ground(), self.scale, self.line_flagged)
            c += float(np.einsum("mi,mij,mj->", line.misfit, line.weight, line.misfit))
        return c + sum(float(np.sum(p.weight * p.misfit(self.params) ** 2)) for p in self.pseudo())

    def pseudo(self) -> list["_Pseudo"]:
        """Pseudo-observations: trajectory corrections at the knots, weighted parameters."""
        out = []
        s = self.settings
        for block, basis, sigma in (("position", self.params.position_basis, s.position_sigma),
                                    ("attitude", self.params.attitude_basis, s.attitude_sigma)):
            if sigma is None:
                continue
            times = basis.knot_times() if basis.kind != "polynomial" else \
                basis.t0 + basis.scale * np.linspace(-1.0, 1.0, basis.size)
            B = basis.matrix(times)  # (k, m)
            idx = self.params.block_indices(block).reshape(-1, basis.size, 3)  # per trajectory (camera)
            group = f"{block} pseudo-observations"
            for rows in idx:
                for a in range(3):
                    out.append(_Pseudo(group, rows[:, a], B, 1.0 / (sigma * self.scale.get(group, 1.0)) ** 2))
        weighted = [i for i, p in enumerate(self.params.params) if p.mode == "weighted"]
        if weighted:
            group = "interior pseudo-observations"
            sigmas = np.array([self.params.params[i].sigma for i in weighted]) * self.scale.get(group, 1.0)
            out.append(_Pseudo(group, np.array(weighted), np.eye(len(weighted)), 1.0 / sigmas ** 2))
        return out

    def system(self) -> tuple[Linearization, System]:
        lin, prior = self.linearize()
        system = assemble(lin, prior, int(self.params.free.size), self.groups)
        for p in self.pseudo():
            cols = self.unknown[p.index]
            m = p.misfit(self.params)
            w = np.broadcast_to(p.weight, m.shape)
            system.N[np.ix_(cols, cols)] += p.B.T @ (w[:, None] * p.B)
            system.b += np.bincount(cols, weights=p.B.T @ (w * m), minlength=system.b.size)
            system.cost += float(np.sum(w * m * m))
        return lin, system

    def step(self, lin: Linearization, system: System, dx: np.ndarray) -> None:
        values = self.params.values()
        values[self.params.free] += dx
        self.params.set_values(values)
        if self.estimated.size:
            self.ground = self.ground.copy()
            self.ground[self.estimated] += back_substitute(lin, system, dx)


@dataclass
class _Pseudo:
    """A group of pseudo-observations B @ x[index] = 0 with weights (1/sigma^2)."""
    group: str
    index: np.ndarray
    B: np.ndarray
    weight: np.ndarray | float

    def misfit(self, params: ParameterSet) -> np.ndarray:
        return self.B @ params.values()[self.index]


def _start_from_existing_correction(scene: SceneModel, params: ParameterSet) -> None:
    """Re-adjusting an adjusted scene starts from its correction(s) when the models agree: a
    shared correction starts every camera's of a per-camera run; corrections per camera
    cannot start a shared one."""
    platform = scene.platform
    own = [cam.name for cam in scene.cameras if cam.name in platform.camera_corrections]
    if own and not params.per_camera:
        raise InputError(f"the scene was adjusted with a trajectory correction per camera ({', '.join(own)}); "
                         "adjust it again with one correction per camera, or adjust the original (onboard) scene")
    starts = [platform.for_camera(cam.name).correction for cam in scene.cameras] if params.per_camera else \
        [platform.correction]
    if all(corr is None for corr in starts):
        return
    position, attitude = params.block_values("position"), params.block_values("attitude")
    m_p, m_a = params.position_basis.size, params.attitude_basis.size
    for k, corr in enumerate(starts):
        if corr is None:
            continue
        if corr.position.to_dict() != params.position_basis.to_dict() or \
                corr.attitude.to_dict() != params.attitude_basis.to_dict():
            raise InputError("the scene was adjusted with another trajectory model; adjust the original (onboard) "
                             "scene, or choose the same model and interval")
        position[k * m_p:(k + 1) * m_p] = corr.position_coefficients
        attitude[k * m_a:(k + 1) * m_a] = corr.attitude_coefficients
    values = params.values()
    values[params.block_indices("position")] = position
    values[params.block_indices("attitude")] = attitude
    params.set_values(values)


# --- determinability ------------------------------------------------------------------------------
def non_determinable(N: np.ndarray, names: list[str], trajectory: np.ndarray) -> list[list[str]]:
    """Sets of parameters the observations cannot separate, each listed with the most
    involved first.

    Trajectory: (near-)null directions of the correlation-scaled normal matrix (ratio below
    SINGULAR). Interior (the rest): directions that keep less than INTERIOR_SINGULAR of their
    information once the trajectory is free (the Schur complement of the trajectory block,
    scaled by the interior diagonal), named with the trajectory parameters that absorb them.
    """
    d = np.sqrt(np.maximum(np.diag(N), 0.0))
    dead = np.nonzero(d <= 0)[0]
    if dead.size:
        return [[names[i]] for i in dead]
    C = N / np.outer(d, d)
    t = np.nonzero(trajectory)[0]
    if t.size == 0:  # an RPC scene's correction: no trajectory to absorb anything
        vals, vecs = np.linalg.eigh(C)
        return [_members(vecs[:, k], np.arange(len(names)), names) for k in np.nonzero(vals < SINGULAR * vals[-1])[0]]
    vals, vecs = np.linalg.eigh(C[np.ix_(t, t)])
    sets = [_members(vecs[:, k], t, names) for k in np.nonzero(vals < SINGULAR * vals[-1])[0]]
    if sets or trajectory.all():
        return sets
    i = np.nonzero(~trajectory)[0]
    absorb = np.linalg.solve(C[np.ix_(t, t)], C[np.ix_(t, i)])
    vals, vecs = np.linalg.eigh(C[np.ix_(i, i)] - C[np.ix_(i, t)] @ absorb)
    for k in np.nonzero(vals < INTERIOR_SINGULAR)[0]:
        inner = _members(vecs[:, k], i, names)
        outer = _members(-absorb @ vecs[:, k], t, names)[:2]
        sets.append(inner + outer)
    return sets


def _members(v: np.ndarray, index: np.ndarray, names: list[str]) -> list[str]:
    big = np.nonzero(np.abs(v) > 0.25 * np.abs(v).max())[0]
    return [names[index[j]] for j in big[np.argsort(-np.abs(v[big]))]]


def _choose_to_fix(problem: _Problem, members: list[str]) -> str | None:
    """The parameter to fix in a non-determinable set: an interior one, preferably of the
    reference (middle) chip, else the one taking the largest part."""
    params = problem.params
    interior = [n for n in members if params.params[params.index[n]].block not in ("position", "attitude")]
    for n in interior:
        p = params.params[params.index[n]]
        if p.block == "chip" and p.chip == len(problem.scene.cameras[p.camera].chips) // 2:
            return n
    return interior[0] if interior else None


def check_determinability(problem: _Problem, system: System) -> list[dict]:
    """Find non-determinable parameter sets; fix one interior parameter of each (or stop with
    their names). Returns what was found and done, for the report."""
    found = []
    for _ in range(len(problem.params.params)):
        free = problem.params.free
        names = [problem.params.params[i].name for i in free]
        # A weighted interior parameter is determined by its prior (to at most its sigma) whatever
        # the observations say: like the trajectory it may absorb the others, it is not tested.
        # Its prior is a small share of the information the image observations give it, so the
        # share test would call it non-determinable and fix it at 0, discarding the prior.
        trajectory = np.array([problem.params.params[i].block in ("position", "attitude")
                               or problem.params.params[i].mode == "weighted" for i in free])
        sets = non_determinable(system.N, names, trajectory)
        if not sets:
            return found
        members = sets[0]
        chosen = _choose_to_fix(problem, members) if problem.settings.on_singular == "fix" else None
        if chosen is None:
            hint = ("" if problem.settings.on_singular == "stop" and any(
                problem.params.params[problem.params.index[n]].block not in ("position", "attitude")
                for n in members) else
                "; give onboard GPS/attitude sigmas, more or better spread GCPs, or a simpler trajectory model")
            raise InputError(f"these parameters cannot be determined together from the observations: "
                             f"{', '.join(members)}{hint}")
        found.append({"parameters": members, "fixed": chosen})
        log.warning("not determinable together: %s; fixed %s", ", ".join(members), chosen)
        problem.params.fix([chosen])
        problem.structure()
        _, system = problem.system()
    return found


# --- the solution ------------------------------------------------------------------------------------
def solve(problem: _Problem, progress, is_cancelled, label: str = "") -> dict:
    """Gauss-Newton iterations to convergence, damped (Levenberg-Marquardt) only after a step
    that fails: damping slows the weakly determined directions (position against attitude,
    eigenvalue ratios ~1e-8) to linear convergence. Returns the iteration log."""
    lam = 0.0
    history = []
    lin, system = problem.system()
    cost = system.cost
    for it in range(problem.settings.max_iterations):
        if is_cancelled():
            raise Cancelled("adjustment cancelled by the user")
        D = np.diag(system.N).copy()
        D[D <= 0] = 1.0
        promised, rejected = None, False
        while True:
            try:
                factor = linalg.cho_factor(system.N + lam * np.diag(D), check_finite=False)
                dx = -linalg.cho_solve(factor, system.b, check_finite=False)
            except linalg.LinAlgError:
                lam = max(10.0 * lam, 1e-9)
                if lam > 1e12:
                    raise NoDescentError(_not_converged(history, "the normal matrix is not positive definite"))
                continue
            if promised is None:  # the linearised model's decrease of the cost for this iteration's first step
                promised = -float(system.b @ dx)
            change = _image_change(lin, dx)
            # At the optimum already (rounding decides the cost, not the step), or the step is a
            # negligible share of every parameter's standard deviation (weakly determined
            # directions, where the cost is flat, would otherwise be crept along for ever).
            relative = np.max(np.abs(dx) / np.sqrt(np.diag(
                linalg.cho_solve(factor, np.eye(dx.size), check_finite=False))), initial=0.0)
            if change < STEP_TOLERANCE or relative < SIGMA_TOLERANCE:
                # Damped down to nothing after the steps the linearised model promised much from
                # were all refused: stuck, not at the optimum (a nearly singular normal matrix).
                if rejected and promised > PROMISE_SHARE * cost:
                    raise NoDescentError(_not_converged(
                        history, f"no step reduces the residuals (the linearised model promised {promised:.4g} "
                                 f"of {cost:.4g}; the normal matrix is nearly singular)"))
                return {"iterations": history, "system": system, "linearization": lin}
            saved = (problem.params.values(), problem.ground.copy())
            problem.step(lin, system, dx)
            new_cost = problem.cost()
            if new_cost <= cost * (1 + 1e-9):
                break
            problem.params.set_values(saved[0])
            problem.ground = saved[1]
            rejected = True
            lam = max(10.0 * lam, 1e-9)
            if lam > 1e12:
                raise NoDescentError(_not_converged(history, "no step reduces the residuals"))
        history.append({"iteration": it + 1, "cost": new_cost, "max_image_change_px": change, "damping": lam})
        log.info("%siteration %d: weighted squared residuals %.6g, largest image change %.2e px", label, it + 1,
                 new_cost, change)
        progress(min(0.9, 0.1 + 0.08 * (it + 1)), f"{label}iteration {it + 1}: cost {new_cost:.6g}")
        stalled = cost - new_cost <= 1e-8 * cost
        cost = new_cost
        lam = lam / 10.0 if lam > 1e-9 else 0.0
        # A step that no longer lowers the cost (Gauss-Newton, which neglects the curvature of
        # large residuals such as gross errors, may cycle there) has converged in cost.
        if (change < 10 * STEP_TOLERANCE and lam == 0.0) or stalled:
            # Gauss-Newton converges quadratically here: the next step would change nothing
            # measurable. The statistics take the last linearisation with the final residuals.
            lin.r = problem.residuals()
            system.cost = new_cost
            return {"iterations": history, "system": system, "linearization": lin}
        lin, system = problem.system()
    n = problem.settings.max_iterations
    raise ConvergenceError(_not_converged(history, f"still changing after {n} iteration{'s' * (n != 1)}"))


def _image_change(lin: Linearization, dx: np.ndarray) -> float:
    """Largest change (px) a parameter step makes to an image residual, to first order."""
    step = np.einsum("nkq,nq->nk", lin.values, np.where(lin.columns >= 0, dx[np.maximum(lin.columns, 0)], 0.0))
    return float(np.max(np.abs(step), initial=0.0))


def _not_converged(history: list[dict], why: str) -> str:
    tried = "; ".join(f"#{h['iteration']}: {h['cost']:.4g} (step {h['max_image_change_px']:.3g} px)"
                      for h in history[-5:]) or "no iteration completed"
    return (f"the adjustment did not converge: {why}. Weighted squared residuals per iteration: {tried}. "
            "Try fewer free interior parameters, a simpler trajectory model, onboard sigmas, or check the GCPs "
            "for gross errors.")


# --- statistics ------------------------------------------------------------------------------------------
@dataclass
class Statistics:
    """Posterior statistics at the solution: Q (cofactor matrix of the unknowns), sigma0, dof,
    per image row redundancy (n,2) and normalised residual w (n,2) (against the stated sigmas
    times their group's factor), the residuals v (n,2) px and p v^2 (n,2) with the current
    weights; per control point p e^2 (m,3) and redundancy (m,3) of its east, north, up ground
    coordinates (weighted ground; else (0,3)); per pseudo-observation group (sum of p v^2,
    redundancy, count); lines: the line points' constraint statistics (None without lines)."""
    Q: np.ndarray
    sigma0: float
    dof: float
    redundancy: np.ndarray
    w: np.ndarray
    v: np.ndarray
    pvv: np.ndarray
    ground_pvv: np.ndarray
    ground_redundancy: np.ndarray
    pseudo: dict
    lines: linepoints.LineStatistics | None = None


def statistics(problem: _Problem, lin: Linearization, system: System) -> Statistics:
    """Redundancy numbers (diagonal of the hat matrix, ground points included through their
    Schur complement), normalised residuals and variance components."""
    n_unknowns = system.N.shape[0]
    Q = linalg.cho_solve(linalg.cho_factor(system.N, check_finite=False), np.eye(n_unknowns), check_finite=False)
    P = np.zeros((lin.r.shape[0], 2, 2))
    P[:, 0, 0], P[:, 1, 1] = lin.p[:, 0], lin.p[:, 1]
    weighted = lin.point >= 0
    G = np.zeros_like(P)
    for idx in problem.groups:
        keep = lin.columns[idx.start] >= 0
        if not keep.any():
            continue
        c = lin.columns[idx.start][keep]
        A = lin.values[idx][:, :, keep]
        AQ = (A.reshape(-1, c.size) @ Q[np.ix_(c, c)]).reshape(A.shape)
        G[idx] = np.einsum("nkq,nlq->nkl", AQ, A)
    h = np.einsum("nkk->nk", G)
    qgg = system.K
    if weighted.any():
        h[weighted], qgg = _ground_leverage(lin, system, Q, G, weighted)
    redundancy = np.clip(1.0 - h * lin.p, 0.0, 1.0)
    v = lin.r
    # the line points are the last ground unknowns
    lines = line_statistics(problem, qgg[qgg.shape[0] - len(problem.lines):]) if len(problem.lines) else None
    ground_pvv, r_g = np.zeros((0, 3)), np.zeros((0, 3))
    if problem.weighted and problem.n_control:
        # the weighted control points are the first ground unknowns
        qgg = qgg[:problem.n_control]
        e = np.einsum("mij,mj->mi", problem.enu, (problem.ground - problem.ground0)[:problem.n_control])
        w_enu = np.einsum("mii->mi", np.einsum("mij,mjk,mlk->mil", problem.enu, problem.ground_weight, problem.enu))
        r_g = np.clip(1.0 - np.einsum("mij,mjk,mik->mi", problem.enu, qgg, problem.enu) * w_enu, 0.0, 1.0)
        ground_pvv = w_enu * e * e
    pseudo: dict[str, tuple[float, float, int]] = {}
    for p in problem.pseudo():
        cols = problem.unknown[p.index]
        m = p.misfit(problem.params)
        hp = np.einsum("kq,qr,kr->k", p.B, Q[np.ix_(cols, cols)], p.B) * p.weight
        old = pseudo.get(p.group, (0.0, 0.0, 0))
        pseudo[p.group] = (old[0] + float(np.sum(p.weight * m * m)), old[1] + float(np.sum(1 - hp)), old[2] + m.size)
    total_rows, total_unknowns = problem.counts()
    dof = float(total_rows - total_unknowns)
    if dof <= 0:
        raise InputError(f"too few observations: {total_rows} equations for {total_unknowns} unknowns")
    sigma0 = math.sqrt(system.cost / dof)
    w = normalised(problem, v, redundancy)
    return Statistics(Q, sigma0, dof, redundancy, w, v, lin.p * v * v, ground_pvv, r_g, pseudo, lines)


def _ground_leverage(lin: Linearization, system: System, Q: np.ndarray, G: np.ndarray,
                     weighted: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Diagonals (k,2) of the predicted observations' cofactors for the observations with a
    ground unknown, and the ground unknowns' cofactors (m,3,3).

    With M_p = sum over the point's observations of J_g' P A (3 x u) and K its eliminated
    block, the ground estimate is dg = -K (b_g + M_p dx): its cofactor is K + K M_p Q M_p' K,
    and an observation's prediction A dx + J_g dg has the cofactor
    J_g K J_g' + (A - J_g K M_p) Q (A - J_g K M_p)'. Every observation of a point enters M_p
    (a tie point's rays share its ground unknowns)."""
    n_points = system.K.shape[0]
    u = Q.shape[0]
    s = np.zeros((n_points, 3, 3))                                                # M Q M'
    aqm = np.zeros((lin.r.shape[0], 2, 3))                                        # A Q M' per observation
    for first, last, obs, M in point_couplings(lin, weighted, u, n_points):
        mq = (M.reshape(-1, u) @ Q).reshape(M.shape)
        s[first:last] = np.einsum("cau,cbu->cab", mq, M)
        cols = lin.columns[obs]
        mine = mq[(lin.point[obs] - first)[:, None, None], np.arange(3)[None, :, None], np.maximum(cols, 0)[:, None, :]]
        aqm[obs] = np.matmul(lin.values[obs], np.where(cols[:, None, :] >= 0, mine, 0.0).transpose(0, 2, 1))
    point = lin.point[weighted]
    aqm = aqm[weighted]
    jk = lin.jg[weighted] @ system.K[point]                                       # J_g K (k,2,3)
    h = np.einsum("nkg,nkg->nk", jk, lin.jg[weighted]) + np.einsum("nkk->nk", G[weighted]) \
        - 2.0 * np.einsum("nkg,nkg->nk", aqm, jk) + np.einsum("nkg,ngh,nkh->nk", jk, s[point], jk)
    return h, system.K + system.K @ s @ system.K


def normalised(problem: _Problem, v: np.ndarray, redundancy: np.ndarray) -> np.ndarray:
    """Normalised residuals w (n,2) = v / (sigma sqrt(r)), sigma the stated image sigma times
    its camera's variance component factor."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(redundancy > 1e-6, v / (problem.image_sigma()[:, None] * np.sqrt(redundancy)), 0.0)


# --- accuracy -------------------------------------------------------------------------------------------
def accuracy(scene: SceneModel, table: GcpTable, rows: np.ndarray, alpha: float,
             scale: dict[str, float] | None = None) -> dict:
    """Check-point accuracy of a scene: ground -> image residuals (px) and image -> ground at
    the known height in a local east-north frame (m): RMSE per axis, max, CE90.

    The figures are per observation (a point seen in three cameras counts three times), each
    monoplotted on its own. ``points``: distinct check point ids; ``observations``: rows.

    Figures over all check observations, and again without the blunders: observations whose
    image residual exceeds the critical value (at ``alpha``) of what their own sigmas allow
    (image sigma, planimetric ground sigma over the GSD and the image shift of a height error of
    sigma_z, per axis), each times its group's variance component factor in ``scale`` (the
    check points are measured as the control points are: the factors estimated on those make
    the test independent of the stated sigmas' scale). ``blunders`` counts those observations,
    ``blunder_points`` the points with any. A model error makes many exceed it:
    ``blunder_test`` (:func:`core.adjust.checkpoints.blunder_test`) decides, and with
    ``model_error`` the figures without them are not meaningful.
    """
    scale = scale or {}
    if rows.size == 0:
        return {"points": 0}
    res = np.full((rows.size, 2), np.nan)
    en = np.full((rows.size, 2), np.nan)
    allowed = np.full(rows.size, np.nan)
    sub = table.select(rows)
    ground = sub.ecef()
    crit = _critical(alpha)
    for c, cam in enumerate(scene.cameras):
        m = sub.camera == cam.name
        if not m.any():
            continue
        col, row = scene.ground_to_image(ground[m], c)
        res[m] = np.stack([col - sub.col[m], row - sub.row[m]], axis=1)
        seen = scene.image_to_ground(sub.col[m], sub.row[m], sub.h[m], c)
        en[m] = np.einsum("nij,nj->ni", enu_rotations(sub.lon[m], sub.lat[m]), seen - ground[m])[:, :2]
        # a height error moves the image point by its relief displacement only
        sigma_z = sub.sigma_z[m] * scale.get("ground_z", 1.0)
        up = ground[m] + sigma_z[:, None] * up_vector(sub.lon[m], sub.lat[m])
        relief = np.hypot(*(a - b for a, b in zip(scene.ground_to_image(up, c), (col, row))))
        sigma_px = sub.sigma_px[m] * scale.get(image_group(cam.name), 1.0)
        sigma_xy = sub.sigma_xy[m] * scale.get("ground_xy", 1.0)
        allowed[m] = crit * np.sqrt(sigma_px ** 2 + (sigma_xy / _gsd(scene, c)) ** 2 + relief ** 2)
    flagged = ~(np.abs(res) <= allowed[:, None]).all(axis=1)
    test = blunder_test(int(flagged.sum()), rows.size, alpha)
    return {"points": int(np.unique(sub.id).size), "observations": int(rows.size), **_figures(res, en),
            "blunders": int(flagged.sum()), "blunder_points": int(np.unique(sub.id[flagged]).size),
            "blunder_test": test, "model_error": test["model_error"],
            "without_blunders": _figures(res[~flagged], en[~flagged]),
            "residuals": res, "en": en, "is_flagged": flagged}


def _figures(res: np.ndarray, en: np.ndarray) -> dict:
    """RMSE per axis, max and CE90 of image residuals (n,2) px and ground errors (n,2) m."""
    if res.shape[0] == 0:
        return {"image": None, "ground": None}
    horizontal = np.hypot(en[:, 0], en[:, 1])
    px = np.hypot(res[:, 0], res[:, 1])
    rms = lambda a: float(np.sqrt(np.mean(a * a)))  # noqa: E731
    return {"image": {"rmse_col": rms(res[:, 0]), "rmse_row": rms(res[:, 1]), "rmse": rms(px), "max": float(px.max())},
            "ground": {"rmse_east": rms(en[:, 0]), "rmse_north": rms(en[:, 1]), "rmse": rms(horizontal),
                       "max": float(horizontal.max()), "ce90": float(np.percentile(horizontal, 90))}}


def _gsd(scene: SceneModel, camera: int) -> float:
    """Ground sample distance (m): the distance between neighbouring pixels at the image centre."""
    cam = scene.cameras[camera]
    c, r = np.array([cam.cols / 2, cam.cols / 2 + 1]), np.array([cam.rows / 2, cam.rows / 2])
    g = scene.image_to_ground(c, r, float(np.mean(scene.height_range)), camera)
    return float(np.linalg.norm(g[1] - g[0]))


# --- the whole adjustment ----------------------------------------------------------------------------------
def check_inputs(scene: SceneModel, table: GcpTable, settings: AdjustmentSettings,
                 ties: TieTable | None = None, lines: ControlLines | None = None) -> GcpTable:
    """Cameras resolved and the GCPs (and tie points) checked before anything is solved:
    finite values, points in this scene's images, enough of them, and spread over the image.
    Without tie points at least 3 control points are needed; with tie points fewer (0, 1, 2)
    when the onboard pseudo-observations hold what they leave of the datum (see
    :func:`core.adjust.ties.datum`); with control lines (checked against the scene) fewer too:
    lines in several directions hold the datum as points do (the report's lines/directions
    says when they do not)."""
    settings.validate()
    table = resolve_cameras(table, scene)
    bad = ~np.all(np.isfinite(np.stack([table.col, table.row, table.lon, table.lat, table.h, table.sigma_px,
                                        table.sigma_xy, table.sigma_z])), axis=0)
    if bad.any():
        raise InputError(f"GCPs {', '.join(table.id[bad][:10])} have NaN or missing coordinates or sigmas")
    if np.any(table.sigma_px <= 0) or (settings.ground == "weighted" and
                                       (np.any(table.sigma_xy <= 0) or np.any(table.sigma_z <= 0))):
        raise InputError("GCP sigmas must be positive (sigma_px, and sigma_xy, sigma_z for weighted ground)")
    control = table.role == "control"
    with_ties = ties is not None and len(ties) > 0
    if with_ties:
        check_ties(scene, ties, table.id)
    with_lines = lines is not None and len(lines.image) > 0
    if with_lines:
        from ..model.rpcscene import RpcScene
        if isinstance(scene, RpcScene):
            raise InputError("control lines need a rigorous (physical) scene model; an RPC scene's correction is "
                             "adjusted from GCPs")
        check_lines(scene, lines)
    sparse_control = with_ties or with_lines
    inside = np.zeros(len(table), bool)
    for c, cam in enumerate(scene.cameras):
        m = table.camera == cam.name
        inside[m] = (table.col[m] >= 0) & (table.col[m] <= cam.cols) & (table.row[m] >= 0) & (table.row[m] <= cam.rows)
    if not inside[control].any() and not (sparse_control and not control.any()):
        raise InputError("no control point lies inside this scene's images: is the GCP layer from another scene?")
    if (~inside[control]).sum() > 0.5 * control.sum():
        raise InputError(f"{int((~inside[control]).sum())} of {int(control.sum())} control points lie outside the "
                         "scene's images: is the GCP layer from another scene?")
    if control.any():
        _check_seen_by_scene(scene, table.select(control))
    if not sparse_control or np.unique(table.id[control]).size >= 3:
        _check_spread(scene, table, control)
    _datum(table, settings, ties, lines)
    return table


def _datum(table: GcpTable, settings: AdjustmentSettings, ties: TieTable | None,
           lines: ControlLines | None = None) -> dict | None:
    """How the datum of a block with tie points (and control lines) is held (None without tie
    points; InputError naming a datum defect)."""
    if ties is None or len(ties) == 0:
        return None
    return datum(np.unique(table.id[table.role == "control"]).size, settings.position_sigma, settings.attitude_sigma,
                 *datum_lines(lines))


def _with_yaw(held: dict, problem: _Problem, st: Statistics) -> dict:
    """The datum entry with the posterior sigma of the block's yaw (:func:`yaw_hold`) and its
    sentence appended to the note."""
    yaw = yaw_hold(problem.params, st.sigma0 ** 2 * st.Q)
    return {**held, "yaw": yaw, "note": "; ".join(filter(None, (held.get("note"), yaw_sentence(yaw))))}


def _check_seen_by_scene(scene: SceneModel, control: GcpTable) -> None:
    """Most control points' ground positions must project into the scene's images: onboard
    errors move them by hundreds of pixels, another scene by its whole size. An evenly spaced
    sample of 5000 points decides."""
    control = control.select(np.unique(np.linspace(0, len(control) - 1, min(len(control), 5000)).astype(int)))
    seen = np.zeros(len(control), bool)
    for c, cam in enumerate(scene.cameras):
        m = control.camera == cam.name
        if m.any():
            col, row = scene.ground_to_image(control.select(m).ecef(), c)
            seen[m] = (col > -0.5 * cam.cols) & (col < 1.5 * cam.cols) & (row > -0.5 * cam.rows) & \
                (row < 1.5 * cam.rows)
    if seen.mean() < 0.5:
        raise InputError(f"the ground positions of {int((~seen).sum())} of {len(control)} control points are far "
                         "outside this scene's images (more than half an image away): is the GCP layer from "
                         "another scene?")


def _check_spread(scene: SceneModel, table: GcpTable, control: np.ndarray) -> None:
    """Control points on a line or bunched in a corner cannot fix a trajectory."""
    cam = scene.cameras[0]
    xy = np.stack([table.col[control] / cam.cols, table.row[control] / cam.rows], axis=1)
    if xy.shape[0] < 3:
        raise InputError(f"too few control points: {xy.shape[0]} (at least 3, better many more, are needed)")
    span = xy.max(axis=0) - xy.min(axis=0)
    sv = np.linalg.svd(xy - xy.mean(axis=0), compute_uv=False)
    if sv[1] < 0.01 * sv[0]:
        raise InputError("the control points lie on a line; the scene's rotation about it cannot be determined. "
                         "Add points off that line.")
    if span[0] < 0.1 and span[1] < 0.1:
        raise InputError(f"the control points cover only {100 * span[0]:.0f}% x {100 * span[1]:.0f}% of the image "
                         "(one corner); spread them over the scene")


def _problem_for(scene, table: GcpTable, settings: AdjustmentSettings, ties: TieSetUp,
                 lines: LineSetUp | None = None) -> _Problem:
    """The problem of a rigorous scene, or of an RPC scene (its image-space correction,
    :mod:`core.adjust.rpcbias`)."""
    from ..model.rpcscene import RpcScene
    if isinstance(scene, RpcScene):
        if len(ties):
            raise InputError("tie points need a rigorous (physical) scene model with several cameras; an RPC "
                             "scene is one image")
        from .rpcbias import RpcProblem
        return RpcProblem(scene, table, settings)
    return _Problem(scene, table, settings, ties, lines)


def adjust(scene: SceneModel, table: GcpTable, settings: AdjustmentSettings | None = None,
           progress: Callable[[float, str | None], None] | None = None,
           is_cancelled: Callable[[], bool] | None = None, ties: TieTable | None = None,
           lines: ControlLines | None = None) -> AdjustmentResult:
    """Adjust ``scene`` to the control points of ``table``, the tie points ``ties`` and the
    control lines ``lines`` (both optional); evaluate its check points. With tie points the
    control may be sparse or absent when the onboard pseudo-observations hold the datum
    (report["datum"] says how it is held); with lines too (report["lines"]["directions"] says
    whether they determine both horizontal directions)."""
    settings = settings or AdjustmentSettings()
    progress = progress or (lambda fraction, message=None: None)
    is_cancelled = is_cancelled or (lambda: False)
    table = check_inputs(scene, table, settings, ties, lines)
    held = _datum(table, settings, ties, lines)
    progress(0.02, "setting up the observations")
    tie_set = set_up_ties(scene, ties) if ties is not None and len(ties) else TieSetUp.empty()
    problem = _problem_for(scene, table, settings, tie_set, set_up_lines(scene, lines))
    n_eq, n_unknowns = problem.counts()
    if n_eq <= n_unknowns:
        raise InputError(f"too few GCPs for the chosen model: {len(problem.obs)} image observations give {n_eq} "
                         f"equations for {n_unknowns} unknowns; add GCPs or choose a simpler trajectory model "
                         "(lower order, longer interval) or fewer interior parameters")
    _, system = problem.system()
    determinability = check_determinability(problem, system)
    selection = None
    selecting = settings.interior_selection == "significant" and interior_free(problem).size > 0
    try:
        est = _estimate(problem, progress, is_cancelled)
    except NoDescentError as err:
        if not selecting:
            raise
        problem, est, selection = conventional_instead(problem, lambda p: _estimate(p, progress, is_cancelled),
                                                       f"the self-calibrating solution did not converge: {err}")
    else:
        if selecting:
            problem, est, selection = select_interior(problem, est, lambda p: _estimate(p, progress, is_cancelled))
    if est.at_limit:  # said of the reported solution only, not of the interior selection's trial solutions
        log.warning("robust estimation stopped at its limit of %d passes; the flags may be incomplete",
                    len(est.passes))
    progress(0.92, "evaluating check points")
    adjusted = problem.params.adjusted_scene()
    out = _result(problem, table, adjusted, est, determinability)
    rep = out.report
    rep["interior_selection"] = selection
    if held is not None:
        held = rep["datum"] = _with_yaw(held, problem, est.st)
        log.info("datum held by %s%s", held["held_by"], f": {held['note']}" if "note" in held else "")
    adjusted.info["adjustment"] = {
        "settings": asdict(settings), "sigma0": rep["sigma0"],
        "variance_components": {k: {f: v[f] for f in ("apriori_sigma", "estimated_sigma", "unit", "estimated")}
                                for k, v in rep["variance_components"].items()},
        "reliable": rep["reliability"]["reliable"], "robust_stopped_at_limit": rep["robust"]["stopped_at_limit"],
        "parameters": [{k: p[k] for k in ("name", "value", "sigma", "unit", "mode")}
                       for p in out.report["parameters"] if p["mode"] != "fixed" or p["value"] != 0.0],
        "determinability": determinability, "interior_selection": selection,
        "check_points": {k: out.report["check_points"].get(k) for k in ("points", "image", "ground")}}
    if held is not None:
        adjusted.info["adjustment"]["datum"] = {k: held[k] for k in ("held_by", "control_points", "control_lines",
                                                                "note", "yaw") if k in held}
        adjusted.info["adjustment"]["tie_points"] = int(problem.ties.ids.size)
    if "lines" in rep:
        adjusted.info["adjustment"]["lines"] = {k: rep["lines"][k] for k in ("lines", "points", "flagged_line_ids",
                                                                             "across_rmse_m", "directions")}
    return out


@dataclass
class _Estimate:
    """The last solution and its statistics, the robust passes' log, whether the loop stopped
    at its pass limit, the variance components (group -> (sum of p v^2 with the stated sigmas,
    redundancy, count)) over the inliers (n,) of the last pass, and the truncation factor."""
    result: dict
    st: Statistics
    passes: list
    at_limit: bool
    components: dict
    inlier: np.ndarray
    kappa: float


def _estimate(problem: _Problem, progress, is_cancelled) -> _Estimate:
    """Solve, estimate the variance components and down-weight gross errors, alternately,
    until neither the flags nor the component factors change (see :mod:`core.adjust.robust`)."""
    s = problem.settings
    crit = _critical(s.alpha)
    robust = s.robust != "none"
    kappa = truncation(crit) if robust else 1.0
    iterate = robust or s.variance_components
    passes = []
    for k in range(s.max_robust_iterations if iterate else 1):
        label = f"robust pass {k + 1}: " if robust else f"variance component pass {k + 1}: " if iterate else ""
        result = solve(problem, progress, is_cancelled, label)
        st = statistics(problem, result["linearization"], result["system"])
        # Before any component is estimated the scale is robust: sigma0 of a first pass is
        # inflated by the gross errors themselves and would hide most of them.
        scale = robust_scale(st.w, st.redundancy) if robust and (k == 0 or not s.variance_components) else 1.0
        inlier = inliers(st, scale, crit) if robust else np.ones(len(problem.obs), bool)
        comps = components(problem, st, inlier)
        component_change = 0.0
        if s.variance_components:
            component_change = rescale(problem, comps, kappa)
            st.w, scale = normalised(problem, st.v, st.redundancy), 1.0
        before = problem.factor[:, 0] < 1.0
        lines_before = problem.line_flagged.copy()
        change = robust_weights(problem, st, scale) if robust else 0.0
        if robust:
            change = max(change, flag_lines(problem, st, scale, crit))
        after = problem.factor[:, 0] < 1.0
        passes.append({"pass": k + 1, "sigma0": st.sigma0, "down_weighted": int(after.sum()),
                       "largest_change": change, "component_change": component_change})
        log.info("%ssigma0 %.3f, %d observations down-weighted, variance components changed by %.1f %%", label,
                 st.sigma0, int(after.sum()), 100 * component_change)
        # Done when no observation changes side (the weights of the down-weighted ones then only
        # follow their already large residuals and no longer move the solution), or when the
        # last re-weighting no longer moved the solution measurably (with tens of thousands of
        # observations some always sit at the critical value and change side back and forth),
        # no control line changes side, and no variance component changes by more than its tolerance.
        settled = (change < 1e-3 or (k > 0 and (np.array_equal(before, after) or not result["iterations"]))) and \
            np.array_equal(lines_before, problem.line_flagged)
        if not iterate or (settled and component_change < COMPONENT_TOLERANCE):
            return _Estimate(result, st, passes, False, comps, inlier, kappa)
    return _Estimate(result, st, passes, True, comps, inlier, kappa)


def _result(problem: _Problem, table: GcpTable, adjusted: SceneModel, est: _Estimate,
            determinability: list) -> AdjustmentResult:
    crit = _critical(problem.settings.alpha)
    result, st = est.result, est.st
    params = problem.params
    free = params.free
    sigma = np.full(len(params.params), np.nan)
    sigma[free] = st.sigma0 * np.sqrt(np.diag(st.Q))
    d = np.sqrt(np.diag(st.Q))
    corr_matrix = st.Q / np.outer(d, d)
    parameters = []
    for i, p in enumerate(params.params):
        parameters.append({"name": p.name, "block": p.block, "value": p.value, "sigma": None if np.isnan(sigma[i])
                           else float(sigma[i]), "unit": p.unit, "mode": p.mode,
                           "significant": None if np.isnan(sigma[i]) or p.block in ("position", "attitude")
                           else bool(abs(p.value) > 1.96 * sigma[i])})
    pairs = correlated_pairs(corr_matrix, [params.params[i] for i in free])
    for pair in pairs:
        if pair["trajectory"]:
            log.warning("%s and %s are correlated %.4f: the GCPs hardly separate them (their sigmas say by how "
                        "much); onboard sigmas (pseudo-observations) would", pair["a"], pair["b"], pair["r"])
    flagged = np.abs(st.w).max(axis=1) > crit
    gcp = ~(problem.is_tie | problem.is_line)
    rows = problem.rows[gcp]
    n = len(table)
    points = {"id": table.id, "role": table.role, "camera": table.camera, "col": table.col, "row": table.row,
              "res_col": np.full(n, np.nan), "res_row": np.full(n, np.nan), "w_col": np.full(n, np.nan),
              "w_row": np.full(n, np.nan), "redundancy": np.full(n, np.nan), "weight": np.full(n, np.nan),
              "flagged": np.zeros(n, bool)}
    points["res_col"][rows], points["res_row"][rows] = st.v[gcp, 0], st.v[gcp, 1]
    points["w_col"][rows], points["w_row"][rows] = st.w[gcp, 0], st.w[gcp, 1]
    points["redundancy"][rows] = st.redundancy[gcp].mean(axis=1)
    points["weight"][rows] = problem.factor[gcp, 0]
    points["flagged"][rows] = flagged[gcp]
    checks = np.nonzero(table.role == "check")[0]
    after = accuracy(adjusted, table, checks, problem.settings.alpha, problem.scale)
    before = accuracy(problem.scene, table, checks, problem.settings.alpha, problem.scale)
    if checks.size:
        points["res_col"][checks], points["res_row"][checks] = after["residuals"][:, 0], after["residuals"][:, 1]
        points["flagged"][checks] = after["is_flagged"]
    after["intersection"] = intersection_accuracy(adjusted, table, checks, after.get("is_flagged"))
    before["intersection"] = intersection_accuracy(problem.scene, table, checks)
    _log_check_points(before, after)
    points["res_px"] = np.hypot(points["res_col"], points["res_row"])
    # Robust runs leave their flagged observations out of the residual figures; plain ones keep all.
    good = ~flagged if problem.settings.robust != "none" else np.ones_like(flagged)
    # sigma0 of the stated sigmas: over the inliers (with their redundancy) when the variance
    # components are estimated, else over all observations as weighted.
    sigma0, dof = stated_sigma0(est.components, est.kappa) if problem.settings.variance_components else \
        (st.sigma0, st.dof)
    chi2_lo, chi2_hi = stats.chi2.ppf([0.025, 0.975], dof) / dof
    problems = breakdown(problem, st, flagged, est.inlier)
    reliable = all(p["reliable"] for p in problems)
    for p in problems:
        log.warning("%s%s", p["message"], "" if p["reliable"] else "; the result is not reliable")
    report = {
        "settings": asdict(problem.settings),
        "observations": {"control_points": problem.n_control, "image_observations": int(gcp.sum()),
                         "check_points": int(checks.size), "unknowns": int(free.size),
                         "ground_unknowns": int(3 * problem.estimated.size),
                         "tie_points": problem.ties.counts(), "tie_observations": int(problem.is_tie.sum()),
                         "line_points": int(problem.is_line.sum()),
                         "degrees_of_freedom": st.dof},
        "iterations": result["iterations"],
        "robust": {"method": problem.settings.robust, "passes": est.passes, "critical_w": crit,
                   "stopped_at_limit": est.at_limit, "flagged": int(flagged.sum()),
                   "flagged_ids": [str(i) for i in table.id[rows][flagged[gcp]][:1000]],
                   "flagged_tie_ids": [str(i) for i in problem.ties.table.id[problem.rows[problem.is_tie]][flagged[problem.is_tie]][:1000]]},
        "reliability": {"reliable": reliable, "problems": problems},
        "sigma0": sigma0,
        "sigma0_adjusted": st.sigma0,
        "sigma0_test": {"ratio_bounds_95": [math.sqrt(chi2_lo), math.sqrt(chi2_hi)],
                        "passed": bool(chi2_lo <= sigma0 ** 2 <= chi2_hi)},
        "variance_components": component_report(problem, est.components, est.kappa),
        "determinability": determinability,
        "parameters": parameters,
        "high_correlations": pairs,
        "control_residuals": _residual_summary(st.v[good & gcp]),
        "control_residuals_per_chip": {
            f"{c.name}/{ch.name or k + 1}": _residual_summary(st.v[good & gcp & (problem.obs.camera == ci)
                                                                    & (problem.obs.chip == k)])
            for ci, c in enumerate(problem.scene.cameras) for k, ch in enumerate(c.chips)},
        "check_points": _check_point_report(after),
        "check_points_before": _check_point_report(before),
        "trajectory": _trajectory_curves(problem) if problem.params.position_basis is not None else None,
    }
    if len(problem.ties.table):
        report["tie_points"], ties = _tie_points(problem, st, flagged, good)
    else:
        ties = {}
    lines = {}
    if len(problem.lines):
        report["lines"], lines = linepoints.results(problem, adjusted, st, flagged)
    return AdjustmentResult(adjusted, report, points, ties, lines)


def _tie_points(problem: _Problem, st: Statistics, flagged: np.ndarray, good: np.ndarray) -> tuple[dict, dict]:
    """The tie points' report entry and per input observation arrays (see AdjustmentResult).

    Their adjusted ground positions are no absolute accuracy (no known truth; with few GCPs
    they share the datum's error): the relative accuracy is told by the image residuals."""
    tie = problem.is_tie
    table = problem.ties.table
    n = len(table)
    rows = problem.rows[tie]
    out = {"id": table.id, "camera": table.camera, "col": table.col, "row": table.row}
    for name, values in (("res_col", st.v[tie, 0]), ("res_row", st.v[tie, 1]), ("w_col", st.w[tie, 0]),
                         ("w_row", st.w[tie, 1]), ("weight", problem.factor[tie, 0])):
        out[name] = np.full(n, np.nan)
        out[name][rows] = values
    out["flagged"] = np.zeros(n, bool)
    out["flagged"][rows] = flagged[tie]
    lon, lat, h = (np.full(n, np.nan) for _ in range(3))
    point = problem.obs.point[tie]
    lon[rows], lat[rows], h[rows] = ecef_to_geodetic(problem.ground[point])
    out.update(lon=lon, lat=lat, h=h)
    cams = problem.scene.cameras
    report = {**problem.ties.counts(),
              "flagged": int(flagged[tie].sum()),
              "span": problem.ties.span(problem.scene),
              "residuals": _residual_summary(st.v[tie & good]),
              "residuals_per_camera": {c.name: _residual_summary(st.v[tie & good & (problem.obs.camera == ci)])
                                       for ci, c in enumerate(cams)},
              "relative_accuracy": "image residuals of the tie observations (px, flagged ones left out) measure the "
                                   "block's relative accuracy; the tie points' adjusted ground positions carry the "
                                   "datum's error as well and are no absolute accuracy figure"}
    return report, out


def _check_point_report(figures: dict) -> dict:
    """The JSON part of :func:`accuracy`'s figures (with their ``intersection``): no per-row arrays."""
    out = {k: v for k, v in figures.items() if k not in ("residuals", "en", "is_flagged")}
    out["intersection"] = {k: v for k, v in figures["intersection"].items() if k != "errors"}
    return out


def _log_check_points(before: dict, after: dict) -> None:
    """The check figures, and a model error where it is found."""
    if after.get("model_error"):
        log.warning("%s", model_error_message(after))
    for line in summary_lines(before, after):
        log.info("check points %s", line)


def correlated_pairs(corr: np.ndarray, params: list) -> list[dict]:
    """Pairs of unknowns worth a look: |r| > 0.9 where an interior parameter takes part, and
    |r| > 0.999 between trajectory terms (a split the control barely determines)."""
    trajectory = np.array([p.block in ("position", "attitude") for p in params])
    a, b = np.triu_indices(len(params), 1)
    r = corr[a, b]
    both = trajectory[a] & trajectory[b]
    keep = np.nonzero(np.where(both, np.abs(r) > 0.999, np.abs(r) > 0.9))[0]
    keep = keep[np.argsort(-np.abs(r[keep]))][:50]
    return [{"a": params[a[k]].name, "b": params[b[k]].name, "r": float(r[k]), "trajectory": bool(both[k])}
            for k in keep]


def _residual_summary(v: np.ndarray) -> dict:
    if v.size == 0:
        return {"count": 0}
    px = np.hypot(v[:, 0], v[:, 1])
    return {"count": int(v.shape[0]), "rmse_col": float(np.sqrt(np.mean(v[:, 0] ** 2))),
            "rmse_row": float(np.sqrt(np.mean(v[:, 1] ** 2))), "max_col": float(np.max(np.abs(v[:, 0]))),
            "max_row": float(np.max(np.abs(v[:, 1]))), "max": float(px.max())}


def _trajectory_curves(problem: _Problem, samples: int = 200) -> dict:
    """Corrections against time, for plots: position (m, ECEF) and attitude (rad); with one
    correction per camera, the reference (first) camera's there and every camera's in
    ``per_camera`` (camera name -> {position, attitude})."""
    t_min, t_max = problem.scene.time_span()
    t = np.linspace(t_min, t_max, samples)
    params = problem.params
    pb, ab = params.position_basis, params.attitude_basis

    def curves(camera: int) -> dict:
        corr = params.trajectory_correction(camera)
        return {"position": (pb.matrix(t) @ corr.position_coefficients).tolist(),
                "attitude": (ab.matrix(t) @ corr.attitude_coefficients).tolist()}

    out = {"time": t.tolist(), **curves(0), "position_knots": pb.knot_times().tolist(),
           "attitude_knots": ab.knot_times().tolist()}
    if params.per_camera:
        out["per_camera"] = {cam.name: curves(c) for c, cam in enumerate(problem.scene.cameras)}
    return out
