"""The checks every scene read from a file passes: the scene JSON's schema (types, finite values,
ranges, monotonic times, orbit, camera geometry; the RPC scene JSON's too), and the checks that
need the model (the trajectory covers the image lines, the satellite stays in orbit, the image
corners see the Earth).

Every message names the file, the key path inside it and the value found, e.g.
``scene.json: cameras[0].focal_length: must be > 0 (got -3.3)``. The schema is checked on the
scene-JSON form of a model, so vendor metadata (read into the same model) is checked by the same
rules (see :func:`core.formats.scene_json.validate_scene`).
"""
from __future__ import annotations

import logging
import math
from datetime import datetime

import numpy as np

from ..errors import MetadataError
from ..geodesy import ray_height_intersection
from ..validation import PLAUSIBLE_HEIGHTS, plausible_heights_text
from .rpcfiles import RPC_COEFFS, RPC_KEYS

log = logging.getLogger(__name__)

# The scene JSON's identity: files name the format, and the version they were written in.
FORMAT = "pushbroom-scene"
VERSION = 2
# Distance (m) of a satellite from the Earth's centre: 120 km altitude up to beyond geostationary.
ORBIT_RADIUS = (6.5e6, 4.3e7)
ORBIT_SPEED = (1.0e3, 1.2e4)  # m/s, in ECEF
LINE_PERIOD = (1e-7, 1.0)  # s per image line
FOCAL_LENGTH = (1e-3, 100.0)  # m
IFOV = (1e-8, 1e-3)  # rad: detector pitch over focal length (1 mrad: 100 m pixels from 100 km)
MAX_COLS = 1_000_000
MAX_ROWS = 100_000_000
QUATERNION_TOLERANCE = 1e-2  # |norm - 1| normalised silently below, refused above
ROTATION_TOLERANCE = 1e-4  # installation matrices: |R R^T - I| (rounded to 6 digits by hand is fine)
# Line times may extrapolate the trajectory a little past its samples (products vary), not far.
COVERAGE_MARGIN_S = 1.0
COVERAGE_MARGIN_SHARE = 0.05


