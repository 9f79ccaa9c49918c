"""Scene simulator: a pushbroom acquisition with known truth, deterministic by seed.

A circular sun-synchronous orbit passes (descending) over a synthetic terrain; a preset
camera set images it. Two scene models are written:

- the **true** scene: the geometry that made the measurements;
- the **onboard** scene: what the satellite's own ephemeris, attitude and laboratory
  calibration deliver, i.e. the truth with the simulated errors. Error conventions (the
  adjustment estimates their negatives):
    onboard position(t) = true position(t) + b + d (t - t_c) + q (t - t_c)^2   (ECEF axes, m)
    onboard attitude(t) = true attitude(t) @ R(a(t)),  a(t) = a0 + a1 (t - t_c) + a2 (t - t_c)^2,
                          R = rotation_from_angles(roll, pitch, yaw) in the body frame (rad)
    onboard camera      = the nominal (laboratory) design; the true camera has per-chip
                          shifts (dx, dy), rotations dtheta, the 10 camera terms of Zhang et
                          al. 2015 eq. 7 (principal point, focal length, radial k1 k2,
                          decentring p1 p2, affinity b1 b2 b3) and, for multi-camera sets,
                          installation errors.
  t_c is the strip's mid time. Every drawn value is in ``simulation.json``.

Outputs in the folder: ``onboard_scene.json``, ``true_scene.json``, ``gcps.csv`` (ground
control and check points), ``tie_points.csv`` (multi-camera presets), ``dem.tif`` (EGM96
geoid heights), ``simulation.json`` (settings and truth), and with ``render=True`` one raw
image per camera ``image_<CAMERA>.tif`` (see :mod:`core.render`) and the reference orthoimage
``reference.tif`` of the same ground (see :mod:`core.reference`). With roads (``n_lines``),
``lines.gpkg`` (road map and image lines) and ``line_points.csv`` (see :mod:`core.roads`).

Frames: ECEF metres, times in seconds from the epoch, image coordinates GDAL (col, row).
The focal-plane chips run from right to left across track (nominal theta = pi), so that a
descending pass gives images with north up and east to the right, as delivered products.
"""
from __future__ import annotations

import csv
import json
import logging
import math
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Callable

import numpy as np
from osgeo import gdal, osr

from ..core.adjust.parameters import CAMERA_TERMS, UNITS
from ..core.model.camera import Camera, Chip, LineTiming
from ..core.dem import Dem
from ..core.errors import Cancelled, InputError
from ..core.files import OutputError, atomic_outputs, check_folder_destination, write_text
from ..core.geodesy import A, ecef_to_geodetic, geodetic_to_ecef
from .roads import LINES_FILE, POINTS_FILE, RoadSettings, simulate_roads
from ..core.rotations import matrix_to_quat, rotation_from_angles, rot_y
from ..core.formats.scene_json import save_scene
from ..core.model.sensor import SceneModel
from ..core.model.trajectory import Ephemeris, Platform, QuaternionSamples

gdal.UseExceptions()
log = logging.getLogger(__name__)

GM_EARTH = 3.986004418e14          # m^3/s^2
OMEGA_EARTH = 7.2921151467e-5      # rad/s
EPOCH = "2010-12-15T03:00:00.000000Z"
EPHEMERIS_STEP = 1.0               # s
ATTITUDE_STEP = 0.25               # s
TRAJECTORY_MARGIN = 30.0           # s of ephemeris/attitude beyond the imaging span
ARCSEC = math.pi / 648000.0
MANIFEST = "simulation.json"       # the settings and truth of a simulation, in its folder


# --- presets ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class CameraSpec:
    """One camera of a preset. tilt: along-track view angle (rad, + forward); chips of
    ``chip_pixels`` detectors overlapping by ``overlap`` px; odd chips are displaced along
    track by ``stagger`` metres (a staggered TDI array), their rows delayed to match."""
    name: str
    focal_length: float
    pitch: float
    n_chips: int
    chip_pixels: int
    overlap: int = 0
    stagger: float = 0.0
    tilt: float = 0.0

    @property
    def cols(self) -> int:
        return self.n_chips * self.chip_pixels - (self.n_chips - 1) * self.overlap


