"""The simulated acquisition: a circular orbit, a nadir-pointing platform with a slow wobble,
the cameras of a preset (nominal and with drawn interior errors) and the true and onboard
scene models of a strip (error conventions: :mod:`simulation.simulator`).

Frames: ECEF metres, times in seconds from the epoch, image coordinates GDAL (col, row).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..core.geodesy import OMEGA_EARTH, ecef_to_geodetic, geodetic_to_ecef
from ..core.errors import InputError
from ..core.model.camera import CAMERA_TERMS, UNITS, Camera, Chip, LineTiming
from ..core.model.sensor import SceneModel
from ..core.model.trajectory import Ephemeris, Platform, QuaternionSamples
from ..core.rotations import matrix_to_quat, rot_y, rotation_from_angles
from .presets import CAMERA_ERRORS, CameraSpec, ErrorSettings, Preset, camera_term

GM_EARTH = 3.986004418e14          # m^3/s^2
EPOCH = "2010-12-15T03:00:00.000000Z"
EPHEMERIS_STEP = 1.0               # s
ATTITUDE_STEP = 0.25               # s
TRAJECTORY_MARGIN = 30.0           # s of ephemeris/attitude beyond the imaging span


# --- orbit and attitude ----------------------------------------------------------------------
def circular_orbit(altitude: float, inclination: float, lon0: float, lat0: float, t) -> tuple[np.ndarray, np.ndarray]:
    """ECEF positions and velocities (n, 3) of a circular orbit that passes, descending, over
    (lon0, lat0) degrees at t = 0, at ``altitude`` m above the ellipsoid there. t: (n,) s."""
    t = np.asarray(t, dtype=float)
    radius = float(np.linalg.norm(geodetic_to_ecef(lon0, lat0, 0.0))) + altitude
    n = math.sqrt(GM_EARTH / radius ** 3)
    ground = geodetic_to_ecef(lon0, lat0, 0.0)
    phi0 = math.asin(ground[2] / np.linalg.norm(ground))  # geocentric latitude
    sin_i, cos_i = math.sin(inclination), math.cos(inclination)
    if abs(math.sin(phi0)) > abs(sin_i):
        raise InputError(f"latitude {lat0} is beyond the reach of an orbit inclined "
                         f"{math.degrees(inclination):.1f} deg")
    u0 = math.pi - math.asin(math.sin(phi0) / sin_i)
    node = math.radians(lon0) - math.atan2(cos_i * math.sin(u0), math.cos(u0))
    p_axis = np.array([math.cos(node), math.sin(node), 0.0])
    q_axis = np.array([-cos_i * math.sin(node), cos_i * math.cos(node), sin_i])
    u = u0 + n * t
    r_inertial = radius * (np.cos(u)[:, None] * p_axis + np.sin(u)[:, None] * q_axis)
    v_inertial = radius * n * (-np.sin(u)[:, None] * p_axis + np.cos(u)[:, None] * q_axis)
    # The inertial frame coincides with ECEF at t = 0 and the Earth turns under it.
    a = OMEGA_EARTH * t
    c, s = np.cos(a), np.sin(a)
    rot = np.zeros((t.size, 3, 3))
    rot[:, 0, 0], rot[:, 0, 1], rot[:, 1, 0], rot[:, 1, 1], rot[:, 2, 2] = c, s, -s, c, 1.0
    pos = np.einsum("nij,nj->ni", rot, r_inertial)
    vel = np.einsum("nij,nj->ni", rot, v_inertial) - np.cross([0.0, 0.0, OMEGA_EARTH], pos)
    return pos, vel


def nadir_attitude(pos: np.ndarray, vel: np.ndarray) -> np.ndarray:
    """Body -> ECEF rotations (n, 3, 3) of a yaw-steered nadir-pointing platform: z toward the
    Earth's centre, x along the ground track (ECEF velocity), y = z x x (right of track)."""
    z = -pos / np.linalg.norm(pos, axis=1, keepdims=True)
    x = vel - np.einsum("ni,ni->n", vel, z)[:, None] * z
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=2)