class _Schema:
    """Checks of JSON values at key paths; raises MetadataError '<source>: <path>: <problem>'."""

    def __init__(self, source: str):
        self.source = source

    def fail(self, path: str, problem: str):
        raise MetadataError(f"{self.source}: {path}: {problem}")

    def object(self, value, path: str) -> dict:
        if not isinstance(value, dict):
            self.fail(path, f"must be an object {{...}} (got {_shown(value)})")
        return value

    def required(self, d: dict, key: str, path: str):
        if key not in d:
            self.fail(_join(path, key), "required field is missing")
        return d[key]

    def string(self, value, path: str, nonempty: bool = False) -> str:
        if not isinstance(value, str) or (nonempty and not value.strip()):
            self.fail(path, f"must be a{' non-empty' if nonempty else ''} text string (got {_shown(value)})")
        return value

    def boolean(self, value, path: str) -> bool:
        if not isinstance(value, bool):
            self.fail(path, f"must be true or false (got {_shown(value)})")
        return value

    def number(self, value, path: str, lo: float | None = None, hi: float | None = None,
               lo_open: bool = False) -> float:
        """A finite JSON number in [lo, hi] (lo excluded with ``lo_open``)."""
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            self.fail(path, f"must be a number (got {_shown(value)})")
        v = float(value)
        if not math.isfinite(v):
            self.fail(path, f"must be a finite number (got {value})")
        if lo is not None and (v <= lo if lo_open else v < lo):
            self.fail(path, f"must be {'>' if lo_open else '>='} {lo:g} (got {value:g})")
        if hi is not None and v > hi:
            self.fail(path, f"must be <= {hi:g} (got {value:g})")
        return v

    def integer(self, value, path: str, lo: int, hi: int) -> int:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or \
                (isinstance(value, float) and not (math.isfinite(value) and value.is_integer())):
            self.fail(path, f"must be a whole number (got {_shown(value)})")
        if not lo <= value <= hi:
            self.fail(path, f"must be between {lo} and {hi} (got {value:g})")
        return int(value)

    def array(self, value, path: str, shape: tuple) -> np.ndarray:
        """Finite numbers of the given shape (None: any length on that axis)."""
        if not isinstance(value, list):
            self.fail(path, f"must be a list of numbers (got {_shown(value)})")
        try:
            kind = np.array(value).dtype.kind
        except ValueError:  # ragged rows
            kind = "O"
        if kind not in "iuf":  # also text ("0"), true/false and null
            self.fail(path, "must hold only numbers, in rows of equal length")
        a = np.array(value, dtype=float)
        if a.ndim != len(shape) or any(n is not None and n != m for n, m in zip(shape, a.shape)):
            want = " x ".join("N" if n is None else str(n) for n in shape)
            self.fail(path, f"must be an array of shape {want} (got shape {' x '.join(map(str, a.shape)) or '()'})")
        bad = ~np.isfinite(a)
        if bad.any():
            index = np.argwhere(bad)[0]
            self.fail(_join(path, index), f"must be a finite number (got {a[tuple(index)]})")
        return a

    def lengths_within(self, rows: np.ndarray, path: str, bounds: tuple[float, float], problem: str) -> None:
        """Every row's length within ``bounds``; ``problem`` formats (length, low, high)."""
        with np.errstate(over="ignore"):
            length = np.linalg.norm(rows, axis=1)
        bad = ~((length >= bounds[0]) & (length <= bounds[1]))
        if bad.any():
            i = int(np.argmax(bad))
            self.fail(_join(path, [i]), problem.format(length[i], *bounds))

    def sample_times(self, d: dict, path: str) -> np.ndarray:
        """The strictly increasing ``times`` (at least 2) of a trajectory table."""
        times = self.array(self.required(d, "times", path), f"{path}.times", (None,))
        if times.size < 2:
            self.fail(f"{path}.times", f"needs at least 2 samples (got {times.size})")
        self.increasing(times, f"{path}.times")
        return times

    def increasing(self, a: np.ndarray, path: str) -> None:
        steps = np.diff(a)
        if (steps <= 0).any():
            i = int(np.argmax(steps <= 0)) + 1
            self.fail(_join(path, [i]), f"must be greater than the previous value (times strictly increasing; "
                                        f"got {a[i]:.9g} after {a[i - 1]:.9g})")


    def monotonic(self, a: np.ndarray, path: str) -> None:
        """Strictly increasing, or strictly decreasing (a reverse scan's line times)."""
        steps = np.diff(a) * (1.0 if a[-1] >= a[0] else -1.0)
        if (steps <= 0).any():
            i = int(np.argmax(steps <= 0)) + 1
            self.fail(_join(path, [i]), f"must keep the direction of the values before it (times strictly "
                                        f"increasing, or strictly decreasing in a reverse scan; got {a[i]:.9g} "
                                        f"after {a[i - 1]:.9g})")


def _join(path: str, key) -> str:
    if isinstance(key, (list, tuple, np.ndarray)):
        return path + "".join(f"[{int(k)}]" for k in key)
    return f"{path}.{key}" if path else str(key)


def _shown(value) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


