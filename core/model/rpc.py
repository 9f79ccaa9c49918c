"""Rational polynomial (RPC00B) camera models: evaluation, and inversion by Newton.

Ground coordinates are (lon, lat) degrees and ellipsoidal height (m). The model's own image
coordinates (sample, line) are converted to GDAL (col, row) with ``origin``: the model
coordinate of the centre of the upper-left pixel (0 for RPC00B/GDAL RPC metadata, 1 for
DIMAP v2's 1-based convention), so col = sample - origin + 0.5.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConvergenceError, MetadataError


def _check_coefficients(model, names: tuple[str, ...], what: str) -> None:
    """Make each named attribute a (20,) float array; MetadataError naming a bad one."""
    for k in names:
        v = np.asarray(getattr(model, k), dtype=float).ravel()
        if v.size != 20 or not np.all(np.isfinite(v)):
            raise MetadataError(f"{what} {k} must hold 20 finite numbers (got {v.size})")
        setattr(model, k, v)


def rpc_terms(x, y, z) -> np.ndarray:
    """The 20 RPC00B monomials (n, 20) of normalised (x = lon, y = lat, z = height), broadcast."""
    x, y, z = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (x, y, z)))
    one = np.ones_like(x)
    return np.stack([one, x, y, z, x * y, x * z, y * z, x * x, y * y, z * z, x * y * z, x ** 3, x * y * y,
                     x * z * z, x * x * y, y ** 3, y * z * z, x * x * z, y * y * z, z ** 3], axis=-1)


# The exponents of (x, y, z) in each of the 20 monomials of rpc_terms.
EXPONENTS = np.array([(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0), (1, 0, 1), (0, 1, 1), (2, 0, 0), (0, 2, 0),
                      (0, 0, 2), (1, 1, 1), (3, 0, 0), (1, 2, 0), (1, 0, 2), (2, 1, 0), (0, 3, 0), (0, 1, 2), (2, 0, 1),
                      (0, 2, 1), (0, 0, 3)])


def derivative_operators() -> np.ndarray:
    """(3, 20, 20): D[a] maps the 20 coefficients of a cubic of rpc_terms onto those of its
    derivative by x, y or z (a = 0, 1, 2), again over rpc_terms (the derivative of a monomial is
    its exponent times the monomial with that exponent lowered by one: a term of lower degree)."""
    index = {tuple(e): m for m, e in enumerate(EXPONENTS)}
    d = np.zeros((3, 20, 20))
    for k, e in enumerate(EXPONENTS):
        for a in np.nonzero(e)[0]:
            d[a, index[tuple(e - np.eye(3, dtype=int)[a])], k] = e[a]
    return d


DERIVATIVE = derivative_operators()


@dataclass
class RpcModel:
    """Direct RPC00B model ground -> image.

    coefficients: dict with 'line_num', 'line_den', 'samp_num', 'samp_den', each (20,).
    Offsets/scales: lon, lat (deg), height (m), line, samp (model pixels).
    """
    line_num: np.ndarray
    line_den: np.ndarray
    samp_num: np.ndarray
    samp_den: np.ndarray
    lon_off: float
    lon_scale: float
    lat_off: float
    lat_scale: float
    height_off: float
    height_scale: float
    line_off: float
    line_scale: float
    samp_off: float
    samp_scale: float
    origin: float = 0.0

    def __post_init__(self):
        _check_coefficients(self, ("line_num", "line_den", "samp_num", "samp_den"), "RPC coefficient list")
        coefficients = np.stack([self.samp_num, self.samp_den, self.line_num, self.line_den], axis=1)  # (20, 4)
        # (20, 16): over rpc_terms, the four cubics (columns by four) and their derivatives by x, y, z (rows of
        # four): computed once, as the inversion evaluates the derivatives thousands of times on few points
        self._cubics_and_derivatives = np.concatenate([coefficients[None], DERIVATIVE @ coefficients]) \
            .transpose(1, 0, 2).reshape(20, 16)

    def ground_to_image(self, lon, lat, h) -> tuple[np.ndarray, np.ndarray]:
        """GDAL (col, row) of ground points (lon, lat deg, h m)."""
        t = rpc_terms((np.asarray(lon) - self.lon_off) / self.lon_scale,
                      (np.asarray(lat) - self.lat_off) / self.lat_scale,
                      (np.asarray(h) - self.height_off) / self.height_scale)
        line = (t @ self.line_num) / (t @ self.line_den) * self.line_scale + self.line_off
        samp = (t @ self.samp_num) / (t @ self.samp_den) * self.samp_scale + self.samp_off
        return samp - self.origin + 0.5, line - self.origin + 0.5

    def ground_to_image_jacobian(self, lon, lat, h) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """GDAL (col (n,), row (n,)) of ground points (lon, lat deg, h m), each a single value or
        (n,), and their analytic derivatives (n, 2, 3): rows col, row; columns px per degree of
        lon and lat, px per m of h. The quotient rule (P'Q - PQ') / Q^2 on the cubics, through the
        offsets and scales; one pass for the value and the derivatives."""
        t = rpc_terms((np.atleast_1d(np.asarray(lon, dtype=float)) - self.lon_off) / self.lon_scale,
                      (np.asarray(lat, dtype=float) - self.lat_off) / self.lat_scale,
                      (np.asarray(h, dtype=float) - self.height_off) / self.height_scale)
        v = (t @ self._cubics_and_derivatives).reshape(-1, 4, 4)  # (n, value and d/dx, d/dy, d/dz, the four cubics)
        p, q = v[:, 0, 0::2], v[:, 0, 1::2]          # (n, 2): samp, line
        dp, dq = v[:, 1:, 0::2].transpose(0, 2, 1), v[:, 1:, 1::2].transpose(0, 2, 1)  # (n, 2, 3)
        ground = np.array([self.lon_scale, self.lat_scale, self.height_scale])
        image = np.array([self.samp_scale, self.line_scale])
        jac = (dp * q[..., None] - p[..., None] * dq) / (q * q)[..., None] * (image[:, None] / ground)
        own = p / q * image + np.array([self.samp_off, self.line_off]) - self.origin + 0.5
        return own[:, 0], own[:, 1], jac

    def image_to_ground(self, col, row, h, tol: float = 1e-10, max_iter: int = 30, converged_only: bool = False):
        """(lon, lat) degrees of GDAL image points at ellipsoidal heights h, by Newton on the direct
        model with its analytic derivatives (:meth:`ground_to_image_jacobian`: one evaluation per
        step), each point until its step is below ``tol`` of the scales (a point whose step is NaN
        stops: NaN). Without convergence: ConvergenceError, or with ``converged_only`` NaN for the
        points that did not converge."""
        col, row, h = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (col, row, h)))
        shape = col.shape
        col, row, h = col.ravel(), row.ravel(), h.ravel()
        lon = np.full(col.shape, self.lon_off)
        lat = np.full(col.shape, self.lat_off)
        active = np.arange(col.size)
        for _ in range(max_iter):
            c0, r0, jac = self.ground_to_image_jacobian(lon[active], lat[active], h[active])
            (a, b), (c, d) = jac[:, 0, :2].T, jac[:, 1, :2].T
            det = a * d - b * c
            dc, dr = col[active] - c0, row[active] - r0
            dlon = (d * dc - b * dr) / det
            dlat = (a * dr - c * dc) / det
            lon[active] += dlon
            lat[active] += dlat
            active = active[(np.abs(dlon) / self.lon_scale >= tol) | (np.abs(dlat) / self.lat_scale >= tol)]
            if active.size == 0:
                return lon.reshape(shape), lat.reshape(shape)
        if converged_only:
            lon[active] = lat[active] = np.nan
            return lon.reshape(shape), lat.reshape(shape)
        raise ConvergenceError("RPC inversion did not converge in %d iterations" % max_iter)


@dataclass
class RationalDirectModel:
    """Rational functions image -> ground (the DIMAP ``Direct_Model``): lon and lat (deg)
    as ratios of 20-term cubics in normalised (x = sample, y = line, z = height), with the
    RPC00B monomial order of :func:`rpc_terms`.

    Offsets/scales: samp, line (model pixels), height (m), lon, lat (deg). ``origin`` is the
    model coordinate of the centre of the upper-left pixel, as in :class:`RpcModel`.
    """
    lon_num: np.ndarray
    lon_den: np.ndarray
    lat_num: np.ndarray
    lat_den: np.ndarray
    samp_off: float
    samp_scale: float
    line_off: float
    line_scale: float
    height_off: float
    height_scale: float
    lon_off: float
    lon_scale: float
    lat_off: float
    lat_scale: float
    origin: float = 0.0

    def __post_init__(self):
        _check_coefficients(self, ("lon_num", "lon_den", "lat_num", "lat_den"), "direct rational coefficient list")

    def image_to_ground(self, col, row, h) -> tuple[np.ndarray, np.ndarray]:
        """(lon, lat) degrees of GDAL image points (col, row) at ellipsoidal heights h (m)."""
        t = rpc_terms((np.asarray(col, dtype=float) + self.origin - 0.5 - self.samp_off) / self.samp_scale,
                      (np.asarray(row, dtype=float) + self.origin - 0.5 - self.line_off) / self.line_scale,
                      (np.asarray(h, dtype=float) - self.height_off) / self.height_scale)
        lon = (t @ self.lon_num) / (t @ self.lon_den) * self.lon_scale + self.lon_off
        lat = (t @ self.lat_num) / (t @ self.lat_den) * self.lat_scale + self.lat_off
        return lon, lat