def _platform_wobble(t: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Smooth true attitude motion (n, 3) rad: a few slow oscillations of ~10 microradians,
    measured by the star trackers (so present in both true and onboard models)."""
    periods = rng.uniform(40.0, 200.0, (3, 2))
    phases = rng.uniform(0.0, 2 * math.pi, (3, 2))
    amp = rng.uniform(3e-6, 1e-5, (3, 2))
    return np.sum(amp * np.sin(2 * math.pi * t[:, None, None] / periods + phases), axis=2)


# --- cameras ---------------------------------------------------------------------------------
def nominal_camera(spec: CameraSpec, rows: int, t0: float, period: float) -> Camera:
    """The laboratory design of a camera: chips on one focal plane centred on the optical
    axis, running right to left (theta = pi), odd chips staggered along track with their
    rows delayed by whole lines so the delivered image is aligned to about a line."""
    cols = spec.cols
    chips = []
    for k in range(spec.n_chips):
        offset = k * (spec.chip_pixels - spec.overlap)
        staggered = spec.stagger if k % 2 == 1 else 0.0
        lines = round(staggered / spec.pitch)
        chips.append(Chip(col_offset=float(offset), n_pixels=spec.chip_pixels, kind="focal_plane",
                          time_offset=-lines * period, x0=staggered,
                          y0=-(offset + 0.5 - cols / 2.0) * spec.pitch, pitch=spec.pitch, theta=math.pi,
                          name=f"{spec.name}-{k + 1}"))
    return Camera(name=spec.name, cols=cols, rows=rows, timing=LineTiming(t0=t0, period=period), chips=chips,
                  focal_length=spec.focal_length, installation=rot_y(spec.tilt))


def _draw(rng: np.random.Generator, magnitude: float, shape=()) -> np.ndarray:
    """Values of size magnitude * U(1/3, 1) with random signs."""
    return magnitude * rng.uniform(1.0 / 3.0, 1.0, shape) * rng.choice([-1.0, 1.0], shape)


def perturbed_camera(nominal: Camera, errors: ErrorSettings, reference: bool,
                     rng: np.random.Generator) -> tuple[Camera, dict]:
    """The true camera: the nominal one with drawn interior errors, and a dict of them.

    The middle chip is the reference of a multi-chip array (no shift or rotation); the
    reference camera of a camera set has no installation error. The camera terms are drawn
    in px at the array end (:class:`ErrorSettings`) and converted with :func:`camera_term`;
    the truth holds both: camera_terms (SI, units in camera_terms_units; 'f' is the focal
    length's error, the adjustment's name) and camera_terms_px.
    """
    ref_chip = len(nominal.chips) // 2
    chips, chip_truth = [], []
    for k, chip in enumerate(nominal.chips):
        free = k != ref_chip and len(nominal.chips) > 1
        dx, dy = _draw(rng, errors.ccd_shift, 2) if free else (0.0, 0.0)
        dtheta = float(_draw(rng, errors.ccd_rotation)) if free else 0.0
        chips.append(replace(chip, x0=chip.x0 + dx * chip.pitch, y0=chip.y0 + dy * chip.pitch,
                             theta=chip.theta + dtheta))
        chip_truth.append({"chip": chip.name, "dx_px": float(dx), "dy_px": float(dy), "dx_m": float(dx * chip.pitch),
                           "dy_m": float(dy * chip.pitch), "dtheta_rad": dtheta})
    pitch = nominal.chips[0].pitch
    half_length = 0.5 * nominal.cols * pitch
    # focal and k1 are drawn first and always, the other terms only when asked for, so that
    # simulations without them draw the random numbers they drew before those terms existed.
    px = {"focal": float(_draw(rng, errors.focal)), "radial_k1": float(_draw(rng, errors.radial_k1))}
    angles = _draw(rng, errors.installation, 3) if not reference else np.zeros(3)
    px.update({name: float(_draw(rng, getattr(errors, name))) if getattr(errors, name) else 0.0
               for name in CAMERA_ERRORS if name not in px})
    terms = {CAMERA_ERRORS[name]: float(camera_term(CAMERA_ERRORS[name], v, pitch, half_length, nominal.focal_length))
             for name, v in px.items()}
    distortion = {t: v for t, v in terms.items() if t != "f" and v}
    true = replace(nominal, chips=chips, focal_length=nominal.focal_length + terms["f"], distortion=distortion,
                   installation=nominal.installation @ rotation_from_angles(*angles))
    truth = {"camera": nominal.name, "chips": chip_truth,
             "camera_terms": {t: terms[t] for t in CAMERA_TERMS},
             "camera_terms_px": {CAMERA_ERRORS[name]: px[name] for name in CAMERA_ERRORS},
             "camera_terms_units": {t: UNITS[t] for t in CAMERA_TERMS},
             "installation_error_rad": [float(a) for a in angles]}
    return true, truth


# --- the scene ---------------------------------------------------------------------------------
@dataclass
class SimulatedScenes:
    """The scene models of a simulated strip: the true one, the onboard one (the truth with the
    drawn errors) and the drawn values (trajectory errors, each camera's interior errors)."""
    true: SceneModel
    onboard: SceneModel
    truth: dict


@dataclass(frozen=True)
class Pointing:
    """How the whole platform points and where its orbit passes.

    pitch, roll (rad): the platform turned from yaw-steered nadir pointing by
    ``rotation_from_angles(roll, pitch, 0)`` in the body frame (x along track, y right of it, z
    down): pitch > 0 looks forward (as a camera's tilt), roll > 0 turns the line of sight to the
    left of the track (a right-hand turn about x). pass_point: (lon, lat) degrees the orbit passes
    over (descending) at t = 0, the middle of the imaging span; None: the preset's centre. The
    default is the nadir strip :func:`simulation.simulator.simulate` builds."""
    pitch: float = 0.0
    roll: float = 0.0
    pass_point: tuple[float, float] | None = None


def _line_period(spec: CameraSpec, altitude: float, ground_speed: float, pitch: float = 0.0,
                 roll: float = 0.0) -> float:
    """Line period (s) giving square pixels on the ground for a camera's view angle (its tilt
    plus the platform's pitch; the roll lengthens the slant range)."""
    tilt = spec.tilt + pitch
    slant = altitude / (math.cos(tilt) * math.cos(roll))
    return slant * spec.pitch / spec.focal_length / math.cos(tilt) / ground_speed


@dataclass
class _Design:
    """The nominal acquisition, before anything is drawn: cameras, ephemeris samples (t_eph,
    pos, vel; s and ECEF m, m/s) and attitude samples (t_att, rot: body -> ECEF (n, 3, 3),
    without the platform's wobble)."""
    cams: list
    t_eph: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    t_att: np.ndarray
    rot: np.ndarray


def _design(preset: Preset, n_scenes: int, pointing: Pointing) -> _Design:
    """The nominal cameras and trajectory of a strip of ``n_scenes`` scenes of ``preset``."""
    lon0, lat0 = pointing.pass_point or preset.centre
    # Ground speed at the centre: the sub-satellite point's speed scaled from orbit to ground.
    p, v = circular_orbit(preset.altitude, preset.inclination, lon0, lat0, np.array([0.0]))
    ground_speed = float(np.linalg.norm(v[0]) * (np.linalg.norm(p[0]) - preset.altitude) / np.linalg.norm(p[0]))
    ref = preset.cameras[0]
    ref_period = _line_period(ref, preset.altitude, ground_speed, pointing.pitch, pointing.roll)
    rows = preset.scene_rows * n_scenes
    duration = rows * ref_period
    cams = []
    for spec in preset.cameras:
        period = _line_period(spec, preset.altitude, ground_speed, pointing.pitch, pointing.roll)
        # A forward camera sees a ground line before the reference one: by the time the platform
        # takes to fly the along-track distance between their views.
        lead = preset.altitude * (math.tan(spec.tilt + pointing.pitch) - math.tan(pointing.pitch)) / ground_speed
        cam_rows = int(round(duration / period))
        cams.append(nominal_camera(spec, cam_rows, -0.5 * duration - lead, period))
    t_first = min(c.timing.t0 + min(ch.time_offset for ch in c.chips) for c in cams) - TRAJECTORY_MARGIN
    t_last = max(c.timing.time(np.array([c.rows]))[0] for c in cams) + TRAJECTORY_MARGIN
    t_eph = np.arange(t_first, t_last + EPHEMERIS_STEP, EPHEMERIS_STEP)
    pos, vel = circular_orbit(preset.altitude, preset.inclination, lon0, lat0, t_eph)
    t_att = np.arange(t_first, t_last + ATTITUDE_STEP, ATTITUDE_STEP)
    pa, va = circular_orbit(preset.altitude, preset.inclination, lon0, lat0, t_att)
    rot = nadir_attitude(pa, va)
    if pointing.pitch or pointing.roll:  # the nadir strip keeps its exact numbers
        rot = rot @ rotation_from_angles(pointing.roll, pointing.pitch, 0.0)
    return _Design(cams, t_eph, pos, vel, t_att, rot)


def _scene_info(preset: Preset, n_scenes: int) -> dict:
    ref = preset.cameras[0]
    return {"sensor": preset.name, "description": preset.description, "simulated": True,
            "n_scenes": n_scenes, "scene_rows": preset.scene_rows,
            "gsd_m": ref.pitch / ref.focal_length * preset.altitude,
            "height_range": [-100.0, preset.relief + 1000.0]}


def nominal_scene(preset: Preset, n_scenes: int = 1, pointing: Pointing | None = None,
                  epoch: str = EPOCH) -> SceneModel:
    """The nominal scene model of a strip (nothing drawn: no wobble, no errors): where the
    platform looks, e.g. to aim it (:func:`aim_pass_point`)."""
    d = _design(preset, n_scenes, pointing or Pointing())
    platform = Platform(Ephemeris(d.t_eph, d.pos, d.vel), QuaternionSamples(d.t_att, matrix_to_quat(d.rot)))
    return SceneModel(epoch, platform, d.cams, aberration=True, refraction=True,
                      info={**_scene_info(preset, n_scenes), "model": "nominal"})


def aim_pass_point(preset: Preset, pitch: float, roll: float, target: tuple[float, float, float],
                   tol_deg: float = 1e-8, max_iter: int = 12) -> tuple[float, float]:
    """(lon, lat) degrees the orbit must pass over at t = 0 so that the reference camera's image
    centre, with the platform pitched and rolled (rad, :class:`Pointing`), sees ``target`` (lon,
    lat degrees, ellipsoidal height m) at t = 0. Fixed-point iteration: the view moves with the
    pass point almost rigidly, so each step shifts the pass point by the last miss (degrees);
    converges to ~1e-9 deg in a few steps. InputError when it does not (a view beyond the Earth's
    limb)."""
    lon_t, lat_t, h_t = target
    point = np.array([lon_t, lat_t], dtype=float)
    miss = np.array([np.inf, np.inf])
    for _ in range(max_iter):
        scene = nominal_scene(preset, 1, Pointing(pitch, roll, (float(point[0]), float(point[1]))))
        cam = scene.cameras[0]
        hit = scene.image_to_ground(np.array([cam.cols / 2.0]), np.array([cam.rows / 2.0]), h_t, 0)
        lon, lat, _ = ecef_to_geodetic(hit)
        miss = np.array([lon_t - lon[0], lat_t - lat[0]])
        if not np.all(np.isfinite(miss)):
            break
        point = point + miss
        if np.max(np.abs(miss)) < tol_deg:
            return float(point[0]), float(point[1])
    raise InputError(f"the view (pitch {math.degrees(pitch):.1f} deg, roll {math.degrees(roll):.1f} deg) of "
                     f"{preset.name} cannot be aimed at ({lon_t:.4f}, {lat_t:.4f}): last miss {miss} deg")


def build_scenes(preset: Preset, n_scenes: int, errors: ErrorSettings, rng: np.random.Generator,
                 pointing: Pointing | None = None, epoch: str = EPOCH) -> SimulatedScenes:
    """True and onboard scene models of a strip of ``n_scenes`` scenes of ``preset``, the platform
    pointed by ``pointing`` (default: nadir over the preset's centre); times in seconds from
    ``epoch`` (UTC), t = 0 the middle of the imaging span."""
    d = _design(preset, n_scenes, pointing or Pointing())
    t_eph, pos, vel, t_att, cams = d.t_eph, d.pos, d.vel, d.t_att, d.cams
    rot_true = d.rot @ rotation_from_angles(*_platform_wobble(t_att, rng).T)

    traj = {name: _draw(rng, getattr(errors, name), 3) for name in
            ("position_bias", "position_drift", "position_quadratic", "attitude_bias", "attitude_drift",
             "attitude_quadratic")}
    dt_e, dt_a = t_eph[:, None], t_att[:, None]
    pos_on = pos + traj["position_bias"] + traj["position_drift"] * dt_e + traj["position_quadratic"] * dt_e ** 2
    vel_on = vel + traj["position_drift"] + 2 * traj["position_quadratic"] * dt_e
    att_err = traj["attitude_bias"] + traj["attitude_drift"] * dt_a + traj["attitude_quadratic"] * dt_a ** 2
    rot_on = rot_true @ rotation_from_angles(*att_err.T)

    true_cams, interior = [], []
    for i, cam in enumerate(cams):
        true_cam, truth = perturbed_camera(cam, errors, reference=(i == 0), rng=rng)
        true_cams.append(true_cam)
        interior.append(truth)

    info = _scene_info(preset, n_scenes)
    true = SceneModel(epoch, Platform(Ephemeris(t_eph, pos, vel), QuaternionSamples(t_att, matrix_to_quat(rot_true))),
                      true_cams, aberration=True, refraction=True, info={**info, "model": "true"})
    onboard = SceneModel(epoch, Platform(Ephemeris(t_eph, pos_on, vel_on),
                                         QuaternionSamples(t_att, matrix_to_quat(rot_on))),
                         cams, aberration=True, refraction=True, info={**info, "model": "onboard"})
    truth = {"trajectory": {k: v.tolist() for k, v in traj.items()}, "reference_time_s": 0.0,
             "interior": interior}
    return SimulatedScenes(true, onboard, truth)


def scene_bounds(scene: SceneModel, heights: tuple[float, float],
                 margin_deg: float = 0.02) -> tuple[float, float, float, float]:
    """(lon_min, lat_min, lon_max, lat_max) of every camera's image border seen at the given
    ellipsoidal heights, widened by margin_deg."""
    lons, lats = [], []
    for k, cam in enumerate(scene.cameras):
        s = np.linspace(0.0, 1.0, 65)
        col = np.concatenate([s * cam.cols, np.full_like(s, cam.cols), s * cam.cols, np.zeros_like(s)])
        row = np.concatenate([np.zeros_like(s), s * cam.rows, np.full_like(s, cam.rows), s * cam.rows])
        for h in heights:
            lon, lat, _ = ecef_to_geodetic(scene.image_to_ground(col, row, h, k))
            lons.append(lon)
            lats.append(lat)
    lon, lat = np.concatenate(lons), np.concatenate(lats)
    return (float(lon.min()) - margin_deg, float(lat.min()) - margin_deg, float(lon.max()) + margin_deg,
            float(lat.max()) + margin_deg)