# --- the scene JSON schema -------------------------------------------------------------------
def check_scene_dict(d, source: str) -> dict:
    """Check a scene-JSON object (see :mod:`core.formats.scene_json`) against the schema.

    Returns the object to build the model from: ``d`` itself, or a copy whose attitude
    quaternions are normalised when they deviate from unit length by at most
    QUATERNION_TOLERANCE. Raises MetadataError naming ``source`` and the key path.
    """
    s = _Schema(source)
    s.object(d, "scene")
    if d.get("format") != FORMAT:
        raise MetadataError(f"{source}: not a Pushbroom Adjust scene (field 'format' must be {FORMAT!r})")
    if "version" in d:
        if s.integer(d["version"], "version", 1, 10 ** 6) > VERSION:
            raise MetadataError(f"{source}: scene version {d['version']} is newer than this plugin reads ({VERSION})")
    _check_epoch(s, s.required(d, "epoch", ""))
    platform = s.object(s.required(d, "platform", ""), "platform")
    _check_ephemeris(s, s.object(s.required(platform, "ephemeris", "platform"), "platform.ephemeris"))
    attitude = _check_attitude(s, s.object(s.required(platform, "attitude", "platform"), "platform.attitude"))
    if platform.get("correction") is not None:
        s.object(platform["correction"], "platform.correction")
    names = _check_cameras(s, s.required(d, "cameras", ""))
    for name, correction in s.object(platform.get("camera_corrections") or {}, "platform.camera_corrections").items():
        if name not in names:
            s.fail(f"platform.camera_corrections.{name}",
                   f"names no camera of this scene (cameras: {', '.join(names)})")
        s.object(correction, f"platform.camera_corrections.{name}")
    for key, value in s.object(d.get("corrections", {}), "corrections").items():
        s.boolean(value, f"corrections.{key}")
    info = s.object(d.get("info", {}), "info")
    if "height_range" in info:
        _check_height_range(s, info["height_range"], "info.height_range")
    if attitude is not None:
        d = {**d, "platform": {**platform, "attitude": attitude}}
    return d


def check_rpc_scene_dict(d: dict, source: str) -> dict:
    """Check an RPC scene-JSON object (``"model": "rpc"``, see :mod:`core.model.rpcscene`): camera
    {name, cols, rows}, rpc {LINE_OFF ... HEIGHT_SCALE: numbers, scales non-zero; *_COEFF: 20
    numbers}, optional correction {col, row: 3 numbers each} and info. Returns ``d``; raises
    MetadataError naming ``source`` and the key path."""
    s = _Schema(source)
    camera = s.object(s.required(d, "camera", ""), "camera")
    s.string(s.required(camera, "name", "camera"), "camera.name", nonempty=True)
    s.integer(s.required(camera, "cols", "camera"), "camera.cols", 1, MAX_COLS)
    s.integer(s.required(camera, "rows", "camera"), "camera.rows", 1, MAX_ROWS)
    rpc = s.object(s.required(d, "rpc", ""), "rpc")
    for key in RPC_KEYS:
        v = s.number(s.required(rpc, key, "rpc"), f"rpc.{key}")
        if key.endswith("_SCALE") and v == 0:
            s.fail(f"rpc.{key}", "a scale must not be 0")
    for key, _ in RPC_COEFFS:
        s.array(s.required(rpc, key, "rpc"), f"rpc.{key}", (20,))
    correction = s.object(d.get("correction", {}), "correction")
    for key in ("col", "row"):
        if key in correction:
            s.array(correction[key], f"correction.{key}", (3,))
    s.object(d.get("info", {}), "info")
    return d


def _check_epoch(s: _Schema, epoch) -> None:
    text = s.string(epoch, "epoch", nonempty=True)
    try:
        datetime.fromisoformat(text.strip().replace("Z", "+00:00"))
    except ValueError:
        s.fail("epoch", f"must be a UTC date and time in ISO 8601, e.g. 2010-12-15T03:00:00Z (got {_shown(text)})")


def _check_order(s: _Schema, value, path: str, samples: int) -> None:
    # Order = samples per Lagrange window: 1 would be a staircase, 0 puts everything at zero.
    s.integer(value, path, 2, max(samples, 2))


def _check_ephemeris(s: _Schema, e: dict) -> None:
    p = "platform.ephemeris"
    times = s.sample_times(e, p)
    pos = s.array(s.required(e, "positions", p), f"{p}.positions", (times.size, 3))
    s.lengths_within(pos, f"{p}.positions", ORBIT_RADIUS, "is {:.6g} m from the Earth's centre; a satellite is "
                                                          "{:.3g} to {:.3g} m away (ECEF metres expected)")
    if e.get("velocities") is not None:
        vel = s.array(e["velocities"], f"{p}.velocities", (times.size, 3))
        s.lengths_within(vel, f"{p}.velocities", ORBIT_SPEED, "speed {:.6g} m/s is not an orbital speed "
                                                              "({:g} to {:g} m/s, ECEF m/s expected)")
    if "order" in e:
        _check_order(s, e["order"], f"{p}.order", times.size)


