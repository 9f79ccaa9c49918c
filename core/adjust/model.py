"""Image observations of ground points: exact image residuals and their analytic Jacobians.

For an observation imaged at (col, row) in camera c on chip k, the line time t = timing(row) +
time_offset_k fixes the measured platform state. With the current corrections the satellite is
at S = S_m(t) + Bp(t) Cp, moving at V = V_m(t) + Bp'(t) Cp, and the body turns by R = R_m(t) @
E(Ba(t) Ca); the camera axes are I_c @ E(delta_c) (installation). A ground point X projects to
normalised camera coordinates

    w = (I_c E(delta_c))^T R^T g,   (ux, uy) = (w0 / w2, w1 / w2),

g being the apparent direction S -> X (refraction and velocity aberration as in the sensor
model; held fixed in the derivatives, where they change nothing measurable). The detector's
own (ux, uy) follows from the chip and camera terms (Zheng et al. 2015 eq. 4, Zhang et al. 2015
eq. 7); r_u = projected - detector (radians) vanishes where the current model images X.

The residual is exact: :func:`project` finds, by Newton's method on the measured chip, the
(col, row) where the current model images X (r_u = 0, the line time and detector moving with
it) and the residual is that position minus the measured one, however large the corrections
(a fixed first-order map of the input scene holds only while they stay small). Its Jacobian by
a parameter p follows from r_u(col, row, p) = 0: d(col, row)/dp = T d r_u/dp with the 2x2 map
T = -(d r_u / d(col, row))^-1 of the current model at the imaged position (:func:`pixel_map`).

Arrays: n observations; Jacobian blocks (n, 2, k) in pixels per unit of the parameter.
"""
from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from ..geodesy import C_LIGHT, ecef_to_geodetic, up_vector
from ..model import corrections as corr
from ..model.camera import CAMERA_TERMS, corrected_image_plane
from ..model.sensor import SceneModel, in_chunks, rows_by
from ..model.trajectory import Platform
from ..rotations import rotation_and_derivatives, rotation_matrices
from .parameters import ANGLES, ParameterSet, trajectory_groups

PROJECTION_TOLERANCE = 1e-8  # px: the last Newton step of an exact projection (rounding: ~5e-10 px)
PROJECTION_ITERATIONS = 40
MAP_REFRESH = 4              # Newton iterations between refreshes of the pixel map (a chord method)


@dataclass
class ImageObservations:
    """n image observations, imaged at (col, row) (n,) px: camera, chip, point (index of the
    ground point), d (detector index on the chip), t (s), the measured platform state pos, vel
    (n,3) and rot (n,3,3) at t, the trajectory basis windows at t (first (n,) row of the position /
    attitude block, offset by camera with one correction per camera; weights (n, w), pos_rates
    (n, w) their time derivatives, 1/s) and sigma (n,) px. The problem's own observations are
    imaged where they were measured; :func:`project` moves copies to where the model images them."""
    camera: np.ndarray
    chip: np.ndarray
    point: np.ndarray
    d: np.ndarray
    t: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    rot: np.ndarray
    pos_first: np.ndarray
    pos_weights: np.ndarray
    pos_rates: np.ndarray
    att_first: np.ndarray
    att_weights: np.ndarray
    sigma: np.ndarray
    col: np.ndarray
    row: np.ndarray

    def __len__(self) -> int:
        return int(self.t.size)

    def select(self, m) -> "ImageObservations":
        return ImageObservations(**{f.name: getattr(self, f.name)[m] for f in fields(self)})

    __getitem__ = select  # chunks of the observations (core.model.sensor.in_chunks)