@dataclass(frozen=True)
class ErrorSettings:
    """Magnitudes of the simulated errors. Each drawn value is magnitude * U(1/3, 1) with a
    random sign (so 3 px gives 1-3 px), per component; 0 switches an error off.

    position_bias (m), position_drift (m/s), position_quadratic (m/s^2): per ECEF axis.
    attitude_bias (rad), attitude_drift (rad/s), attitude_quadratic (rad/s^2): per body axis.
    ccd_shift (px, x and y) and ccd_rotation (rad, about the chip's first detector): every
    chip but the middle (reference) one. installation (rad): per axis, every camera but the
    reference (nadir) one.

    The 10 camera terms of seed 001 eq. 7, per camera, in px: the image displacement each
    causes at the end of the detector array (half the array length r from the principal point,
    on the line x = 0; :func:`camera_term`): principal_point_x / _y (dxp, dyp), focal (the
    focal-length error), radial_k1 / radial_k2, decentring_p1 (along track, p1 r^2) /
    decentring_p2 (across, 3 p2 r^2), affinity_b1 (b1 x, quoted at x = r: a detector line
    through the principal point does not see it), affinity_b2 (along track, b2 y), affinity_b3
    (across, b3 y). Seed 001's CCD bending (dx = b y r^2, cubic along track) is not a term of
    :class:`core.camera.Camera` and is not simulated; its low-order part is what p1 and b2 model.
    """
    position_bias: float = 0.0
    position_drift: float = 0.0
    position_quadratic: float = 0.0
    attitude_bias: float = 0.0
    attitude_drift: float = 0.0
    attitude_quadratic: float = 0.0
    ccd_shift: float = 0.0
    ccd_rotation: float = 0.0
    installation: float = 0.0
    principal_point_x: float = 0.0
    principal_point_y: float = 0.0
    focal: float = 0.0
    radial_k1: float = 0.0
    radial_k2: float = 0.0
    decentring_p1: float = 0.0
    decentring_p2: float = 0.0
    affinity_b1: float = 0.0
    affinity_b2: float = 0.0
    affinity_b3: float = 0.0


# ErrorSettings fields of the camera terms -> the terms' names in the adjustment
# (core.adjust.parameters.CAMERA_TERMS: 'f' is the focal length, the others Camera.distortion).
CAMERA_ERRORS = {"principal_point_x": "dxp", "principal_point_y": "dyp", "focal": "f", "radial_k1": "k1",
                 "radial_k2": "k2", "decentring_p1": "p1", "decentring_p2": "p2", "affinity_b1": "b1",
                 "affinity_b2": "b2", "affinity_b3": "b3"}
# Error settings of earlier versions: 'distortion' was radial_k1 (px at the array end);
# 'focal_error' was in metres, which no longer says how far a camera's image moves.
RENAMED_ERRORS = {"distortion": "radial_k1"}
REPLACED_ERRORS = {"focal_error": "focal (px at the array end)"}


def camera_term(term: str, px, pitch: float, half_length: float, focal_length: float):
    """The SI value of camera term ``term`` (a :data:`CAMERA_ERRORS` value) that displaces the
    image point at the array end by ``px`` pixels of size ``pitch`` (m): half_length (m) is r,
    the array end's distance from the principal point (seed 001 eq. 7 with x = 0, y = r)."""
    r, d = half_length, px * pitch
    scale = {"dxp": 1.0, "dyp": 1.0, "f": r / focal_length, "k1": r ** 3, "k2": r ** 5, "p1": r ** 2,
             "p2": 3.0 * r ** 2, "b1": r, "b2": r, "b3": r}[term]
    return d / scale


@dataclass(frozen=True)
class Preset:
    """A sensor and orbit: altitude (m), inclination (rad), cameras (the reference camera,
    where GCPs are placed, first), rows per scene, the scene centre and the terrain relief (m)."""
    name: str
    description: str
    altitude: float
    cameras: tuple[CameraSpec, ...]
    scene_rows: int
    errors: ErrorSettings
    inclination: float = math.radians(98.5)
    centre: tuple[float, float] = (114.0, 34.5)
    relief: float = 1200.0


# Three-line cameras: GPS-grade orbits, star-tracker attitude with bias, drift and a quadratic
# term, installation errors of the forward and backward cameras.
_TLC_TRAJECTORY = ErrorSettings(position_bias=10.0, position_drift=0.02, attitude_bias=1e-4, attitude_drift=5e-7,
                                attitude_quadratic=1e-9, installation=20 * ARCSEC)
# TH-1 (seed 001): lens and CCD errors that a conventional adjustment (attitude only) leaves
# as systematic check errors of about 4 px (20 m at 5 m GSD) and self-calibration removes.
# Seed 001 names the principal point and decentring distortion the dominant terms, the focal
# length not negligible (1-2 um), b1 and b2 negligible (~1e-14); see the magnitudes' notes in
# README (Simulate a scene).
TH1_ERRORS = replace(_TLC_TRAJECTORY, principal_point_x=10.0, principal_point_y=10.0, focal=4.0, radial_k1=5.0,
                     radial_k2=1.5, decentring_p1=8.0, decentring_p2=7.0, affinity_b3=3.0)
# ZY-3 (seed 003): the cameras are calibrated in orbit (their lines of sight are given as
# look-angle tables); what remains of the interior is sub-pixel (tie-point residuals of 0.25
# px after adjustment) beside the CCD alignment.
ZY3_ERRORS = replace(_TLC_TRAJECTORY, ccd_shift=1.0, ccd_rotation=2e-4, principal_point_x=0.3, principal_point_y=0.3,
                     focal=0.3, radial_k1=0.3, decentring_p1=0.2, decentring_p2=0.2)