def _check_attitude(s: _Schema, a: dict) -> dict | None:
    """Check the attitude; returns a copy with normalised quaternions when they needed it."""
    p = "platform.attitude"
    kind = s.required(a, "kind", p)
    if kind == "quaternion_polynomial":
        s.number(s.required(a, "offset", p), f"{p}.offset")
        scale = s.number(s.required(a, "scale", p), f"{p}.scale")
        if scale == 0:
            s.fail(f"{p}.scale", "must not be 0")
        s.array(s.required(a, "coefficients", p), f"{p}.coefficients", (4, None))
        return None
    if kind != "quaternion_samples":
        s.fail(f"{p}.kind", f"must be 'quaternion_samples' or 'quaternion_polynomial' (got {_shown(kind)})")
    times = s.sample_times(a, p)
    q = s.array(s.required(a, "quaternions", p), f"{p}.quaternions", (times.size, 4))
    norm = np.linalg.norm(q, axis=1)
    off = np.abs(norm - 1.0) > QUATERNION_TOLERANCE
    if off.any():
        i = int(np.argmax(off))
        s.fail(f"{p}.quaternions[{i}]", f"must be a unit quaternion (norm {norm[i]:.6g}; within "
                                        f"{QUATERNION_TOLERANCE:g} of 1 is normalised)")
    if "order" in a:
        _check_order(s, a["order"], f"{p}.order", times.size)
    if np.abs(norm - 1.0).max() > 1e-12:
        log.info("%s: attitude quaternions normalised (largest deviation from unit norm %.2g)", s.source,
                 np.abs(norm - 1.0).max())
        return {**a, "quaternions": (q / norm[:, None]).tolist()}
    return None


def _check_cameras(s: _Schema, cameras) -> dict:
    """Check the cameras; returns their names -> index."""
    if not isinstance(cameras, list) or not cameras:
        s.fail("cameras", f"must be a non-empty list of cameras (got {_shown(cameras)})")
    names = {}
    for i, cam in enumerate(cameras):
        path = f"cameras[{i}]"
        s.object(cam, path)
        name = s.string(s.required(cam, "name", path), f"{path}.name", nonempty=True)
        if name in names:
            s.fail(f"{path}.name", f"{name!r} is already the name of cameras[{names[name]}]; names must be unique")
        names[name] = i
        cols = s.integer(s.required(cam, "cols", path), f"{path}.cols", 1, MAX_COLS)
        s.integer(s.required(cam, "rows", path), f"{path}.rows", 1, MAX_ROWS)
        _check_timing(s, s.object(s.required(cam, "timing", path), f"{path}.timing"), f"{path}.timing")
        focal = s.number(cam.get("focal_length", 1.0), f"{path}.focal_length", 0.0, FOCAL_LENGTH[1], lo_open=True)
        if focal < FOCAL_LENGTH[0]:
            s.fail(f"{path}.focal_length", f"{focal:g} m is not a plausible focal length "
                                           f"({FOCAL_LENGTH[0]:g} to {FOCAL_LENGTH[1]:g} m; metres expected)")
        if "principal_point" in cam:
            s.array(cam["principal_point"], f"{path}.principal_point", (2,))
        for key, value in s.object(cam.get("distortion", {}), f"{path}.distortion").items():
            s.number(value, f"{path}.distortion.{key}")
        if "installation" in cam:
            _check_rotation(s, s.array(cam["installation"], f"{path}.installation", (3, 3)), f"{path}.installation")
        _check_chips(s, s.required(cam, "chips", path), path, cols, focal)
    return names


