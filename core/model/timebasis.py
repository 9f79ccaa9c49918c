"""Linear bases in time for trajectory corrections: f(t) = B(t) @ c.

Three families, each a (n, m) basis matrix B(t) for n times and m coefficients:

- ``polynomial``: 1, tau, tau^2 (order 0-2), tau = (t - t0) / scale — the systematic-error
  compensation of seed 000 eq. 1-2 and seed 003 eq. 8-10; order 2 without onboard
  pseudo-observations is seed 002's quadratic position-rotation model (eq. 3);
- ``lagrange``: orientation images at equally spaced knot times; a time takes the 4-point
  Lagrange interpolation of its four nearest knots (seed 000 eq. 3);
- ``spline``: piecewise quadratic polynomials between equally spaced knots, continuous in
  value and slope (seed 001 eq. 9 with its continuity conditions), as a quadratic B-spline
  basis so that continuity holds by construction.

Times are seconds from the scene epoch. Coefficients are in the unit of the corrected
quantity (m, rad) per basis function.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import BSpline

from ..errors import InputError

KINDS = ("polynomial", "lagrange", "spline")
LAGRANGE_POINTS = 4


@dataclass
class TimeBasis:
    """kind: one of KINDS. t0, scale (s): tau = (t - t0) / scale for polynomials. order:
    polynomial degree (0-2). start, interval (s), n_knots: equally spaced knots of the
    lagrange and spline kinds (covering the strip)."""
    kind: str
    t0: float = 0.0
    scale: float = 1.0
    order: int = 0
    start: float = 0.0
    interval: float = 1.0
    n_knots: int = 0

    def __post_init__(self):
        if self.kind not in KINDS:
            raise InputError(f"unknown trajectory model {self.kind!r} (choose one of {', '.join(KINDS)})")
        if self.kind == "polynomial" and not 0 <= self.order <= 2:
            raise InputError(f"polynomial order must be 0, 1 or 2 (got {self.order})")
        if self.kind == "lagrange" and self.n_knots < LAGRANGE_POINTS:
            raise InputError(f"orientation images need at least {LAGRANGE_POINTS} knots (got {self.n_knots})")
        if self.kind == "spline" and self.n_knots < 2:
            raise InputError(f"piecewise polynomials need at least 2 knots (got {self.n_knots})")
        if not (self.scale > 0 and self.interval > 0):
            raise InputError("time scale and knot interval must be positive")

    @classmethod
    def covering(cls, kind: str, t_min: float, t_max: float, order: int = 2,
                 interval: float | None = None) -> "TimeBasis":
        """A basis over [t_min, t_max] s: polynomials centred on the span (tau in [-1, 1]), or
        knots every ``interval`` s spanning it (at least the minimum count)."""
        centre, half = 0.5 * (t_min + t_max), max(0.5 * (t_max - t_min), 1e-6)
        if kind == "polynomial":
            return cls(kind, t0=centre, scale=half, order=order)
        if interval is None or not interval > 0:
            raise InputError(f"the {kind} trajectory model needs a positive knot interval (s)")
        minimum = LAGRANGE_POINTS if kind == "lagrange" else 2
        n = max(int(np.ceil((t_max - t_min) / interval - 1e-9)) + 1, minimum)
        span = (n - 1) * interval
        return cls(kind, t0=centre, scale=half, start=centre - 0.5 * span, interval=interval, n_knots=n)

    @property
    def size(self) -> int:
        """Number of coefficients m."""
        if self.kind == "polynomial":
            return self.order + 1
        return self.n_knots if self.kind == "lagrange" else self.n_knots + 1

    @property
    def width(self) -> int:
        """Coefficients that act at any one time (polynomial: all; Lagrange: 4; spline: 3)."""
        return {"polynomial": self.size, "lagrange": LAGRANGE_POINTS, "spline": 3}[self.kind]

    def window(self, t) -> tuple[np.ndarray, np.ndarray]:
        """The basis in compact form: (first coefficient index (n,), weights (n, width)) such
        that matrix(t)[i, first[i] + j] = weights[i, j] and is zero elsewhere."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if self.kind == "polynomial":
            first = np.zeros(t.size, dtype=np.int64)
        else:
            offset = 1 if self.kind == "lagrange" else 0
            first = np.clip(np.floor((t - self.start) / self.interval).astype(np.int64) - offset, 0,
                            self.size - self.width)
        idx = first[:, None] + np.arange(self.width)
        weights = np.empty((t.size, self.width))
        for lo in range(0, t.size, 65536):  # bounded temporaries for long strips
            sl = slice(lo, lo + 65536)
            weights[sl] = np.take_along_axis(self.matrix(t[sl]), idx[sl], axis=1)
        return first, weights

    def knot_times(self) -> np.ndarray:
        """(n_knots,) knot times (s); for polynomials, t0."""
        if self.kind == "polynomial":
            return np.array([self.t0])
        return self.start + self.interval * np.arange(self.n_knots)

    def labels(self) -> list[str]:
        """A short name for each coefficient."""
        if self.kind == "polynomial":
            return ["bias", "drift", "quadratic"][: self.size]
        if self.kind == "lagrange":
            return [f"OI{k + 1} t={t:.1f}s" for k, t in enumerate(self.knot_times())]
        return [f"S{k + 1}" for k in range(self.size)]

    def matrix(self, t) -> np.ndarray:
        """Basis matrix (n, m) at times t (n,) s."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if self.kind == "polynomial":
            return self._powers((t - self.t0) / self.scale, self.size)
        if self.kind == "lagrange":
            return self._lagrange(t)
        return self._spline(t)

    @staticmethod
    def _powers(tau: np.ndarray, size: int) -> np.ndarray:
        """(n, size): tau ** 0 .. tau ** (size - 1), by products (a power per element is slower)."""
        out = np.empty((tau.size, size))
        out[:, 0] = 1.0
        for k in range(1, size):
            out[:, k] = out[:, k - 1] * tau
        return out

    def derivative(self, t) -> np.ndarray:
        """d(basis)/dt (n, m) in 1/s: of a polynomial exact, else by central differences (the
        bases are piecewise cubic at most)."""
        if self.kind == "polynomial":
            powers = self._powers((np.atleast_1d(np.asarray(t, dtype=float)) - self.t0) / self.scale, self.size)
            out = np.zeros_like(powers)
            out[:, 1:] = powers[:, :-1] * (np.arange(1, self.size) / self.scale)
            return out
        h = 1e-3
        return (self.matrix(np.asarray(t, dtype=float) + h) - self.matrix(np.asarray(t, dtype=float) - h)) / (2 * h)

    def _lagrange(self, t: np.ndarray) -> np.ndarray:
        knots = self.knot_times()
        # The four knots around each time (clamped at the ends, which extrapolates the end cubic).
        first = np.clip(np.floor((t - self.start) / self.interval).astype(int) - 1, 0, self.n_knots - LAGRANGE_POINTS)
        idx = first[:, None] + np.arange(LAGRANGE_POINTS)
        tk = knots[idx]
        w = np.ones_like(tk)
        for j in range(LAGRANGE_POINTS):
            for k in range(LAGRANGE_POINTS):
                if k != j:
                    w[:, j] *= (t - tk[:, k]) / (tk[:, j] - tk[:, k])
        out = np.zeros((t.size, self.n_knots))
        np.put_along_axis(out, idx, w, axis=1)
        return out

    def _spline(self, t: np.ndarray) -> np.ndarray:
        # Quadratic B-splines on knots extended two intervals past each end; identity
        # coefficients evaluate every basis function at once, and times beyond the knots
        # follow the end pieces' polynomials.
        knots = self.start + self.interval * np.arange(-2, self.n_knots + 2)
        return BSpline(knots, np.eye(self.size), 2, extrapolate=True)(t)

    def to_dict(self) -> dict:
        return {"kind": self.kind, "t0": self.t0, "scale": self.scale, "order": self.order, "start": self.start,
                "interval": self.interval, "n_knots": self.n_knots}

    @classmethod
    def from_dict(cls, d: dict) -> "TimeBasis":
        return cls(**{k: d[k] for k in ("kind", "t0", "scale", "order", "start", "interval", "n_knots") if k in d})