PRESETS: dict[str, Preset] = {
    "cbers02b_hrc": Preset(
        "cbers02b_hrc", "CBERS-02B HRC, 778 km, 3 staggered TDI-CCDs of 4096 px, 2.36 m GSD", 778e3,
        (CameraSpec("HRC", 3.3, 10e-6, 3, 4096, overlap=21, stagger=0.8e-3),), 12246,
        ErrorSettings(position_bias=40.0, position_drift=0.05, attitude_bias=5e-4, attitude_drift=2e-6,
                      attitude_quadratic=5e-9, ccd_shift=3.0, ccd_rotation=1e-3)),
    "th1_tlc": Preset(
        "th1_tlc", "TH-1 three-line camera, 500 km, 5 m GSD, forward/nadir/backward at +-25 deg", 500e3,
        (CameraSpec("NAD", 1.0, 10e-6, 1, 12000),
         CameraSpec("FWD", 1.0, 10e-6, 1, 12000, tilt=math.radians(25.0)),
         CameraSpec("BWD", 1.0, 10e-6, 1, 12000, tilt=math.radians(-25.0))), 12000,
        TH1_ERRORS, inclination=math.radians(97.3), centre=(113.5, 35.0)),
    "zy3_tlc": Preset(
        "zy3_tlc", "ZY-3 three-line camera, 505 km, nadir 2.1 m, forward/backward 3.5 m at +-22 deg", 505e3,
        (CameraSpec("NAD", 1.7, 7e-6, 3, 8192),
         CameraSpec("FWD", 1.7, 10e-6, 4, 4096, tilt=math.radians(22.0)),
         CameraSpec("BWD", 1.7, 10e-6, 4, 4096, tilt=math.radians(-22.0))), 24576,
        ZY3_ERRORS, inclination=math.radians(97.4), centre=(115.0, 40.0)),
}


@dataclass
class SimulationResult:
    """Paths of the files written by :func:`simulate`."""
    folder: Path
    onboard_scene: Path
    true_scene: Path
    gcps: Path
    dem: Path
    manifest: Path
    tie_points: Path | None = None
    images: dict = field(default_factory=dict)
    lines: Path | None = None
    reference: Path | None = None


MIN_CUT = 500  # px: the smallest cut of a preset's cameras (matching windows and GCPs need room)


def cut_preset(preset: Preset, cols: int, rows: int) -> Preset:
    """``preset`` with each camera cut down to ``cols`` detectors and its scenes to ``rows``
    lines, so that it renders in seconds (e.g. a three-line block for a test or a model run):
    the same orbit and trajectory errors, its images a centred part of the full cameras'. The
    lens and CCD errors (px at the array end) are scaled by cols / the full array's length, so
    that the distortion bends an image window as much as in the full camera (the same px per
    px); keeping the end displacements would bend it full / cols times more. Cameras of one
    detector line only (a staggered multi-chip array cannot be cut evenly)."""
    chips = [c for c in preset.cameras if c.n_chips != 1]
    if chips:
        raise InputError(f"a cut needs cameras of one detector line; {preset.name} camera {chips[0].name} has "
                         f"{chips[0].n_chips} CCD chips")
    full = preset.cameras[0].chip_pixels
    if not MIN_CUT <= cols <= full or not MIN_CUT <= rows <= preset.scene_rows:
        raise InputError(f"a cut of {preset.name} must be {MIN_CUT} to {full} detectors and {MIN_CUT} to "
                         f"{preset.scene_rows} lines (got {cols} x {rows})")
    scale = cols / full
    errors = replace(preset.errors, **{name: getattr(preset.errors, name) * scale for name in CAMERA_ERRORS})
    return replace(preset, name=f"{preset.name}_{cols}x{rows}",
                   description=f"{preset.description}, cut to {cols} x {rows} px",
                   cameras=tuple(replace(c, chip_pixels=cols) for c in preset.cameras), scene_rows=rows, errors=errors)


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
        raise InputError(f"latitude {lat0} is beyond the reach of an orbit inclined {math.degrees(inclination):.1f} deg")
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


def perturbed_camera(nominal: Camera, errors: ErrorSettings, reference: bool, rng: np.random.Generator) -> tuple[Camera, dict]:
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
class _Geometry:
    true: SceneModel
    onboard: SceneModel
    truth: dict


def _line_period(spec: CameraSpec, altitude: float, ground_speed: float) -> float:
    """Line period (s) giving square pixels on the ground for a camera's view angle."""
    slant = altitude / math.cos(spec.tilt)
    return slant * spec.pitch / spec.focal_length / math.cos(spec.tilt) / ground_speed


