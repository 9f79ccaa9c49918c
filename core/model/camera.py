"""Line timing and cameras of a pushbroom scene.

Image coordinates follow GDAL: (col, row) = (x, y) with (0, 0) the upper-left corner of
the upper-left pixel, so pixel centres are at half-integers. A chip's detector index
``d`` is continuous with d = 0 at the centre of its first detector.

Camera frame: x along track (flight direction), y across track (to the right), z toward
the scene. A detector's line of sight in that frame is (ux, uy, 1), where (ux, uy) are
normalised image-plane coordinates (tangents of the along/across-track view angles).
The camera frame is turned into the platform body frame by ``installation`` (3x3,
camera -> body), and the body into ECEF by the attitude.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import MetadataError

DISTORTION_TERMS = ("dxp", "dyp", "df", "k1", "k2", "p1", "p2", "b1", "b2", "b3")
# Correction terms of the camera geometry a bundle adjustment can estimate: per focal-plane chip
# (shifts on the focal plane and rotation, seed 000 eq. 4), per look-angle chip (offsets and
# change across the chip), per focal-plane camera (the focal length and the distortion terms of
# eq. 7; 'df' is the focal-length term itself, so the camera term 'f' replaces it).
CHIP_TERMS = ("dx", "dy", "theta")
LOOK_TERMS = ("ux0", "ux1", "uy0", "uy1")
CAMERA_TERMS = ("f",) + tuple(t for t in DISTORTION_TERMS if t != "df")
# SI units of those terms and of the installation angles (roll, pitch, yaw).
UNITS = {"dx": "m", "dy": "m", "theta": "rad", "ux0": "rad", "ux1": "rad", "uy0": "rad", "uy1": "rad",
         "f": "m", "dxp": "m", "dyp": "m", "k1": "1/m2", "k2": "1/m4", "p1": "1/m", "p2": "1/m", "b1": "",
         "b2": "", "b3": "", "roll": "rad", "pitch": "rad", "yaw": "rad"}


@dataclass
class LineTiming:
    """Acquisition time of image rows.

    Either constant: ``t = t0 + (row - 0.5) * period`` (t0 is the time of the first
    row's centre), or a table of (line, time) pairs with line = row - 0.5 (line index
    of pixel centres), linearly interpolated and extrapolated with the end segments.
    A table's lines increase; its times increase, or decrease in a reverse scan (the
    sensor sweeps the image from its last row to its first: Maxar's "Reverse" scan
    direction), strictly either way.
    """
    t0: float = 0.0
    period: float = 0.0
    lines: np.ndarray | None = None
    times: np.ndarray | None = None

    def __post_init__(self):
        if self.lines is not None:
            self.lines = np.asarray(self.lines, dtype=float)
            self.times = np.asarray(self.times, dtype=float)
            steps = np.diff(self.times) * (1.0 if self.times[-1] >= self.times[0] else -1.0)
            if self.lines.size < 2 or self.lines.size != self.times.size or np.any(np.diff(self.lines) <= 0) \
                    or np.any(steps <= 0):
                raise MetadataError("line timing table needs >= 2 (line, time) pairs, lines increasing and times "
                                    "strictly increasing (or strictly decreasing: a reverse scan)")
        elif not (np.isfinite(self.period) and self.period > 0):
            raise MetadataError(f"line period must be positive (got {self.period})")

    def time(self, row) -> np.ndarray:
        """Time (s from epoch) of row coordinate(s) ``row`` (GDAL y)."""
        line = np.asarray(row, dtype=float) - 0.5
        if self.lines is None:
            return self.t0 + line * self.period
        return _interp_extrapolate(line, self.lines, self.times)

    def row(self, t) -> np.ndarray:
        """Row coordinate (GDAL y) acquired at time(s) t."""
        t = np.asarray(t, dtype=float)
        if self.lines is None:
            return (t - self.t0) / self.period + 0.5
        if self.reverse:
            return _interp_extrapolate(t, self.times[::-1], self.lines[::-1]) + 0.5
        return _interp_extrapolate(t, self.times, self.lines) + 0.5

    @property
    def reverse(self) -> bool:
        """Whether the times decrease with the row (a reverse scan)."""
        return self.lines is not None and bool(self.times[-1] < self.times[0])

    def mean_period(self) -> float:
        """Mean line period (s): negative in a reverse scan."""
        if self.lines is None:
            return self.period
        return float((self.times[-1] - self.times[0]) / (self.lines[-1] - self.lines[0]))

    def to_dict(self) -> dict:
        if self.lines is None:
            return {"t0": self.t0, "period": self.period}
        return {"lines": self.lines.tolist(), "times": self.times.tolist()}

    @classmethod
    def from_dict(cls, d: dict) -> "LineTiming":
        if "lines" in d:
            return cls(lines=np.array(d["lines"]), times=np.array(d["times"]))
        return cls(float(d["t0"]), float(d["period"]))


def _interp_extrapolate(x, xp: np.ndarray, fp: np.ndarray) -> np.ndarray:
    """np.interp with linear extrapolation from the end segments instead of clamping."""
    x = np.asarray(x, dtype=float)
    y = np.interp(x, xp, fp)
    lo, hi = x < xp[0], x > xp[-1]
    y = np.where(lo, fp[0] + (x - xp[0]) * (fp[1] - fp[0]) / (xp[1] - xp[0]), y)
    return np.where(hi, fp[-1] + (x - xp[-1]) * (fp[-1] - fp[-2]) / (xp[-1] - xp[-2]), y)


@dataclass
class Chip:
    """One linear detector array (a CCD chip, or the whole line of a look-angle camera).

    col_offset: image column (GDAL x) of the left edge of detector 0 in the delivered image.
    n_pixels: detectors in the chip. time_offset: s added to the row time for this chip
    (along-track displaced chips of a staggered array image a given row at another time).

    Geometry is one of:
      - focal plane ("focal_plane"): detector d sits at x = x0 + d*pitch*sin(theta),
        y = y0 + d*pitch*cos(theta) (metres, seed 000 eq. 4 with theta the chip rotation);
      - look angles ("look_angle"): ux(d), uy(d) given as polynomials (ascending coefficients
        in d) or as per-detector tables (one value per detector, linearly interpolated).
    """
    col_offset: float
    n_pixels: int
    kind: str = "focal_plane"
    time_offset: float = 0.0
    x0: float = 0.0
    y0: float = 0.0
    pitch: float = 0.0
    theta: float = 0.0
    ux_poly: np.ndarray | None = None
    uy_poly: np.ndarray | None = None
    ux_table: np.ndarray | None = None
    uy_table: np.ndarray | None = None
    name: str = ""

    def __post_init__(self):
        for key in ("ux_poly", "uy_poly", "ux_table", "uy_table"):
            v = getattr(self, key)
            if v is not None:
                setattr(self, key, np.asarray(v, dtype=float))
        if self.kind == "focal_plane":
            if not self.pitch > 0:
                raise MetadataError(f"chip {self.name!r}: detector pitch must be positive")
        elif self.kind == "look_angle":
            if (self.ux_poly is None or self.uy_poly is None) and (self.ux_table is None or self.uy_table is None):
                raise MetadataError(f"chip {self.name!r}: look-angle chip needs ux/uy polynomials or tables")
        else:
            raise MetadataError(f"chip {self.name!r}: unknown chip kind {self.kind!r}")

    def focal_plane_xy(self, d) -> tuple[np.ndarray, np.ndarray]:
        """Focal-plane coordinates (x, y) in metres of detector index d (focal-plane chips)."""
        d = np.asarray(d, dtype=float)
        return (self.x0 + d * self.pitch * np.sin(self.theta),
                self.y0 + d * self.pitch * np.cos(self.theta))

    def look(self, d) -> tuple[np.ndarray, np.ndarray]:
        """(ux, uy) of detector index d for look-angle chips."""
        d = np.asarray(d, dtype=float)
        if self.ux_table is not None:
            idx = np.arange(self.ux_table.size, dtype=float)
            return _interp_extrapolate(d, idx, self.ux_table), _interp_extrapolate(d, idx, self.uy_table)
        return np.polynomial.polynomial.polyval(d, self.ux_poly), np.polynomial.polynomial.polyval(d, self.uy_poly)

    def to_dict(self) -> dict:
        out = {"name": self.name, "kind": self.kind, "col_offset": self.col_offset, "n_pixels": self.n_pixels,
               "time_offset": self.time_offset}
        if self.kind == "focal_plane":
            out.update(x0=self.x0, y0=self.y0, pitch=self.pitch, theta=self.theta)
        for key in ("ux_poly", "uy_poly", "ux_table", "uy_table"):
            v = getattr(self, key)
            if v is not None:
                out[key] = v.tolist()
        return out

    @classmethod
    def from_dict(cls, d: dict) -> "Chip":
        return cls(**{k: v for k, v in d.items() if k in cls.__dataclass_fields__})


@dataclass
class Camera:
    """A pushbroom camera: chips on one focal plane (or look-angle lines), timing and mounting.

    focal_length (m) and the 10 distortion terms of seed 001 eq. 7 (dxp, dyp, df in metres,
    k1 (1/m^2), k2 (1/m^4), p1, p2 (1/m), b1, b2, b3 (unitless)) apply to focal-plane chips;
    principal_point (xp, yp) in metres. installation: camera -> body rotation (3, 3).
    cols, rows: size of the delivered image.
    """
    name: str
    cols: int
    rows: int
    timing: LineTiming
    chips: list[Chip]
    focal_length: float = 1.0
    principal_point: tuple[float, float] = (0.0, 0.0)
    distortion: dict = field(default_factory=dict)
    installation: np.ndarray = field(default_factory=lambda: np.eye(3))

    def __post_init__(self):
        self.installation = np.asarray(self.installation, dtype=float).reshape(3, 3)
        self.chips = sorted(self.chips, key=lambda c: c.col_offset)
        if not self.chips:
            raise MetadataError(f"camera {self.name!r} has no detector chips")
        unknown = set(self.distortion) - set(DISTORTION_TERMS)
        if unknown:
            raise MetadataError(f"camera {self.name!r}: unknown distortion terms {sorted(unknown)}")
        self._starts = np.array([c.col_offset for c in self.chips])
        self._time_offsets = np.array([c.time_offset for c in self.chips])

    # --- columns and chips -------------------------------------------------------------
    def in_image(self, col, row) -> np.ndarray:
        """Mask of image points (GDAL px) inside this camera's image (:func:`inside_image`)."""
        return inside_image(col, row, self.cols, self.rows)

    def chip_index(self, col) -> np.ndarray:
        """Index of the chip that delivers image column(s) ``col`` (the later chip wins overlaps)."""
        return np.clip(np.searchsorted(self._starts, np.asarray(col, dtype=float), side="right") - 1,
                       0, len(self.chips) - 1)

    def chip_range(self, k: int) -> tuple[float, float]:
        """Columns [start, end) that chip k delivers in the image."""
        chip = self.chips[k]
        end = self.chips[k + 1].col_offset if k + 1 < len(self.chips) else chip.col_offset + chip.n_pixels
        return chip.col_offset, min(end, chip.col_offset + chip.n_pixels)

    def time_offset(self, chip_idx) -> np.ndarray:
        return self._time_offsets[chip_idx]

    @property
    def chip_time_offsets(self) -> np.ndarray:
        """(chips,) s: each chip's time offset (:meth:`time_offset`)."""
        return self._time_offsets

    # --- lines of sight ----------------------------------------------------------------
    def image_plane(self, col, chip_idx=None) -> tuple[np.ndarray, np.ndarray]:
        """Normalised image-plane coordinates (ux, uy) of column(s) col, on the given chip(s)."""
        col = np.atleast_1d(np.asarray(col, dtype=float))
        k = self.chip_index(col) if chip_idx is None else np.broadcast_to(chip_idx, col.shape)
        ux = np.empty_like(col)
        uy = np.empty_like(col)
        for i, chip in enumerate(self.chips):
            m = k == i
            if not m.any():
                continue
            d = col[m] - chip.col_offset - 0.5
            if chip.kind == "look_angle":
                ux[m], uy[m] = chip.look(d)
            else:
                ux[m], uy[m] = self._focal_plane_to_normalised(*chip.focal_plane_xy(d))
        return ux, uy

    def _focal_plane_to_normalised(self, x, y) -> tuple[np.ndarray, np.ndarray]:
        """Apply principal point, focal length and seed-001 eq. 7 distortion to (x, y) metres."""
        xb = x - self.principal_point[0]
        yb = y - self.principal_point[1]
        if self.distortion:
            xb, yb = distorted(xb, yb, self.distortion, self.focal_length)
        return xb / self.focal_length, yb / self.focal_length

    def los_camera(self, col, chip_idx=None) -> np.ndarray:
        """Unnormalised lines of sight (n, 3) in the camera frame."""
        ux, uy = self.image_plane(col, chip_idx)
        return np.stack([ux, uy, np.ones_like(ux)], axis=-1)

    def column_table(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """(columns, uy) sampled across chip k, for first guesses of the inverse mapping."""
        c0, c1 = self.chips[k].col_offset, self.chips[k].col_offset + self.chips[k].n_pixels
        cols = np.linspace(c0, c1, min(self.chips[k].n_pixels, 256) + 1)
        return cols, self.image_plane(cols, np.full(cols.shape, k))[1]

    def to_dict(self) -> dict:
        return {"name": self.name, "cols": self.cols, "rows": self.rows, "timing": self.timing.to_dict(),
                "chips": [c.to_dict() for c in self.chips], "focal_length": self.focal_length,
                "principal_point": list(self.principal_point), "distortion": dict(self.distortion),
                "installation": self.installation.tolist()}

    @classmethod
    def from_dict(cls, d: dict) -> "Camera":
        return cls(name=d["name"], cols=int(d["cols"]), rows=int(d["rows"]),
                   timing=LineTiming.from_dict(d["timing"]), chips=[Chip.from_dict(c) for c in d["chips"]],
                   focal_length=float(d.get("focal_length", 1.0)),
                   principal_point=tuple(d.get("principal_point", (0.0, 0.0))),
                   distortion=dict(d.get("distortion", {})),
                   installation=np.array(d.get("installation", np.eye(3))))


def inside_image(col, row, cols, rows) -> np.ndarray:
    """Mask of image points (col, row), GDAL px, that lie in an image of ``cols`` x ``rows``
    pixels: 0 <= col <= cols and 0 <= row <= rows. In GDAL's convention the image covers the
    rectangle from the outer corner (0, 0) of its first pixel to the outer corner (cols, rows)
    of its last one; the bounds are closed, so a point on the image's edge (a pixel corner or
    side) is inside. False for NaN. ``cols``, ``rows``: numbers, or arrays broadcasting with
    col and row (one image size per point)."""
    col, row = np.asarray(col, dtype=float), np.asarray(row, dtype=float)
    with np.errstate(invalid="ignore"):
        return (col >= 0) & (col <= cols) & (row >= 0) & (row <= rows)


def distorted(xb, yb, terms, focal_length: float) -> tuple[np.ndarray, np.ndarray]:
    """Focal-plane coordinates (m) moved by the lens distortion of Zhang et al. 2015 eq. 7 (seed
    001): (xb + dx, yb + dy) for (xb, yb), metres from the principal point.

    ``terms``: mapping of DISTORTION_TERMS to values (missing ones are 0): dxp, dyp, df (m),
    k1 (1/m^2), k2 (1/m^4), p1, p2 (1/m), b1, b2, b3; the focal-length term acts as
    -df / focal_length times (xb, yb), with ``focal_length`` (m) the nominal one."""
    g = terms.get
    r2 = xb * xb + yb * yb
    radial = g("k1", 0.0) * r2 + g("k2", 0.0) * r2 * r2
    p1, p2 = g("p1", 0.0), g("p2", 0.0)
    dx = (g("dxp", 0.0) - g("df", 0.0) / focal_length * xb + radial * xb + p1 * (r2 + 2 * xb * xb)
          + 2 * p2 * xb * yb + g("b1", 0.0) * xb + g("b2", 0.0) * yb)
    dy = (g("dyp", 0.0) - g("df", 0.0) / focal_length * yb + radial * yb + 2 * p1 * xb * yb
          + p2 * (r2 + 2 * yb * yb) + g("b3", 0.0) * yb)
    return xb + dx, yb + dy


def corrected_image_plane(cam: Camera, chip: Chip, terms, cam_terms, d, with_jacobian: bool = False):
    """Normalised (ux, uy) (n, 2) of detectors ``d`` (n,) of a focal-plane chip under correction
    terms: ``terms`` (dx, dy, theta) of the chip (CHIP_TERMS: m, m, rad) and ``cam_terms`` (10,)
    of the camera in CAMERA_TERMS order ('f' the change of the focal length, the others added to
    the camera's distortion terms), seed 000 eq. 4 and seed 001 eq. 7. With ``with_jacobian``,
    also the derivatives (n, 2, 3) by the chip terms and (n, 2, 10) by the camera terms, else
    None for both."""
    th = chip.theta + terms[2]
    x = chip.x0 + terms[0] + d * chip.pitch * np.sin(th)
    y = chip.y0 + terms[1] + d * chip.pitch * np.cos(th)
    base = cam.distortion
    f = cam.focal_length + cam_terms[0]
    # the corrected distortion terms; 'df' stays the camera's own (its correction is f)
    current = {t: base.get(t, 0.0) + v for t, v in zip(CAMERA_TERMS[1:], cam_terms[1:])}
    current["df"] = base.get("df", 0.0)
    xb = x - cam.principal_point[0]
    yb = y - cam.principal_point[1]
    X, Y = distorted(xb, yb, current, cam.focal_length)
    u = np.stack([X / f, Y / f], axis=1)
    if not with_jacobian:
        return u, None, None
    k1, k2, p1, p2, b1, b2, b3 = (current[t] for t in ("k1", "k2", "p1", "p2", "b1", "b2", "b3"))
    r2 = xb * xb + yb * yb
    radial = k1 * r2 + k2 * r2 * r2
    dr = 2.0 * (k1 + 2.0 * k2 * r2)  # d radial / d(xb^2 + yb^2) * 2
    c_df = current["df"] / cam.focal_length
    dX_dxb = 1 - c_df + radial + xb * xb * dr + 6 * p1 * xb + 2 * p2 * yb + b1
    dX_dyb = xb * yb * dr + 2 * p1 * yb + 2 * p2 * xb + b2
    dY_dxb = yb * xb * dr + 2 * p1 * yb + 2 * p2 * xb
    dY_dyb = 1 - c_df + radial + yb * yb * dr + 2 * p1 * xb + 6 * p2 * yb + b3
    dxb_dth, dyb_dth = d * chip.pitch * np.cos(th), -d * chip.pitch * np.sin(th)
    n = d.size
    jc = np.empty((n, 2, 3))
    jc[:, 0, 0], jc[:, 1, 0] = dX_dxb / f, dY_dxb / f
    jc[:, 0, 1], jc[:, 1, 1] = dX_dyb / f, dY_dyb / f
    jc[:, 0, 2] = (dX_dxb * dxb_dth + dX_dyb * dyb_dth) / f
    jc[:, 1, 2] = (dY_dxb * dxb_dth + dY_dyb * dyb_dth) / f
    zero, one = np.zeros(n), np.ones(n)
    jk = np.stack([
        np.stack([-X / f ** 2, -Y / f ** 2], axis=1),                            # f
        np.stack([one / f, zero], axis=1), np.stack([zero, one / f], axis=1),      # dxp, dyp
        np.stack([r2 * xb, r2 * yb], axis=1) / f,                                  # k1
        np.stack([r2 * r2 * xb, r2 * r2 * yb], axis=1) / f,                        # k2
        np.stack([r2 + 2 * xb * xb, 2 * xb * yb], axis=1) / f,                     # p1
        np.stack([2 * xb * yb, r2 + 2 * yb * yb], axis=1) / f,                     # p2
        np.stack([xb, zero], axis=1) / f, np.stack([yb, zero], axis=1) / f,        # b1, b2
        np.stack([zero, yb], axis=1) / f,                                          # b3
    ], axis=2)
    return u, jc, jk
