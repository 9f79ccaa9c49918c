"""Image observations of ground points: collinearity residuals and their analytic Jacobians.

For an observation at measured image position (col, row) in camera c on chip k, the line
time t = timing(row) + time_offset_k fixes the measured platform state. With the current
corrections the satellite is at S = S_m(t) + Bp(t) Cp and the body turns by
R = R_m(t) @ E(Ba(t) Ca); the camera axes are I_c @ E(delta_c) (installation). A ground
point X projects to normalised camera coordinates

    w = (I_c E(delta_c))^T R^T g,   (ux, uy) = (w0 / w2, w1 / w2),

g being the apparent direction S -> X (refraction and velocity aberration as in the sensor
model; held fixed in the derivatives, where they change nothing measurable). The detector's
own (ux, uy) follows from the chip and camera terms (seed 000 eq. 4, seed 001 eq. 7). The
residual r_u = projected - detector (radians) becomes pixels through the 2x2 map
T = -(d r_u / d (col, row))^-1 of the input scene at the observation: r = T r_u is the
(predicted - measured) (col, row) to first order, so residuals and sigmas are in pixels.

Arrays: n observations; Jacobian blocks (n, 2, k) in pixels per unit of the parameter.
"""
from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from ..geodesy import ecef_to_geodetic, up_vector
from ..model import corrections as corr
from ..model.camera import CAMERA_TERMS, corrected_image_plane
from ..model.sensor import SceneModel
from ..model.trajectory import Platform
from ..rotations import rotation_and_derivatives
from .parameters import ANGLES, ParameterSet


@dataclass
class ImageObservations:
    """Fixed data of n image observations: camera, chip, point (index of the ground point),
    d (detector index on the chip), t (s), the measured platform state pos, vel (n,3) and
    rot (n,3,3), the trajectory basis windows (first (n,) row of the position / attitude block, offset by
    camera with one correction per camera; weights (n, w)), T (n,2,2),
    sigma (n,) px and the measured col, row (n,) px."""
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
    att_first: np.ndarray
    att_weights: np.ndarray
    T: np.ndarray
    sigma: np.ndarray
    col: np.ndarray
    row: np.ndarray

    def __len__(self) -> int:
        return int(self.t.size)

    def select(self, m) -> "ImageObservations":
        return ImageObservations(**{f.name: getattr(self, f.name)[m] for f in fields(self)})

    def at_time(self, params: ParameterSet, t: np.ndarray, platform) -> "ImageObservations":
        """The same observations imaged at other times t (measured state and windows redone)."""
        out = self.select(slice(None))
        out.t = t
        # The measured trajectory alone, tabulated (1 ms steps) rather than Lagrange per point.
        measured = Platform(platform.ephemeris, platform.attitude, cache_step=platform.cache_step)
        measured.prepare(float(t.min()), float(t.max()))
        out.pos, out.vel, out.rot = measured.state(t)
        out.pos_first, out.pos_weights = params.window("position", t, self.camera)
        out.att_first, out.att_weights = params.window("attitude", t, self.camera)
        return out


def build_observations(scene: SceneModel, params: ParameterSet, camera, col, row, point, sigma,
                       ground: np.ndarray) -> ImageObservations:
    """Observations (col, row measured px, sigma px) of ground points ``point`` (indices into
    ``ground`` (m, 3) ECEF, used for the pixel map) in cameras ``camera`` (indices)."""
    camera = np.asarray(camera, dtype=np.int64)
    col, row = np.asarray(col, dtype=float), np.asarray(row, dtype=float)
    n = col.size
    chip = np.zeros(n, dtype=np.int64)
    d = np.zeros(n)
    t = np.zeros(n)
    for c, cam in enumerate(scene.cameras):
        m = camera == c
        chip[m] = cam.chip_index(col[m])
        d[m] = col[m] - np.array([ch.col_offset for ch in cam.chips])[chip[m]] - 0.5
        t[m] = cam.timing.time(row[m]) + cam.time_offset(chip[m])
    empty = np.zeros((n, 0))
    obs = ImageObservations(camera, chip, np.asarray(point, dtype=np.int64), d, t, empty, empty, empty,
                            np.zeros(n, np.int64), empty, np.zeros(n, np.int64), empty, np.zeros((n, 2, 2)),
                            np.broadcast_to(np.asarray(sigma, dtype=float), (n,)).copy(), col, row)
    obs = obs.at_time(params, t, scene.platform)
    obs.T = pixel_map(scene, params, obs, ground[obs.point])
    return obs


