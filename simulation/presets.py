"""Simulation presets: the sensors and orbits :func:`simulation.simulator.simulate` knows, and the
magnitudes of the errors it draws (:class:`ErrorSettings`, camera terms in px at the array end).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..core.errors import InputError
from ..core.rotations import ARCSEC


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
    :class:`core.model.camera.Camera` and is not simulated; its low-order part is what p1 and b2 model.
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
# (core.model.camera.CAMERA_TERMS: 'f' is the focal length, the others Camera.distortion).
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
# docs/algorithms/simulatescene.md.
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


def resolve_errors(spec: Preset, errors) -> ErrorSettings:
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
        raise InputError(f"unknown error setting(s) {sorted(unknown)} "
                         f"(known: {', '.join(ErrorSettings.__dataclass_fields__)})")
    bad = {k: v for k, v in errors.items() if not (np.isfinite(v) and v >= 0)}
    if bad:
        raise InputError(f"error magnitudes must be finite and >= 0 (got {bad})")
    return replace(spec.errors, **{k: float(v) for k, v in errors.items()})