def _check_timing(s: _Schema, timing: dict, path: str) -> None:
    if "lines" in timing:
        lines = s.array(timing["lines"], f"{path}.lines", (None,))
        times = s.array(s.required(timing, "times", path), f"{path}.times", (lines.size,))
        if lines.size < 2:
            s.fail(f"{path}.lines", f"needs at least 2 (line, time) pairs (got {lines.size})")
        s.increasing(lines, f"{path}.lines")
        s.monotonic(times, f"{path}.times")
        period = abs(times[-1] - times[0]) / (lines[-1] - lines[0])  # a reverse scan's times decrease
        where = f"{path}.times"
    else:
        s.number(s.required(timing, "t0", path), f"{path}.t0")
        period = s.number(s.required(timing, "period", path), f"{path}.period", 0.0, lo_open=True)
        where = f"{path}.period"
    if not LINE_PERIOD[0] <= period <= LINE_PERIOD[1]:
        s.fail(where, f"a line period of {period:g} s is not plausible ({LINE_PERIOD[0]:g} to {LINE_PERIOD[1]:g} s)")


def _check_rotation(s: _Schema, r: np.ndarray, path: str) -> None:
    error = np.abs(r @ r.T - np.eye(3)).max()
    if error > ROTATION_TOLERANCE or np.linalg.det(r) < 0:
        s.fail(path, f"must be a rotation matrix (orthonormal, determinant +1; R R^T differs from I by {error:.2g}, "
                     f"determinant {np.linalg.det(r):.6g})")


def _check_chips(s: _Schema, chips, path: str, cols: int, focal: float) -> None:
    if not isinstance(chips, list) or not chips:
        s.fail(f"{path}.chips", f"must be a non-empty list of detector chips (got {_shown(chips)})")
    spans = []
    for k, chip in enumerate(chips):
        cp = f"{path}.chips[{k}]"
        s.object(chip, cp)
        offset = s.number(s.required(chip, "col_offset", cp), f"{cp}.col_offset", -MAX_COLS, MAX_COLS)
        n = s.integer(s.required(chip, "n_pixels", cp), f"{cp}.n_pixels", 1, MAX_COLS)
        s.number(chip.get("time_offset", 0.0), f"{cp}.time_offset", -10.0, 10.0)
        kind = chip.get("kind", "focal_plane")
        if kind == "focal_plane":
            for key in ("x0", "y0", "theta"):
                s.number(chip.get(key, 0.0), f"{cp}.{key}", -1.0 if key != "theta" else None,
                         1.0 if key != "theta" else None)
            pitch = s.number(s.required(chip, "pitch", cp), f"{cp}.pitch", 0.0, lo_open=True)
            if not IFOV[0] <= pitch / focal <= IFOV[1]:
                s.fail(f"{cp}.pitch", f"pitch {pitch:g} m over the focal length {focal:g} m gives "
                                      f"{pitch / focal:.3g} rad per pixel; plausible is {IFOV[0]:g} to {IFOV[1]:g} "
                                      f"(both in metres)")
        elif kind == "look_angle":
            pairs = [("ux_poly", "uy_poly"), ("ux_table", "uy_table")]
            given = [pair for pair in pairs if all(chip.get(key) is not None for key in pair)]
            if not given:
                s.fail(cp, "a look-angle chip needs ux_poly and uy_poly, or ux_table and uy_table")
            for key in given[0]:
                s.array(chip[key], f"{cp}.{key}", (None,))
        else:
            s.fail(f"{cp}.kind", f"must be 'focal_plane' or 'look_angle' (got {_shown(kind)})")
        spans.append((offset, offset + n, k))
    _check_chip_coverage(s, sorted(spans), path, cols)


def _check_chip_coverage(s: _Schema, spans: list, path: str, cols: int) -> None:
    """The chips, in column order, deliver every image column from 0 to cols."""
    reach = 0.0
    for start, end, k in spans:
        if start > reach + 0.5:
            s.fail(f"{path}.chips[{k}].col_offset", f"leaves image columns {reach:g} to {start:g} without a detector")
        reach = max(reach, end)
    if reach < cols - 0.5:
        s.fail(f"{path}.chips", f"detectors end at column {reach:g}, short of the image's {cols} columns")