class Imaging:
    """Moves observations along their detector line and in time: the measured trajectory of a
    scene (tabulated once over its time span; in a block's composite each scene's over its own)
    and the trajectory bases of a parameter set."""

    def __init__(self, scene: SceneModel, params: ParameterSet):
        self.scene, self.params = scene, params
        # The measured trajectories alone, tabulated (1 ms steps) rather than Lagrange per point.
        self.groups = [np.array(cams, dtype=np.int64) for cams in trajectory_groups(scene)]
        self.platforms = [_measured_table(scene, cams) for cams in self.groups]
        self.group_of = np.empty(len(scene.cameras), dtype=np.int64)
        for g, cams in enumerate(self.groups):
            self.group_of[cams] = g
        self.offsets = [np.array([ch.col_offset for ch in cam.chips], dtype=float) for cam in scene.cameras]

    def at(self, obs: ImageObservations, col: np.ndarray, row: np.ndarray) -> ImageObservations:
        """The observations ``obs`` imaged at (col, row) (n,) px on their own chips (the chip's
        detector line extended beyond the columns it delivers)."""
        d, t = np.empty(col.size), np.empty(col.size)
        for cam, offsets, m in zip(self.scene.cameras, self.offsets, rows_by(obs.camera, len(self.scene.cameras))):
            d[m] = col[m] - offsets[obs.chip[m]] - 0.5
            t[m] = cam.timing.time(row[m]) + cam.time_offset(obs.chip[m])
        if len(self.platforms) == 1:
            pos, vel, rot = self.platforms[0].state(t)
        else:
            pos, vel, rot = np.empty((t.size, 3)), np.empty((t.size, 3)), np.empty((t.size, 3, 3))
            for platform, m in zip(self.platforms, rows_by(self.group_of[obs.camera], len(self.platforms))):
                pos[m], vel[m], rot[m] = platform.state(t[m])
        pos_first, pos_weights = self.params.window("position", t, obs.camera)
        att_first, att_weights = self.params.window("attitude", t, obs.camera)
        pos_rates = self.params.window_weights("position", t, pos_first, rates=True)
        return ImageObservations(obs.camera, obs.chip, obs.point, d, t, pos, vel, rot, pos_first, pos_weights,
                                 pos_rates, att_first, att_weights, obs.sigma, col, row)


def _measured_table(scene: SceneModel, cams: np.ndarray) -> Platform:
    """The measured trajectory the cameras ``cams`` (indices, one trajectory group) see,
    tabulated over their lines: the scene's own platform when they see it uncorrected (an
    onboard scene; its table is the same one, made once for both), else a platform of its own."""
    seen = scene.platform_of(int(cams[0]))
    if seen.correction is None and seen.cache_step == scene.platform.cache_step and \
            all(scene.platform_of(int(c)) is seen for c in cams):
        scene.prepare(int(cams[0]))
        return seen
    measured = scene.platform.trajectory_of(scene.cameras[cams[0]].name)
    platform = Platform(measured.ephemeris, measured.attitude, cache_step=scene.platform.cache_step)
    platform.prepare(scene.time_spans(cams))
    return platform


def build_observations(imaging: Imaging, camera, col, row, point, sigma) -> ImageObservations:
    """Observations (col, row measured px, sigma px) of ground points ``point`` (indices) in
    cameras ``camera`` (indices), imaged where they were measured."""
    camera = np.asarray(camera, dtype=np.int64)
    col, row = np.asarray(col, dtype=float), np.asarray(row, dtype=float)
    n = col.size
    chip = np.zeros(n, dtype=np.int64)
    for c, cam in enumerate(imaging.scene.cameras):
        m = camera == c
        chip[m] = cam.chip_index(col[m])
    empty = np.zeros((n, 0))
    obs = ImageObservations(camera, chip, np.asarray(point, dtype=np.int64), empty, empty, empty, empty, empty,
                            empty, empty, empty, empty, empty,
                            np.broadcast_to(np.asarray(sigma, dtype=float), (n,)).copy(), col, row)
    return imaging.at(obs, col, row)


MAP_STEP = 0.01  # px: the differences of the pixel map (accurate to ~1e-5 relative, rounding ~1e-7)


