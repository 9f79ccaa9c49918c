"""Platform trajectory: ephemeris (position, velocity) and attitude (body -> ECEF).

Times are float seconds from the scene epoch. Positions/velocities are ECEF metres and
m/s, shape (n, 3). Attitude is returned as rotation matrices body -> ECEF, shape (n, 3, 3).
Every model extrapolates smoothly past its samples (never clamps): line times beyond the
ends of a product's tables are legitimate.
"""
from __future__ import annotations

import hashlib
import weakref
from dataclasses import dataclass, field, fields

import numpy as np

from ..errors import MetadataError
from ..rotations import quat_to_matrix, rotation_from_angles
from .timebasis import TimeBasis


def _lagrange_weights(nodes: np.ndarray, order: int, t: np.ndarray,
                      denominators: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Window start indices (n,) and Lagrange weights (n, order) for sample times ``nodes``
    (:func:`lagrange_denominators` of them given)."""
    n_nodes = nodes.size
    start = np.clip(np.searchsorted(nodes, t) - order // 2, 0, n_nodes - order)
    idx = start[:, None] + np.arange(order)
    diff = t[:, None] - nodes[idx]
    # Products over k != j without dividing by diff_j (which may be exactly zero).
    ones = np.ones((t.size, 1))
    left = np.cumprod(np.hstack([ones, diff[:, :-1]]), axis=1)
    right = np.cumprod(np.hstack([ones, diff[:, :0:-1]]), axis=1)[:, ::-1]
    return start, left * right / denominators[start]


def lagrange_denominators(nodes: np.ndarray, order: int) -> np.ndarray:
    """(n_nodes - order + 1, order): prod over k != j of (node_j - node_k) in each window of
    ``order`` nodes, by its first node (they depend on the window alone: computed once per
    window, not once per time)."""
    tw = nodes[np.arange(nodes.size - order + 1)[:, None] + np.arange(order)]
    return np.prod(np.where(np.eye(order, dtype=bool), 1.0, tw[:, :, None] - tw[:, None, :]), axis=2)


@dataclass
class Ephemeris:
    """Sampled ECEF orbit, Lagrange-interpolated.

    times: (N,) s, strictly increasing; positions: (N, 3) m; velocities: (N, 3) m/s or None
    (then differentiated from the position interpolant); order: points per Lagrange window.
    """
    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray | None = None
    order: int = 8
    _denominators: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        self.times = np.asarray(self.times, dtype=float)
        self.positions = np.asarray(self.positions, dtype=float).reshape(-1, 3)
        if self.velocities is not None:
            self.velocities = np.asarray(self.velocities, dtype=float).reshape(-1, 3)
        if self.times.size < 2 or self.times.size != self.positions.shape[0]:
            raise MetadataError(f"ephemeris needs at least 2 samples with matching times and positions "
                                f"(got {self.times.size} times, {self.positions.shape[0]} positions)")
        if not np.all(np.isfinite(self.positions)) or not np.all(np.isfinite(self.times)):
            raise MetadataError("ephemeris contains non-finite values")
        if np.any(np.diff(self.times) <= 0):
            raise MetadataError("ephemeris times are not strictly increasing")
        self.order = int(min(self.order, self.times.size))
        self._denominators = lagrange_denominators(self.times, self.order)

    def position(self, t) -> np.ndarray:
        """ECEF position (n, 3) m at times t (n,) s."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        return self._interpolate(self.positions, *_lagrange_weights(self.times, self.order, t, self._denominators))

    def velocity(self, t) -> np.ndarray:
        """ECEF velocity (n, 3) m/s at times t (n,) s."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if self.velocities is not None:
            return self._interpolate(self.velocities, *_lagrange_weights(self.times, self.order, t, self._denominators))
        # Central difference: 0.05 s balances truncation (~h^2 r omega^3 / 6) and round-off.
        h = 0.05
        return (self.position(t + h) - self.position(t - h)) / (2 * h)

    def position_velocity(self, t) -> tuple[np.ndarray, np.ndarray]:
        """(:meth:`position`, :meth:`velocity`) at times t (n,) s; sampled velocities share the
        positions' Lagrange weights."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if self.velocities is None:
            return self.position(t), self.velocity(t)
        window = _lagrange_weights(self.times, self.order, t, self._denominators)
        return self._interpolate(self.positions, *window), self._interpolate(self.velocities, *window)

    def _interpolate(self, samples: np.ndarray, start: np.ndarray, w: np.ndarray) -> np.ndarray:
        """(n, 3): the Lagrange windows (start (n,), weights (n, order)) of ``samples`` (N, 3)."""
        return np.einsum("nk,nki->ni", w, samples[start[:, None] + np.arange(self.order)])

    def to_dict(self) -> dict:
        d = {"times": self.times.tolist(), "positions": self.positions.tolist(), "order": self.order}
        if self.velocities is not None:
            d["velocities"] = self.velocities.tolist()
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "Ephemeris":
        return cls(np.array(d["times"]), np.array(d["positions"]),
                   None if d.get("velocities") is None else np.array(d["velocities"]), int(d.get("order", 8)))


def _continuous_quaternions(q: np.ndarray) -> np.ndarray:
    """Flip signs so consecutive quaternions lie in the same hemisphere (q and -q are equal)."""
    q = np.array(q, dtype=float)
    flips = np.cumsum(np.r_[0, (np.einsum("ij,ij->i", q[1:], q[:-1]) < 0).astype(int)]) % 2
    q[flips == 1] *= -1
    return q


@dataclass
class QuaternionSamples:
    """Attitude from sampled quaternions (N, 4), scalar first, rotating body -> ECEF.

    Interpolated component-wise with ``order``-point Lagrange windows (2 = linear), then
    normalised; signs are made continuous first.
    """
    times: np.ndarray
    quaternions: np.ndarray
    order: int = 4
    _denominators: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        self.times = np.asarray(self.times, dtype=float)
        q = np.asarray(self.quaternions, dtype=float).reshape(-1, 4)
        if self.times.size < 2 or self.times.size != q.shape[0]:
            raise MetadataError(f"attitude needs at least 2 samples with matching times and quaternions "
                                f"(got {self.times.size} times, {q.shape[0]} quaternions)")
        if not np.all(np.isfinite(q)) or np.any(np.linalg.norm(q, axis=1) < 0.5):
            raise MetadataError("attitude quaternions contain non-finite or non-unit values")
        if np.any(np.diff(self.times) <= 0):
            raise MetadataError("attitude times are not strictly increasing")
        self.quaternions = _continuous_quaternions(q)
        self.order = int(min(self.order, self.times.size))
        self._denominators = lagrange_denominators(self.times, self.order)

    def rotation(self, t) -> np.ndarray:
        """Body -> ECEF rotation matrices (n, 3, 3) at times t (n,) s."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        start, w = _lagrange_weights(self.times, self.order, t, self._denominators)
        idx = start[:, None] + np.arange(self.order)
        return quat_to_matrix(np.einsum("nk,nki->ni", w, self.quaternions[idx]))

    def to_dict(self) -> dict:
        return {"kind": "quaternion_samples", "times": self.times.tolist(),
                "quaternions": self.quaternions.tolist(), "order": self.order}


@dataclass
class QuaternionPolynomial:
    """Attitude as four polynomials q_i(u), u = (t - offset) / scale, scalar first, body -> ECEF.

    coefficients: (4, degree + 1), ascending powers of u (the Pleiades DIMAP form).
    """
    offset: float
    scale: float
    coefficients: np.ndarray

    def __post_init__(self):
        self.coefficients = np.asarray(self.coefficients, dtype=float).reshape(4, -1)
        if not np.all(np.isfinite(self.coefficients)) or not np.isfinite(self.scale) or self.scale == 0:
            raise MetadataError("attitude polynomial has non-finite coefficients or a zero scale")

    def quaternion(self, t) -> np.ndarray:
        """The polynomials' quaternions (n, 4) at times t (n,) s, not normalised."""
        u = (np.atleast_1d(np.asarray(t, dtype=float)) - self.offset) / self.scale
        return (u[:, None] ** np.arange(self.coefficients.shape[1])) @ self.coefficients.T

    def rotation(self, t) -> np.ndarray:
        """Body -> ECEF rotation matrices (n, 3, 3) at times t (n,) s."""
        return quat_to_matrix(self.quaternion(t))

    def to_dict(self) -> dict:
        return {"kind": "quaternion_polynomial", "offset": self.offset, "scale": self.scale,
                "coefficients": self.coefficients.tolist()}


def attitude_from_dict(d: dict):
    """Rebuild an attitude model written by ``to_dict``."""
    kind = d.get("kind")
    if kind == "quaternion_samples":
        return QuaternionSamples(np.array(d["times"]), np.array(d["quaternions"]), int(d.get("order", 4)))
    if kind == "quaternion_polynomial":
        return QuaternionPolynomial(float(d["offset"]), float(d["scale"]), np.array(d["coefficients"]))
    raise MetadataError(f"unknown attitude model kind {kind!r} (expected quaternion_samples or quaternion_polynomial)")


@dataclass
class TrajectoryCorrection:
    """Corrections estimated by an adjustment, on top of the measured trajectory:

        position(t) = measured position(t) + Bp(t) @ position_coefficients     (ECEF m)
        rotation(t) = measured rotation(t) @ R(Ba(t) @ attitude_coefficients)   (body frame)

    with R = rotation_from_angles(roll, pitch, yaw) (rad) and Bp, Ba time bases (see
    :mod:`core.model.timebasis`). Coefficients: (m, 3) arrays, columns X, Y, Z and roll, pitch, yaw.
    """
    position: TimeBasis
    position_coefficients: np.ndarray
    attitude: TimeBasis
    attitude_coefficients: np.ndarray

    def __post_init__(self):
        self.position_coefficients = np.asarray(self.position_coefficients, dtype=float).reshape(-1, 3)
        self.attitude_coefficients = np.asarray(self.attitude_coefficients, dtype=float).reshape(-1, 3)
        for name, basis, coef in (("position", self.position, self.position_coefficients),
                                  ("attitude", self.attitude, self.attitude_coefficients)):
            if coef.shape[0] != basis.size or not np.all(np.isfinite(coef)):
                raise MetadataError(f"trajectory correction: {name} needs {basis.size} finite rows of 3 "
                                    f"coefficients (got {coef.shape[0]})")

    def offsets(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(position offset (n,3) m, velocity offset (n,3) m/s, attitude angles (n,3) rad) at t."""
        return (self.position.matrix(t) @ self.position_coefficients,
                self.position.derivative(t) @ self.position_coefficients,
                self.attitude.matrix(t) @ self.attitude_coefficients)

    def apply(self, t, pos, vel, rot) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The corrected (position, velocity, rotation) from measured ones at times t."""
        dp, dv, angles = self.offsets(np.atleast_1d(np.asarray(t, dtype=float)))
        return pos + dp, vel + dv, rot @ rotation_from_angles(angles[:, 0], angles[:, 1], angles[:, 2])

    def to_dict(self) -> dict:
        return {"position": {"basis": self.position.to_dict(), "coefficients": self.position_coefficients.tolist()},
                "attitude": {"basis": self.attitude.to_dict(), "coefficients": self.attitude_coefficients.tolist()}}

    @classmethod
    def from_dict(cls, d: dict) -> "TrajectoryCorrection":
        return cls(TimeBasis.from_dict(d["position"]["basis"]), np.array(d["position"]["coefficients"]),
                   TimeBasis.from_dict(d["attitude"]["basis"]), np.array(d["attitude"]["coefficients"]))


# Measured-trajectory tables (n, 15) by content and grid, while a platform's cache holds them: an
# adjustment tabulates one trajectory for its input scene, the adjusted scene and that scene read
# back from its file (a block's composite: one per scene each), the same numbers each time.
_MEASURED_TABLES: "weakref.WeakValueDictionary[tuple, np.ndarray]" = weakref.WeakValueDictionary()


def _content_key(model) -> bytes:
    """A digest of what defines an ephemeris or attitude model (a dataclass: its public fields)."""
    digest = hashlib.blake2b(type(model).__name__.encode(), digest_size=20)
    for f in fields(model):
        if not f.name.startswith("_"):
            value = getattr(model, f.name)
            digest.update(np.ascontiguousarray(value).tobytes() if isinstance(value, np.ndarray) else
                          repr(value).encode())
    return digest.digest()


def measured_table(ephemeris: Ephemeris, attitude, t0: float, n: int, step: float) -> np.ndarray:
    """(n, 15) position (m), velocity (m/s), rotation body -> ECEF (9, row-major) of the measured
    trajectory at times t0 + step * arange(n) s; made once while a table of the same trajectory
    and times is held (:data:`_MEASURED_TABLES`)."""
    key = (_content_key(ephemeris), _content_key(attitude), t0, n, step)
    table = _MEASURED_TABLES.get(key)
    if table is None:
        grid = t0 + step * np.arange(n)
        pos, vel = ephemeris.position_velocity(grid)
        table = np.concatenate([pos, vel, attitude.rotation(grid).reshape(n, 9)], axis=1)
        _MEASURED_TABLES[key] = table
    return table


@dataclass
class Platform:
    """Ephemeris plus attitude (plus an adjustment's correction, if any), with a dense sampled
    cache for fast repeated evaluation.

    ``camera_corrections`` (camera name -> correction) are written by an adjustment with one
    trajectory correction per camera (seed 003 Plan A): a camera listed there sees the measured
    trajectory under its own correction instead of ``correction`` (:meth:`for_camera`).

    ``camera_platforms`` (camera name -> platform) belong to the composite scene of a block of
    scenes (:mod:`core.model.block`): a camera listed there sees that platform (its own scene's
    ephemeris, attitude and corrections, times from its own scene's epoch) instead of this one.
    Such a composite is never written: its scenes are (:func:`core.model.block.split_block`).

    The cache tabulates position, velocity and rotation every ``cache_step`` seconds over the
    time spans its cameras see (a segment each) and interpolates linearly: at 1 ms steps the
    error is below 1e-6 m and 1e-12 rad for orbital motion, far under any image measurement.
    Outside the cached spans the exact models are evaluated.
    """
    ephemeris: Ephemeris
    attitude: object
    correction: TrajectoryCorrection | None = None
    cache_step: float = 1e-3
    camera_corrections: dict[str, TrajectoryCorrection] = field(default_factory=dict)
    camera_platforms: dict[str, "Platform"] = field(default_factory=dict)
    _cache: tuple | None = field(default=None, repr=False, compare=False)
    _views: dict = field(default_factory=dict, repr=False, compare=False)

    def for_camera(self, name: str) -> "Platform":
        """The trajectory camera ``name`` sees: this platform, or (with a correction of its own)
        the measured trajectory under that correction, made once and kept (with its own cache); in a
        block's composite, what the camera's own platform gives it."""
        if name in self.camera_platforms:
            return self.camera_platforms[name].for_camera(name)
        if name not in self.camera_corrections:
            return self
        if name not in self._views:
            self._views[name] = Platform(self.ephemeris, self.attitude, self.camera_corrections[name],
                                         self.cache_step)
        return self._views[name]

    def trajectory_of(self, name: str) -> "Platform":
        """The platform whose measured trajectory (ephemeris and attitude) camera ``name`` sees:
        this one, or in a block's composite its own scene's."""
        return self.camera_platforms.get(name, self)

    @property
    def tabulated(self) -> bool:
        """Whether :meth:`prepare` has tabulated this platform's trajectory."""
        return self._cache is not None

    def prepare(self, spans) -> None:
        """Tabulate the trajectory over the time spans ``spans`` [(t_min, t_max)] s (each with a
        small margin; overlapping ones merged): the measured trajectory's table
        (:func:`measured_table`) under this platform's correction, one segment per span."""
        widened = sorted((a - (0.05 * (b - a) + 10 * self.cache_step), b + 0.05 * (b - a) + 10 * self.cache_step)
                         for a, b in spans)
        merged = [list(widened[0])]
        for a, b in widened[1:]:
            if a <= merged[-1][1]:
                merged[-1][1] = max(merged[-1][1], b)
            else:
                merged.append([a, b])
        starts, counts, tables = [], [], []
        for t0, t1 in merged:
            n = int(np.ceil((t1 - t0) / self.cache_step)) + 1
            table = measured_table(self.ephemeris, self.attitude, t0, n, self.cache_step)
            if self.correction is not None:
                grid = t0 + self.cache_step * np.arange(n)
                pos, vel, rot = self.correction.apply(grid, table[:, 0:3], table[:, 3:6],
                                                      table[:, 6:15].reshape(n, 3, 3))
                table = np.concatenate([pos, vel, rot.reshape(n, 9)], axis=1)
            starts.append(t0)
            counts.append(n)
            tables.append(table)
        counts = np.array(counts, dtype=np.int64)
        self._cache = (np.array(starts), counts, np.cumsum(counts) - counts,
                       tables[0] if len(tables) == 1 else np.concatenate(tables))

    def state(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(position (n,3) m, velocity (n,3) m/s, rotation body->ECEF (n,3,3)) at times t (n,) s."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if self._cache is None:
            return self._exact_state(t)
        starts, counts, offsets, table = self._cache
        k = np.maximum(np.searchsorted(starts, t, side="right") - 1, 0) if starts.size > 1 else \
            np.zeros(t.size, dtype=np.int64)
        n = counts[k]
        f = (t - starts[k]) / self.cache_step
        inside = (f >= 0) & (f <= n - 1)
        f = np.where(inside, f, 0.0)
        i = np.minimum(f.astype(np.int64), n - 2)
        # the samples either side in one gather (n, 2, 15); their difference is not stored (the
        # table would be twice the size: a block's composite tabulates a trajectory per scene)
        pair = table[(offsets[k] + i)[:, None] + np.arange(2)]
        row = pair[:, 0] + (f - i)[:, None] * (pair[:, 1] - pair[:, 0])
        if not inside.all():
            out = ~inside
            pos, vel, rot = self._exact_state(t[out])
            row[out] = np.concatenate([pos, vel, rot.reshape(-1, 9)], axis=1)
        return row[:, 0:3], row[:, 3:6], row[:, 6:15].reshape(-1, 3, 3)

    def measured_state(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(position, velocity, rotation) of the measured trajectory alone (no correction)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        return (*self.ephemeris.position_velocity(t), self.attitude.rotation(t))

    def _exact_state(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        state = self.measured_state(t)
        return state if self.correction is None else self.correction.apply(t, *state)

    def to_dict(self) -> dict:
        if self.camera_platforms:
            raise ValueError("a block's composite platform is not written: write its scenes (split_block)")
        d = {"ephemeris": self.ephemeris.to_dict(), "attitude": self.attitude.to_dict()}
        if self.correction is not None:
            d["correction"] = self.correction.to_dict()
        if self.camera_corrections:
            d["camera_corrections"] = {k: v.to_dict() for k, v in self.camera_corrections.items()}
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "Platform":
        correction = TrajectoryCorrection.from_dict(d["correction"]) if d.get("correction") else None
        cameras = {str(k): TrajectoryCorrection.from_dict(v) for k, v in (d.get("camera_corrections") or {}).items()}
        return cls(Ephemeris.from_dict(d["ephemeris"]), attitude_from_dict(d["attitude"]), correction,
                   camera_corrections=cameras)