def _check_height_range(s: _Schema, value, path: str) -> tuple[float, float]:
    """The [lowest, highest] ellipsoidal heights (m) at ``path``: two numbers, in order, of terrain."""
    lo, hi = s.array(value, path, (2,))
    if not lo <= hi:
        s.fail(path, f"must be [lowest, highest] (got [{lo:g}, {hi:g}])")
    if lo < PLAUSIBLE_HEIGHTS[0] or hi > PLAUSIBLE_HEIGHTS[1]:
        s.fail(path, f"[{lo:g}, {hi:g}] m is outside the heights terrain has ({plausible_heights_text()})")
    return lo, hi


# --- checks on the model -----------------------------------------------------------------------
def check_scene_model(scene, source: str) -> None:
    """Checks that need the model: the trajectory covers every image line, the satellite stays
    in orbit over the scene's time span, attitude polynomials give unit quaternions, and every
    camera's image corners look at the Earth. Raises MetadataError naming ``source``."""
    t0, t1 = scene.time_span()
    margin = max(COVERAGE_MARGIN_S, COVERAGE_MARGIN_SHARE * (t1 - t0))
    platform = scene.platform
    samples = [("platform.ephemeris.times", platform.ephemeris.times)]
    if hasattr(platform.attitude, "times"):
        samples.append(("platform.attitude.times", platform.attitude.times))
    for path, times in samples:
        if times[0] > t0 + margin or times[-1] < t1 - margin:
            raise MetadataError(f"{source}: {path}: samples from {times[0]:.6g} to {times[-1]:.6g} s do not cover "
                                f"the image lines, acquired from {t0:.6g} to {t1:.6g} s")
    t = np.linspace(t0, t1, 65)
    quaternion = getattr(platform.attitude, "quaternion", None)
    if quaternion is not None:
        norm = np.linalg.norm(quaternion(t), axis=1)
        off = np.abs(norm - 1.0) > QUATERNION_TOLERANCE
        if off.any():
            i = int(np.argmax(off))
            raise MetadataError(f"{source}: platform.attitude.coefficients: the quaternion at t = {t[i]:.6g} s has "
                                f"norm {norm[i]:.6g}, not 1")
    pos, _, _ = platform.state(t)
    radius = np.linalg.norm(pos, axis=1)
    bad = ~((radius >= ORBIT_RADIUS[0]) & (radius <= ORBIT_RADIUS[1]))
    if bad.any():
        i = int(np.argmax(bad))
        raise MetadataError(f"{source}: platform: the satellite is {radius[i]:.6g} m from the Earth's centre at "
                            f"t = {t[i]:.6g} s (interpolated); a satellite is {ORBIT_RADIUS[0]:.3g} to "
                            f"{ORBIT_RADIUS[1]:.3g} m away")
    _check_views(scene, source)


def _check_views(scene, source: str) -> None:
    """Every camera's image corners and centre see the ellipsoid in front of the satellite."""
    for i, cam in enumerate(scene.cameras):
        col = np.array([0.0, cam.cols, 0.0, cam.cols, cam.cols / 2])
        row = np.array([0.0, 0.0, cam.rows, cam.rows, cam.rows / 2])
        # from the exact trajectory: preparing the scene's cache here would outlive later edits of the model
        s, _, r = scene.platform_of(i).state(cam.timing.time(row) + cam.time_offset(cam.chip_index(col)))
        u = np.einsum("nij,nj->ni", r, cam.los_camera(col) @ cam.installation.T)
        dist = ray_height_intersection(s, u / np.linalg.norm(u, axis=1, keepdims=True), 0.0, newton_steps=0)
        missed = ~np.isfinite(dist)
        if missed.any():
            k = int(np.argmax(missed))
            raise MetadataError(f"{source}: cameras[{i}]: the line of sight of image point (col {col[k]:g}, row "
                                f"{row[k]:g}) misses the Earth; check the camera's installation, chips and the "
                                f"attitude")