def pixel_map(model: "Model", imaging: Imaging, obs: ImageObservations, x: np.ndarray,
              r0: np.ndarray) -> np.ndarray:
    """T (n,2,2): (dcol, drow) = T @ r_u, minus the inverse of d r_u / d(col, row) of the current
    model at the imaged positions of ``obs``, where r_u is r0 (n,2), by differences of MAP_STEP px
    in column (detector) and row (line time) at ground points x (n,3). The curvature of r_u is
    ~2e-3 per px, so unit differences would bias the Jacobian by ~1e-3."""
    right = obs.select(slice(None))
    right.d = obs.d + MAP_STEP
    (a, c) = ((model.residuals_u(right, x) - r0) / MAP_STEP).T
    (b, d) = ((model.residuals_u(imaging.at(obs, obs.col, obs.row + MAP_STEP), x) - r0) / MAP_STEP).T
    # -inverse of [[a, b], [c, d]] written out (np.linalg.inv of millions of 2x2 matrices is ~100x slower)
    with np.errstate(all="ignore"):
        det = a * d - b * c
        return -np.stack([np.stack([d, -b], axis=1), np.stack([-c, a], axis=1)], axis=1) / det[:, None, None]


def project(model: "Model", imaging: Imaging, obs: ImageObservations, x: np.ndarray, start: ImageObservations,
            T: np.ndarray | None = None) -> tuple[ImageObservations, np.ndarray, np.ndarray]:
    """Where the current model images ground points x (n,3) of observations ``obs`` on their
    measured chips: Newton's method on (col, row) from ``start`` (the same observations imaged
    near there, e.g. at the last projection), the pixel map T (n,2,2) given or made at the start
    and refreshed every MAP_REFRESH iterations, to a last step below PROJECTION_TOLERANCE.
    Returns (the observations imaged at the last iterate, T there, the imaged (col, row) (n,2):
    the last iterate plus the last step); NaN where the model does not image a point (behind the
    camera, or no convergence)."""
    cur = start
    r_u = model.residuals_u(cur, x)
    if T is None:
        T = pixel_map(model, imaging, cur, x, r_u)
    step = np.einsum("nij,nj->ni", T, r_u)
    for it in range(PROJECTION_ITERATIONS):
        if not np.max(np.where(np.isfinite(step), np.abs(step), 0.0), initial=0.0) > PROJECTION_TOLERANCE:
            break
        cur = imaging.at(obs, cur.col + step[:, 0], cur.row + step[:, 1])
        r_u = model.residuals_u(cur, x)
        if (it + 1) % MAP_REFRESH == 0:
            T = pixel_map(model, imaging, cur, x, r_u)
        step = np.einsum("nij,nj->ni", T, r_u)
    else:
        step[np.max(np.abs(step), axis=1) > PROJECTION_TOLERANCE] = np.nan
    return cur, T, np.stack([cur.col, cur.row], axis=1) + step


@dataclass
class Jacobian:
    """d(residual px)/d(parameter) blocks for n observations: S (n,2,3) platform position, V
    (n,2,3) platform velocity (through aberration: a drift of the position changes it),
    angles (n,2,3) attitude angles, installation (n,2,3), ground (n,2,3), chip (n,2,4)
    (focal-plane chips use the first 3: dx, dy, theta; look-angle chips ux0, ux1, uy0, uy1),
    camera (n,2,10) in the order of CAMERA_TERMS."""
    S: np.ndarray
    V: np.ndarray
    angles: np.ndarray
    installation: np.ndarray
    ground: np.ndarray
    chip: np.ndarray
    camera: np.ndarray


def _scaled_blocks(jac: Jacobian, T: np.ndarray) -> tuple[np.ndarray, ...]:
    """T @ each block (n,2,k) of ``jac`` (radians per unit) with the pixel maps T (n,2,2): the
    blocks in px per unit, in field order."""
    # written out: 2x2 products are memory-bound
    return tuple(np.stack([T[:, 0, 0, None] * a[:, 0] + T[:, 0, 1, None] * a[:, 1],
                           T[:, 1, 0, None] * a[:, 0] + T[:, 1, 1, None] * a[:, 1]], axis=1)
                 for a in (getattr(jac, f.name) for f in fields(Jacobian)))