def pixel_map(scene: SceneModel, params: ParameterSet, obs: ImageObservations, x: np.ndarray) -> np.ndarray:
    """T (n,2,2): (dcol, drow) = T @ r_u, minus the inverse of d r_u / d(col, row), by unit
    differences in column (detector) and row (line time) at ground points x (n,3)."""
    r0 = Model(scene, params).residuals_u(obs, x)
    period = np.array([cam.timing.mean_period() for cam in scene.cameras])[obs.camera]
    later = obs.at_time(params, obs.t + period, scene.platform)
    d_row = Model(scene, params).residuals_u(later, x) - r0
    right = obs.select(slice(None))
    right.d = obs.d + 1.0
    d_col = Model(scene, params).residuals_u(right, x) - r0
    return -np.linalg.inv(np.stack([d_col, d_row], axis=2))


@dataclass
class Jacobian:
    """d(residual px)/d(parameter) blocks for n observations: S (n,2,3) platform position,
    angles (n,2,3) attitude angles, installation (n,2,3), ground (n,2,3), chip (n,2,4)
    (focal-plane chips use the first 3: dx, dy, theta; look-angle chips ux0, ux1, uy0, uy1),
    camera (n,2,10) in the order of CAMERA_TERMS."""
    S: np.ndarray
    angles: np.ndarray
    installation: np.ndarray
    ground: np.ndarray
    chip: np.ndarray
    camera: np.ndarray


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
    def platform(self, obs: ImageObservations):
        """(S (n,3) corrected position, E (n,3,3) attitude correction and dE (n,3,3,3) its
        derivatives by (roll, pitch, yaw)) at the observations."""
        S = obs.pos + np.einsum("nw,nwa->na", obs.pos_weights,
                                self.cp[obs.pos_first[:, None] + np.arange(obs.pos_weights.shape[1])])
        angles = np.einsum("nw,nwa->na", obs.att_weights,
                           self.ca[obs.att_first[:, None] + np.arange(obs.att_weights.shape[1])])
        E, dE = rotation_and_derivatives(angles)
        return S, E, dE

    def detector(self, obs: ImageObservations, with_jacobian: bool = False):
        """Detector (ux, uy) (n,2) and, with_jacobian, d/d chip terms (n,2,4) and d/d camera
        terms (n,2,10)."""
        n = len(obs)
        u = np.empty((n, 2))
        j_chip = np.zeros((n, 2, 4)) if with_jacobian else None
        j_cam = np.zeros((n, 2, len(CAMERA_TERMS))) if with_jacobian else None
        for c, cam in enumerate(self.scene.cameras):
            for k, chip in enumerate(cam.chips):
                m = np.nonzero((obs.camera == c) & (obs.chip == k))[0]
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

    def residuals_u(self, obs: ImageObservations, x: np.ndarray) -> np.ndarray:
        """r_u (n,2) radians: projected minus detector normalised coordinates."""
        return self._evaluate(obs, x, False)[0]

    def residuals(self, obs: ImageObservations, x: np.ndarray) -> np.ndarray:
        """Residuals (n,2) px, (col, row) order: predicted minus measured, to first order."""
        return np.einsum("nij,nj->ni", obs.T, self.residuals_u(obs, x))

    def linearize(self, obs: ImageObservations, x: np.ndarray) -> tuple[np.ndarray, Jacobian]:
        """(residuals (n,2) px, Jacobian in px per parameter unit)."""
        r_u, jac = self._evaluate(obs, x, True)
        T = obs.T

        def scale(a):  # T @ a for (n,2,k) blocks, written out: 2x2 products are memory-bound
            return np.stack([T[:, 0, 0, None] * a[:, 0] + T[:, 0, 1, None] * a[:, 1],
                             T[:, 1, 0, None] * a[:, 0] + T[:, 1, 1, None] * a[:, 1]], axis=1)

        return (np.einsum("nij,nj->ni", T, r_u),
                Jacobian(*(scale(getattr(jac, f.name)) for f in fields(Jacobian))))

    def _evaluate(self, obs: ImageObservations, x: np.ndarray, with_jacobian: bool):
        S, E, dE = self.platform(obs)
        lon, lat, h = ecef_to_geodetic(x)
        g = corr.apparent_direction(x, S, obs.vel, up_vector(lon, lat), h, self.scene.aberration,
                                    self.scene.refraction) * np.linalg.norm(x - S, axis=1, keepdims=True)
        q = np.einsum("nji,nj->ni", obs.rot, g)          # measured body frame
        y = np.einsum("nji,nj->ni", E, q)                # corrected body frame: w = mount^T y
        n = len(obs)
        w = np.empty((n, 3))
        dw_angles = np.empty((n, 3, 3)) if with_jacobian else None   # [n, angle, w component]
        dw_inst = np.empty((n, 3, 3)) if with_jacobian else None
        dw_ground = np.empty((n, 3, 3)) if with_jacobian else None   # [n, X component, w component]
        for c, cam in enumerate(self.scene.cameras):
            m = np.nonzero(obs.camera == c)[0]
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
        return r_u, Jacobian(-j_ground, projected(dw_angles), projected(dw_inst), j_ground, -j_chip, -j_cam)