def build_scenes(preset: Preset, n_scenes: int, errors: ErrorSettings, rng: np.random.Generator) -> _Geometry:
    """True and onboard scene models of a strip of ``n_scenes`` scenes of ``preset``."""
    lon0, lat0 = preset.centre
    # Ground speed at the centre: the sub-satellite point's speed scaled from orbit to ground.
    p, v = circular_orbit(preset.altitude, preset.inclination, lon0, lat0, np.array([0.0]))
    ground_speed = float(np.linalg.norm(v[0]) * (np.linalg.norm(p[0]) - preset.altitude) / np.linalg.norm(p[0]))
    ref = preset.cameras[0]
    ref_period = _line_period(ref, preset.altitude, ground_speed)
    rows = preset.scene_rows * n_scenes
    duration = rows * ref_period
    cams = []
    for spec in preset.cameras:
        period = _line_period(spec, preset.altitude, ground_speed)
        # A forward camera sees a ground line before the nadir one: by the time the platform
        # takes to fly the along-track distance of its view.
        lead = preset.altitude * math.tan(spec.tilt) / ground_speed
        cam_rows = int(round(duration / period))
        cams.append(nominal_camera(spec, cam_rows, -0.5 * duration - lead, period))
    t_first = min(c.timing.t0 + min(ch.time_offset for ch in c.chips) for c in cams) - TRAJECTORY_MARGIN
    t_last = max(c.timing.time(np.array([c.rows]))[0] for c in cams) + TRAJECTORY_MARGIN
    t_eph = np.arange(t_first, t_last + EPHEMERIS_STEP, EPHEMERIS_STEP)
    pos, vel = circular_orbit(preset.altitude, preset.inclination, lon0, lat0, t_eph)
    t_att = np.arange(t_first, t_last + ATTITUDE_STEP, ATTITUDE_STEP)
    pa, va = circular_orbit(preset.altitude, preset.inclination, lon0, lat0, t_att)
    rot_true = nadir_attitude(pa, va) @ rotation_from_angles(*_platform_wobble(t_att, rng).T)

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

    info = {"sensor": preset.name, "description": preset.description, "simulated": True,
            "n_scenes": n_scenes, "scene_rows": preset.scene_rows,
            "gsd_m": ref.pitch / ref.focal_length * preset.altitude,
            "height_range": [-100.0, preset.relief + 1000.0]}
    true = SceneModel(EPOCH, Platform(Ephemeris(t_eph, pos, vel), QuaternionSamples(t_att, matrix_to_quat(rot_true))),
                      true_cams, aberration=True, refraction=True, info={**info, "model": "true"})
    onboard = SceneModel(EPOCH, Platform(Ephemeris(t_eph, pos_on, vel_on),
                                         QuaternionSamples(t_att, matrix_to_quat(rot_on))),
                         cams, aberration=True, refraction=True, info={**info, "model": "onboard"})
    truth = {"trajectory": {k: v.tolist() for k, v in traj.items()}, "reference_time_s": 0.0,
             "interior": interior}
    return _Geometry(true, onboard, truth)


# --- terrain -----------------------------------------------------------------------------------
def terrain_heights(lon, lat, centre: tuple[float, float], relief: float, seed: int) -> np.ndarray:
    """Synthetic terrain (m above the geoid) at (lon, lat) degrees: a sum of random plane
    waves with wavelengths 1.5-40 km and amplitudes growing with wavelength, spanning about
    ``relief`` metres above a 200 m plain. Smooth at the DEM spacing, deterministic by seed."""
    rng = np.random.default_rng([seed, 7])
    n = 24
    wavelength = np.exp(rng.uniform(np.log(1.5e3), np.log(40e3), n))
    direction = rng.uniform(0.0, 2 * math.pi, n)
    phase = rng.uniform(0.0, 2 * math.pi, n)
    amp = wavelength / wavelength.sum()
    x = (np.asarray(lon) - centre[0]) * 111320.0 * math.cos(math.radians(centre[1]))
    y = (np.asarray(lat) - centre[1]) * 110540.0
    k = 2 * math.pi / wavelength
    h = np.zeros(np.broadcast(x, y).shape)
    for i in range(n):  # a few waves over the whole grid: numpy does the work per wave
        h += amp[i] * np.cos(k[i] * (x * np.cos(direction[i]) + y * np.sin(direction[i])) + phase[i])
    # The sum is near-Gaussian with this standard deviation: +-3 sigma spans the relief.
    sigma = math.sqrt(float(np.sum(amp ** 2)) / 2.0)
    return 200.0 + relief * (0.5 + h / (6.0 * sigma)).clip(0.0, 1.0)


def write_dem(path: Path, bounds: tuple[float, float, float, float], centre, relief: float, seed: int,
              max_cells: int = 4_000_000) -> None:
    """A GeoTIFF DEM in EPSG:4326 (EGM96 geoid heights, Float32) covering ``bounds``
    (lon_min, lat_min, lon_max, lat_max) at 1 arc-second, coarser if it would exceed max_cells."""
    lon_min, lat_min, lon_max, lat_max = bounds
    step = max(1.0 / 3600.0, math.sqrt((lon_max - lon_min) * (lat_max - lat_min) / max_cells))
    nx = int(math.ceil((lon_max - lon_min) / step)) + 1
    ny = int(math.ceil((lat_max - lat_min) / step)) + 1
    lon = lon_min + (np.arange(nx) + 0.5) * step
    lat = lat_max - (np.arange(ny) + 0.5) * step
    z = terrain_heights(lon[None, :], lat[:, None], centre, relief, seed).astype(np.float32)
    ds = gdal.GetDriverByName("GTiff").Create(str(path), nx, ny, 1, gdal.GDT_Float32,
                                              ["COMPRESS=DEFLATE", "PREDICTOR=3", "TILED=YES"])
    ds.SetGeoTransform((lon_min, step, 0.0, lat_max, 0.0, -step))
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(4326)
    ds.SetProjection(srs.ExportToWkt())
    band = ds.GetRasterBand(1)
    band.WriteArray(z)
    band.SetNoDataValue(-32768.0)
    band.SetDescription("height above the EGM96 geoid (m)")
    ds = None