class Model:
    """The collinearity model of a scene under a parameter set's current values."""

    def __init__(self, scene: SceneModel, params: ParameterSet):
        self.scene = scene
        self.params = params
        values = params.values()
        self.cp = values[params.block_indices("position")]
        self.ca = values[params.block_indices("attitude")]
        n_cam = len(scene.cameras)
        self.inst = np.array([[params.params[params.index[f"{c.name}.{a}"]].value for a in ANGLES]
                              for c in scene.cameras])
        self.cam_terms = np.zeros((n_cam, len(CAMERA_TERMS)))
        for c, cam in enumerate(scene.cameras):
            for j, term in enumerate(CAMERA_TERMS):
                i = params.index.get(f"{cam.name}.{term}")
                if i is not None:
                    self.cam_terms[c, j] = params.params[i].value
        self.chip_terms = {}
        for c, cam in enumerate(scene.cameras):
            for k in range(len(cam.chips)):
                terms, idx = params.chip_indices(c, k)
                self.chip_terms[c, k] = values[idx]

    # --- the pieces --------------------------------------------------------------------------
    def platform(self, obs: ImageObservations, derivatives: bool = True):
        """(S (n,3) corrected position, V (n,3) corrected velocity (as the written correction
        has it: aberration follows a drift of the position), E (n,3,3) attitude correction and
        dE (n,3,3,3) its derivatives by (roll, pitch, yaw), None without ``derivatives``) at the
        observations."""
        cp = self.cp[obs.pos_first[:, None] + np.arange(obs.pos_weights.shape[1])]
        S = obs.pos + np.einsum("nw,nwa->na", obs.pos_weights, cp)
        V = obs.vel + np.einsum("nw,nwa->na", obs.pos_rates, cp)
        angles = np.einsum("nw,nwa->na", obs.att_weights,
                           self.ca[obs.att_first[:, None] + np.arange(obs.att_weights.shape[1])])
        E, dE = rotation_and_derivatives(angles) if derivatives else (rotation_matrices(angles), None)
        return S, V, E, dE

    def detector(self, obs: ImageObservations, with_jacobian: bool = False):
        """Detector (ux, uy) (n,2) and, with_jacobian, d/d chip terms (n,2,4) and d/d camera
        terms (n,2,10)."""
        n = len(obs)
        u = np.empty((n, 2))
        j_chip = np.zeros((n, 2, 4)) if with_jacobian else None
        j_cam = np.zeros((n, 2, len(CAMERA_TERMS))) if with_jacobian else None
        most = max(len(cam.chips) for cam in self.scene.cameras)
        rows = rows_by(obs.camera * most + obs.chip, len(self.scene.cameras) * most)
        for c, cam in enumerate(self.scene.cameras):
            for k, chip in enumerate(cam.chips):
                m = rows[c * most + k]
                if m.size == 0:
                    continue
                terms = self.chip_terms[c, k]
                d = obs.d[m]
                if chip.kind == "look_angle":
                    ux, uy = chip.look(d)
                    s = d / chip.n_pixels
                    u[m, 0] = ux + terms[0] + terms[1] * s
                    u[m, 1] = uy + terms[2] + terms[3] * s
                    if with_jacobian:
                        j_chip[m, 0, 0], j_chip[m, 0, 1] = 1.0, s
                        j_chip[m, 1, 2], j_chip[m, 1, 3] = 1.0, s
                    continue
                u[m], jc, jk = corrected_image_plane(cam, chip, terms, self.cam_terms[c], d, with_jacobian)
                if with_jacobian:
                    j_chip[m, :, :3], j_cam[m] = jc, jk
        return u, j_chip, j_cam

    def _local(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(up vectors (n,3), ellipsoidal heights (n,) m) of ground points x (n,3), kept for the
        last x (a projection evaluates the same points again and again)."""
        if getattr(self, "_x", None) is not x:
            lon, lat, h = ecef_to_geodetic(x)
            self._x, self._up_h = x, (up_vector(lon, lat), h)
        return self._up_h

    def residuals_u(self, obs: ImageObservations, x: np.ndarray) -> np.ndarray:
        """r_u (n,2) radians: projected minus detector normalised coordinates."""
        up, h = self._local(x)
        return in_chunks(lambda *chunk: self._evaluate(*chunk, False)[0], x, up, h, obs)

    def linearize(self, obs: ImageObservations, x: np.ndarray, T: np.ndarray) -> Jacobian:
        """The Jacobian in px per parameter unit of observations imaged at ``obs`` (where the
        model images x (n,3), see :func:`project`) with the pixel map T (n,2,2) there."""
        up, h = self._local(x)
        return Jacobian(*in_chunks(lambda x, up, h, T, obs: _scaled_blocks(self._evaluate(x, up, h, obs, True)[1], T),
                                   x, up, h, T, obs))

    def _evaluate(self, x: np.ndarray, up: np.ndarray, h: np.ndarray, obs: ImageObservations, with_jacobian: bool):
        """(r_u (n,2), the Jacobian or None) of observations ``obs`` of ground points x (n,3) with
        local up vectors up (n,3) and ellipsoidal heights h (n,) m: one chunk of the observations
        (:meth:`residuals_u`, :meth:`linearize` run chunks on a thread per core)."""
        S, V, E, dE = self.platform(obs, with_jacobian)
        g = corr.apparent_direction(x, S, V, up, h, self.scene.aberration,
                                    self.scene.refraction) * np.linalg.norm(x - S, axis=1, keepdims=True)
        q = np.einsum("nji,nj->ni", obs.rot, g)          # measured body frame
        y = np.einsum("nji,nj->ni", E, q)                # corrected body frame: w = mount^T y
        n = len(obs)
        w = np.empty((n, 3))
        dw_angles = np.empty((n, 3, 3)) if with_jacobian else None   # [n, angle, w component]
        dw_inst = np.empty((n, 3, 3)) if with_jacobian else None
        dw_ground = np.empty((n, 3, 3)) if with_jacobian else None   # [n, X component, w component]
        for c, (cam, m) in enumerate(zip(self.scene.cameras, rows_by(obs.camera, len(self.scene.cameras)))):
            if m.size == 0:
                continue
            inst, d_inst = rotation_and_derivatives(self.inst[c])
            mount = cam.installation @ inst                 # camera -> body
            w[m] = y[m] @ mount
            if with_jacobian:
                for a in range(3):
                    dw_angles[m, a] = np.einsum("nji,nj->ni", dE[m, a], q[m]) @ mount
                    dw_inst[m, a] = (y[m] @ cam.installation) @ d_inst[a]
                dw_ground[m] = (obs.rot[m] @ E[m]) @ mount
        proj = w[:, :2] / w[:, 2:3]
        det, j_chip, j_cam = self.detector(obs, with_jacobian)
        r_u = proj - det
        if not with_jacobian:
            return r_u, None

        def projected(dw):  # d(ux, uy) from d(w) (..., 3) -> (n, 2, k)
            return (dw[:, :, :2] - proj[:, None, :] * dw[:, :, 2:3]).transpose(0, 2, 1) / w[:, 2, None, None]

        j_ground = projected(dw_ground)
        # Velocity aberration, normalize(u + v/c): a velocity change dv turns the apparent ray by
        # (I - u u') dv / c. Small (1e-3 of a position change's effect per metre of a drift
        # coefficient) but not along the weak position/attitude directions, which Gauss-Newton
        # would otherwise creep along (linear convergence at rate ~0.9, CBERS-02B, no onboard sigmas).
        j_velocity = np.zeros_like(j_ground)
        if self.scene.aberration:
            u = g / np.linalg.norm(g, axis=1, keepdims=True)
            dg_dv = (np.eye(3) - u[:, :, None] * u[:, None, :]) * (np.linalg.norm(x - S, axis=1) / C_LIGHT)[
                :, None, None]
            j_velocity = projected(dg_dv @ dw_ground)
        return r_u, Jacobian(-j_ground, j_velocity, projected(dw_angles), projected(dw_inst), j_ground, -j_chip,
                             -j_cam)