def scene_bounds(scene: SceneModel, heights: tuple[float, float], margin_deg: float = 0.02) -> tuple[float, float, float, float]:
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


# --- measurements ------------------------------------------------------------------------------
@dataclass
class GcpSettings:
    """How points are measured. n_gcps: ground points placed uniformly over the reference
    camera's image; check_fraction: share made check points; image_noise (px), ground_noise_xy
    / ground_noise_z (m): standard deviations; gross_fraction: share of image measurements
    displaced by gross_min..gross_max px in a random direction; n_tie_points: ground points
    measured (without ground coordinates) in every camera that sees them."""
    n_gcps: int = 200
    check_fraction: float = 0.0
    image_noise: float = 0.3
    ground_noise_xy: float = 0.0
    ground_noise_z: float = 0.0
    gross_fraction: float = 0.0
    gross_min: float = 5.0
    gross_max: float = 100.0
    n_tie_points: int = 0

    def validate(self) -> None:
        for name in ("n_gcps", "n_tie_points", "image_noise", "ground_noise_xy", "ground_noise_z", "gross_min"):
            if not getattr(self, name) >= 0:
                raise InputError(f"{name} must be >= 0 (got {getattr(self, name)})")
        for name in ("check_fraction", "gross_fraction"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise InputError(f"{name} must be between 0 and 1 (got {getattr(self, name)})")
        if self.gross_max < self.gross_min:
            raise InputError(f"gross_max ({self.gross_max}) must not be below gross_min ({self.gross_min})")


def place_ground_points(scene: SceneModel, dem: Dem, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(ECEF points (n, 3) on the DEM, their rows (n,)) seen at uniformly random positions
    of camera 0."""
    cam = scene.cameras[0]
    col = rng.uniform(0.0, cam.cols, n)
    row = rng.uniform(0.0, cam.rows, n)
    ground = scene.image_to_ground_dem(col, row, dem, 0)
    if not np.all(np.isfinite(ground)):
        raise InputError(f"{int((~np.isfinite(ground[:, 0])).sum())} simulated points miss the DEM")
    return ground, row


def observe(scene: SceneModel, ground: np.ndarray) -> list[tuple[int, np.ndarray, np.ndarray, np.ndarray]]:
    """Noise-free image positions of ECEF points in every camera: a list of (camera index,
    point indices, col, row) for the points that fall inside each camera's image."""
    out = []
    for k, cam in enumerate(scene.cameras):
        col, row = scene.ground_to_image(ground, k)
        inside = np.isfinite(col) & (col >= 0) & (col <= cam.cols) & (row >= 0) & (row <= cam.rows)
        idx = np.nonzero(inside)[0]
        out.append((k, idx, col[idx], row[idx]))
    return out


def _gross_offsets(n: int, settings: GcpSettings, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(offsets (n, 2) px, flags (n,)) for gross errors in exactly round(share * n) measurements."""
    flags = _exact_share(n, settings.gross_fraction, rng)
    size = rng.uniform(settings.gross_min, settings.gross_max, n)
    angle = rng.uniform(0.0, 2 * math.pi, n)
    off = np.where(flags[:, None], np.stack([np.cos(angle), np.sin(angle)], axis=1) * size[:, None], 0.0)
    return off, flags


def _exact_share(n: int, share: float, rng: np.random.Generator) -> np.ndarray:
    """Boolean mask (n,) with exactly round(share * n) randomly placed True values."""
    mask = np.zeros(n, bool)
    mask[rng.choice(n, int(round(share * n)), replace=False)] = True
    return mask


def _ground_noise(ground: np.ndarray, settings: GcpSettings, rng: np.random.Generator):
    """(lon, lat, h) of the ground points with planimetric and height noise added."""
    lon, lat, h = ecef_to_geodetic(ground)
    east = rng.normal(0.0, settings.ground_noise_xy, lon.size)
    north = rng.normal(0.0, settings.ground_noise_xy, lon.size)
    up = rng.normal(0.0, settings.ground_noise_z, lon.size)
    lat_r = np.radians(lat)
    # Metres to degrees on the ellipsoid (meridian and prime-vertical radii).
    e2 = 6.69437999014e-3
    w = np.sqrt(1 - e2 * np.sin(lat_r) ** 2)
    m_rad = A * (1 - e2) / w ** 3
    n_rad = A / w
    return (lon + np.degrees(east / ((n_rad + h) * np.cos(lat_r))), lat + np.degrees(north / (m_rad + h)), h + up)


GCP_COLUMNS = ("id", "role", "camera", "col", "row", "lon", "lat", "h", "sigma_px", "sigma_xy", "sigma_z",
               "col_true", "row_true", "lon_true", "lat_true", "h_true", "gross", "scene")
TIE_COLUMNS = ("id", "camera", "col", "row", "col_true", "row_true", "lon_true", "lat_true", "h_true", "gross",
               "scene")


def measure_points(scene: SceneModel, ground: np.ndarray, ids: np.ndarray, settings: GcpSettings,
                   rng: np.random.Generator) -> dict:
    """Columns (dict of (m,) arrays) of the image measurements of ground points in every
    camera that sees them: noise-free and measured (noise and gross errors) positions."""
    lon_t, lat_t, h_t = ecef_to_geodetic(ground)
    cols: dict[str, list] = {k: [] for k in ("id", "camera", "col_true", "row_true", "index")}
    for k, idx, col, row in observe(scene, ground):
        cols["id"].append(ids[idx])
        cols["camera"].append(np.full(idx.size, scene.cameras[k].name))
        cols["col_true"].append(col)
        cols["row_true"].append(row)
        cols["index"].append(idx)
    out = {k: np.concatenate(v) for k, v in cols.items()}
    m = out["id"].size
    offsets, gross = _gross_offsets(m, settings, rng)
    out["col"] = out["col_true"] + rng.normal(0.0, settings.image_noise, m) + offsets[:, 0]
    out["row"] = out["row_true"] + rng.normal(0.0, settings.image_noise, m) + offsets[:, 1]
    out["gross"] = gross.astype(int)
    idx = out.pop("index")
    out["lon_true"], out["lat_true"], out["h_true"] = lon_t[idx], lat_t[idx], h_t[idx]
    out["_index"] = idx
    return out


def _write_csv(path: Path, columns: tuple[str, ...], data: dict) -> None:
    """Write parallel arrays as CSV with a header; floats to 15 significant digits (1e-12 deg, 1e-10 px)."""
    n = len(data[columns[0]])
    text = [np.asarray(data[c]).astype(str) if np.asarray(data[c]).dtype.kind in "UOi"
            else np.char.mod("%.15g", np.asarray(data[c], dtype=float)) for c in columns]
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(columns)
        w.writerows(zip(*text) if n else [])


# --- the whole simulation ----------------------------------------------------------------------
def simulate(preset: "str | Preset", folder, seed: int = 0, n_scenes: int = 1, n_gcps: int = 200, image_noise: float = 0.3,
             render: bool = False, errors: ErrorSettings | dict | None = None,
             gcp_settings: GcpSettings | None = None, progress: Callable[[float, str | None], None] | None = None,
             is_cancelled: Callable[[], bool] | None = None, n_lines: int = 0,
             road_settings: RoadSettings | None = None) -> SimulationResult:
    """Simulate a strip of ``n_scenes`` scenes of ``preset`` (a name of PRESETS, or a Preset of
    one's own, e.g. a small scene for tests) into ``folder`` (created).

    errors: the preset's :class:`ErrorSettings` (None), or another one, or a dict overriding
    some of its fields. gcp_settings: measurement settings; n_gcps and image_noise set its
    fields when it is None. progress(fraction, message) and is_cancelled() report and stop
    long work; on cancel or error nothing is written (every file is renamed into place at the
    end, :class:`core.files.OutputSet`). Files of the same names already in ``folder`` are
    replaced only when an earlier simulation wrote them (:func:`check_folder`).
    n_lines / road_settings: simulated roads, control lines with their truth (:mod:`core.roads`);
    n_lines sets the number of roads when road_settings is None.
    """
    if not isinstance(preset, Preset) and preset not in PRESETS:
        raise InputError(f"unknown preset {preset!r} (choose one of {', '.join(PRESETS)})")
    if not 1 <= int(n_scenes) <= 200:
        raise InputError(f"n_scenes must be between 1 and 200 (got {n_scenes})")
    spec = preset if isinstance(preset, Preset) else PRESETS[preset]
    errors = _error_settings(spec, errors)
    settings = gcp_settings or GcpSettings(n_gcps=int(n_gcps), image_noise=float(image_noise))
    settings.validate()
    if settings.n_tie_points and len(spec.cameras) < 2:
        raise InputError(f"tie points need a preset with several cameras ({preset} has one)")
    report = progress or (lambda fraction, message=None: None)
    cancelled = is_cancelled or (lambda: False)
    roads = road_settings or RoadSettings(n_lines=int(n_lines))
    roads.validate()
    folder = Path(folder)
    check_folder(folder, output_names(spec, settings, render) + ([LINES_FILE, POINTS_FILE] if roads.n_lines else []))
    with _new_folder(folder):
        return _simulate(spec, folder, seed, int(n_scenes), render, errors, settings, report, cancelled, roads)


@contextmanager
def _new_folder(folder: Path):
    """Create ``folder`` (and missing parents) for the block; remove the ones it created, if still
    empty, when the block raises."""
    created = [p for p in (folder, *folder.parents) if not p.exists()]
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"cannot create the folder {folder}: {exc.strerror or exc}") from None
    try:
        yield
    except BaseException:
        for p in created:  # deepest first
            try:
                p.rmdir()
            except OSError:
                break
        raise


def _simulate(spec: Preset, folder: Path, seed: int, n_scenes: int, render: bool, errors: ErrorSettings,
              settings: GcpSettings, report, cancelled, roads: RoadSettings) -> SimulationResult:
    """:func:`simulate` once its arguments are checked and ``folder`` exists."""
    preset = spec.name
    rng = np.random.default_rng(seed)

    def step(fraction: float, message: str) -> None:
        if cancelled():
            raise Cancelled("simulation cancelled by the user")
        report(fraction, message)
        log.info(message)

    with atomic_outputs() as files:
        step(0.0, f"building the {preset} strip of {n_scenes} scene(s)")
        geo = build_scenes(spec, int(n_scenes), errors, rng)
        step(0.1, "writing the terrain")
        dem_tmp = files.path(folder / "dem.tif")
        bounds = scene_bounds(geo.true, tuple(geo.true.height_range))
        write_dem(dem_tmp, bounds, spec.centre, spec.relief, seed)
        dem = Dem(dem_tmp, datum="geoid")
        lo, hi = dem.height_range
        for scene in (geo.true, geo.onboard):
            scene.info["height_range"] = [math.floor(lo - 50.0), math.ceil(hi + 50.0)]
        step(0.3, f"measuring {settings.n_gcps} ground control points")
        gcp_data = _gcp_columns(geo.true, dem, settings, int(n_scenes), rng)
        gcp_tmp = files.path(folder / "gcps.csv")
        _write_csv(gcp_tmp, GCP_COLUMNS, gcp_data)
        tie_tmp = None
        if settings.n_tie_points:
            step(0.5, f"measuring {settings.n_tie_points} tie points")
            ground, _ = place_ground_points(geo.true, dem, settings.n_tie_points, rng)
            tie = measure_points(geo.true, ground, np.char.add("T", np.arange(1, ground.shape[0] + 1).astype(str)),
                                 settings, rng)
            # the scene of each observation: where a tie point's cameras see it in neighbouring
            # scenes, it ties them
            names, camera = np.unique(tie["camera"], return_inverse=True)
            rows = np.array([geo.true.cameras[geo.true.camera_index(n)].rows for n in names])[camera]
            tie["scene"] = scene_of_rows(tie["row_true"], rows, n_scenes)
            tie_tmp = files.path(folder / "tie_points.csv")
            _write_csv(tie_tmp, TIE_COLUMNS, tie)
        road_truth = None
        if roads.n_lines:
            step(0.55, f"drawing {roads.n_lines} roads (control lines)")
            road_truth = simulate_roads(geo.true, dem, roads, seed, folder, files)
        step(0.6, "writing the scene models")
        save_scene(geo.true, folder / "true_scene.json", files)
        save_scene(geo.onboard, folder / "onboard_scene.json", files)
        images, frame = {}, None
        if render:
            from .render import render_image, texture_frame
            frame = texture_frame(geo.true, dem, seed)
            frame["roads"] = road_truth
            for k, cam in enumerate(geo.true.cameras):
                path = files.path(folder / f"image_{cam.name}.tif")
                base = 0.65 + 0.35 * k / len(geo.true.cameras)
                step(base, f"rendering the {cam.name} image ({cam.cols} x {cam.rows})")
                frame.setdefault("interpolation_error_px", {})[cam.name] = render_image(
                    geo.true, k, dem, path, frame,
                    progress=lambda f, b=base: report(b + f * 0.35 / len(geo.true.cameras), None),
                    is_cancelled=cancelled)
                images[cam.name] = folder / f"image_{cam.name}.tif"
            from .reference import REFERENCE_NAME, write_reference
            step(0.99, "writing the reference orthoimage")
            frame["reference"] = write_reference(geo.true, dem, frame, files.path(folder / REFERENCE_NAME), seed,
                                                 is_cancelled=cancelled)
        manifest = {"preset": preset, "seed": seed, "n_scenes": int(n_scenes), "epoch": EPOCH,
                    "errors": asdict(errors), "measurements": asdict(settings), "truth": geo.truth,
                    "texture": frame, "roads": road_truth,
                    "conventions": __doc__.split("\n\n")[1].strip(),
                    "files": {"true_scene": "true_scene.json", "onboard_scene": "onboard_scene.json",
                              "gcps": "gcps.csv", "dem": "dem.tif (EGM96 geoid heights)",
                              "tie_points": "tie_points.csv" if tie_tmp else None,
                              "lines": LINES_FILE if road_truth else None, "line_points": POINTS_FILE if road_truth else None,
                              "images": {k: v.name for k, v in images.items()},
                              "reference": frame["reference"]["file"] if render else None}}
        write_text(folder / MANIFEST, json.dumps(manifest, indent=1), files)
    report(1.0, "simulation written")
    return SimulationResult(folder, folder / "onboard_scene.json", folder / "true_scene.json", folder / "gcps.csv",
                            folder / "dem.tif", folder / MANIFEST,
                            folder / "tie_points.csv" if settings.n_tie_points else None, images,
                            folder / LINES_FILE if road_truth else None,
                            folder / "reference.tif" if render else None)


def output_names(spec: Preset, settings: GcpSettings, render: bool) -> list[str]:
    """Names of the files :func:`simulate` writes into its folder with these settings."""
    names = ["dem.tif", "gcps.csv", "true_scene.json", "onboard_scene.json", MANIFEST]
    if settings.n_tie_points:
        names.append("tie_points.csv")
    return names + ([f"image_{cam.name}.tif" for cam in spec.cameras] + ["reference.tif"] if render else [])


def check_folder(folder, names) -> None:
    """OutputError unless ``folder`` (existing or not) can take the files ``names``: each one it
    already holds must be a file an earlier simulation wrote there (listed in its
    simulation.json) and not modified since; anything else is a user's file, never replaced."""
    folder = Path(folder)
    check_folder_destination(folder)
    present = [n for n in names if (folder / n).exists() or (folder / n).is_symlink()]
    if not present:
        return
    ours = _simulated_files(folder)
    manifest_time = (folder / MANIFEST).stat().st_mtime_ns if ours else 0
    foreign = [n for n in present if n not in ours or not (folder / n).is_file()
               or (folder / n).stat().st_mtime_ns > manifest_time]
    if foreign:
        raise OutputError(f"{folder} holds {', '.join(foreign)}, which no earlier simulation there wrote (or which "
                          "were changed since): they are not replaced; choose an empty folder or move them")


def _simulated_files(folder: Path) -> set[str]:
    """Names of the files an earlier simulation wrote into ``folder`` (its manifest included),
    from its simulation.json; empty when there is none or it is not a simulator's manifest."""
    try:
        manifest = json.loads((folder / MANIFEST).read_text())
        listed = manifest["files"]
        names = [listed[k] for k in ("true_scene", "onboard_scene", "gcps", "dem", "tie_points")]
        names += list(listed["images"].values()) + [listed.get("reference")]
        names += [listed.get("lines"), listed.get("line_points")]
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return set()
    return {MANIFEST, *(n.split(" ")[0] for n in names if isinstance(n, str))}


def _error_settings(spec: Preset, errors) -> ErrorSettings:
    """The error settings of a simulation: the preset's, ``errors`` (ErrorSettings), or the
    preset's with the fields of the dict ``errors`` overridden (the names of earlier
    versions are translated: :data:`RENAMED_ERRORS`; 'focal_error' only as 0, off)."""
    if errors is None:
        return spec.errors
    if isinstance(errors, ErrorSettings):
        return errors
    replaced = {k: v for k, v in errors.items() if k in REPLACED_ERRORS and v != 0}
    if replaced:
        raise InputError("error setting(s) " + ", ".join(f"{k} (now {REPLACED_ERRORS[k]})" for k in replaced)
                         + " replaced: give the new setting instead")
    errors = {RENAMED_ERRORS.get(k, "focal" if k in REPLACED_ERRORS else k): v for k, v in errors.items()}
    unknown = set(errors) - set(ErrorSettings.__dataclass_fields__)
    if unknown:
        raise InputError(f"unknown error setting(s) {sorted(unknown)} (known: {', '.join(ErrorSettings.__dataclass_fields__)})")
    bad = {k: v for k, v in errors.items() if not (np.isfinite(v) and v >= 0)}
    if bad:
        raise InputError(f"error magnitudes must be finite and >= 0 (got {bad})")
    return replace(spec.errors, **{k: float(v) for k, v in errors.items()})


def _gcp_columns(scene: SceneModel, dem: Dem, settings: GcpSettings, n_scenes: int,
                 rng: np.random.Generator) -> dict:
    """The GCP CSV columns: points on the DEM, measured in every camera that sees them."""
    ground, placed_row = place_ground_points(scene, dem, settings.n_gcps, rng)
    ids = np.char.add("G", np.arange(1, ground.shape[0] + 1).astype(str))
    data = measure_points(scene, ground, ids, settings, rng)
    idx = data.pop("_index")
    lon, lat, h = _ground_noise(ground, settings, rng)
    data["lon"], data["lat"], data["h"] = lon[idx], lat[idx], h[idx]
    # Checks are whole ground points (all their cameras), drawn without regard to position.
    check = _exact_share(ground.shape[0], settings.check_fraction, rng)
    data["role"] = np.where(check[idx], "check", "control")
    n = idx.size
    data["sigma_px"] = np.full(n, max(settings.image_noise, 1e-3))
    data["sigma_xy"] = np.full(n, max(settings.ground_noise_xy, 1e-3))
    data["sigma_z"] = np.full(n, max(settings.ground_noise_z, 1e-3))
    data["scene"] = scene_of_rows(placed_row[idx], scene.cameras[0].rows, n_scenes)
    return data


def scene_of_rows(row: np.ndarray, rows, n_scenes: int) -> np.ndarray:
    """The scene (1..n_scenes) that row coordinates (n,) fall in, in a strip of ``rows`` image
    rows (a number, or (n,): each row's camera's)."""
    return 1 + np.clip((np.asarray(row) * n_scenes / rows).astype(int), 0, n_scenes - 1)
