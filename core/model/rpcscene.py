"""RPC-only scenes: an image and its rational polynomial model (RPC00B), as a scene.

:class:`RpcScene` offers the interface the algorithms use on a rigorous
:class:`core.model.sensor.SceneModel` (cameras, camera_index, height_range, ground_to_image,
image_to_ground, image_to_ground_dem, info), so every algorithm that takes a scene takes one.

Frames and units as in core.model.sensor: ground points ECEF metres (n, 3), image points GDAL
(col, row) floats (pixel centres at +0.5), heights ellipsoidal metres.

ground -> image is the RPC followed by an image-space correction (Grodecki & Dial 2003):
    col' = col + a0 + a1 * col + a2 * row,    row' = row + b0 + b1 * col + b2 * row
with (col, row) the RPC's own image position (zero correction: the vendor model). image ->
ground inverts the correction (a 2 x 2 linear system), then the RPC by Newton at a height, and
on a DEM by iterating the height under the point.

Files holding an RPC scene (GDAL's RPC metadata of an image, ``_RPC.TXT``, ``.RPB``, a DIMAP
``RPC_*.XML``) are read by :mod:`core.formats.rpcfiles`; the RPC scene JSON
(``"model": "rpc"``) by :mod:`core.formats.scene_json`.
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError, MetadataError
from ..geodesy import ecef_to_geodetic, geodetic_by_ecef, geodetic_to_ecef
from ..validation import ground_points, per_point
from .camera import inside_image
from .rpc import RpcModel
from .sensor import as_points

log = logging.getLogger(__name__)

MODEL = "rpc"
# An image is its RPC's image when its border, at the bottom, middle and top of the RPC's height range, maps
# onto the ground within the RPC's validity (latitude and longitude offset +- scale) widened by this share of
# the scales. Real products' corners at their height range reach 1.00 to 1.08 of the scales (WorldView-3
# the widest); an image twice the size of the one its RPC describes reaches 3 and more.
DOMAIN_MARGIN = 0.25
# ...and the RPC maps that ground back onto the image points to this (px): an RPC that cannot be inverted
# over the image (a vanishing denominator, a fold) is no camera of it.
ROUND_TRIP_PX = 0.01
# Normalised ground coordinates beyond which the cubic ratios are extrapolated too far to mean
# anything (|x| <= 1 is the fitted domain): no image position there.
MAX_NORMALISED = 2.0


@dataclass
class RpcChip:
    """The single 'chip' of an RPC camera: the image is one continuous array."""
    col_offset: float = 0.0
    name: str = "image"


@dataclass
class RpcCamera:
    """The image an RPC describes: name and size (px). ``size_source``: '' when the size is the
    image's, else how it was assumed (no image found with the RPC: where it was looked for and
    what the size was taken from), for the refusal of an image of another size (:func:`size_note`)."""
    name: str
    cols: int
    rows: int
    chips: list = field(default_factory=lambda: [RpcChip()])
    size_source: str = ""

    def chip_index(self, col) -> np.ndarray:
        return np.zeros(np.shape(col), dtype=np.int64)

    def chip_range(self, k: int) -> tuple[float, float]:
        return 0.0, float(self.cols)

    def in_image(self, col, row) -> np.ndarray:
        """Mask of image points (GDAL px) inside the image (:func:`core.model.camera.inside_image`)."""
        return inside_image(col, row, self.cols, self.rows)


@dataclass
class RpcScene:
    """One image with its RPC and an image-space affine correction.

    correction: (2, 3) array [[a0, a1, a2], [b0, b1, b2]] (px, px/px), see the module docstring.
    """
    rpc: RpcModel
    camera: RpcCamera
    correction: np.ndarray = field(default_factory=lambda: np.zeros((2, 3)))
    info: dict = field(default_factory=dict)

    def __post_init__(self):
        self.correction = np.asarray(self.correction, dtype=float).reshape(2, 3)
        self.info.setdefault("model", MODEL)

    # --- the interface of core.model.sensor.SceneModel -------------------------------------
    @property
    def cameras(self) -> list[RpcCamera]:
        return [self.camera]

    def camera_index(self, camera: int | str) -> int:
        """0 for the one camera (its name or index); InputError otherwise."""
        if camera in (0, self.camera.name) or (not isinstance(camera, str) and int(camera) == 0):
            return 0
        raise InputError(f"camera {camera!r} is not in this RPC scene (its one camera: {self.camera.name})")

    @property
    def height_range(self) -> tuple[float, float]:
        """The RPC's height validity range (m, ellipsoidal): offset +- scale."""
        return (self.rpc.height_off - abs(self.rpc.height_scale), self.rpc.height_off + abs(self.rpc.height_scale))

    def prepare(self, camera: int | None = None) -> None:
        """Nothing to tabulate (kept for the SceneModel interface)."""

    def ground_to_image_near(self, xyz, camera: int, col, row) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`ground_to_image` (the SceneModel interface's first guesses (col, row) are not
        needed: an RPC images ground points directly)."""
        return self.ground_to_image(xyz, camera)

    def ground_to_image_on_chip(self, xyz, camera: int, chip, col, row) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`ground_to_image` (the image is one chip; no first guesses are needed)."""
        return self.ground_to_image(xyz, camera)

    def platform_of(self, camera: int) -> None:
        """None: an RPC image has no platform (no trajectory to correct)."""
        return None

    def line_of_sight(self, col, row, camera: int = 0):
        """(t (n,) s, S (n,3) ECEF m, v (n,3) m/s, u (n,3) unit directions ECEF) as
        :meth:`core.model.sensor.SceneModel.line_of_sight`: t and v are 0, S the ground the image
        sees at the top of its RPC's height range and u the direction down to the ground it sees at
        the bottom (beyond them the RPC is extrapolated): its ray as far as the RPC describes one."""
        col, row = as_points(col, row)
        lo, hi = self.height_range
        top = self.image_to_ground(col, row, hi, camera)
        down = self.image_to_ground(col, row, lo, camera) - top
        return np.zeros(col.size), top, np.zeros_like(top), down / np.linalg.norm(down, axis=1)[:, None]

    def ground_to_image(self, xyz, camera: int = 0, **_) -> tuple[np.ndarray, np.ndarray]:
        """GDAL (col (n,), row (n,)) of ECEF points (n, 3), or of one point (3,) (other shapes: InputError
        naming ``xyz``, core.validation.ground_points): the RPC and the correction. NaN far
        outside the RPC's ground domain (normalised |lon| or |lat| > MAX_NORMALISED) and where its
        denominator vanishes."""
        self.camera_index(camera)
        lon, lat, h = ecef_to_geodetic(ground_points(xyz))
        return self.ground_to_image_geodetic(lon, lat, h)

    def ground_to_image_geodetic(self, lon, lat, h, camera: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """ground_to_image for (lon, lat) degrees and ellipsoidal heights (m), each a single value or (n,)
        (core.validation.per_point)."""
        lon, lat, h = (np.asarray(a, dtype=float) for a in per_point(lon=lon, lat=lat, h=h))
        self.warn_heights(h)
        lon = self.wrapped(lon)
        with np.errstate(divide="ignore", invalid="ignore"):
            col, row = self.rpc.ground_to_image(lon, lat, h)
        col, row = self.correct(col, row)
        bad = self.far(lon, lat) | ~np.isfinite(col) | ~np.isfinite(row)
        return np.where(bad, np.nan, col), np.where(bad, np.nan, row)

    def ground_to_image_jacobian(self, xyz) -> tuple[np.ndarray, ...]:
        """(col, row, the RPC's own col, row (n,) px, derivatives (n, 2, 3) of (col, row) by the
        ECEF coordinates, px/m) of ECEF points (n, 3): :meth:`ground_to_image` with the analytic
        derivatives of the RPC (:meth:`core.model.rpc.RpcModel.ground_to_image_jacobian`) through
        geodetic coordinates and the correction. NaN where ground_to_image has none."""
        self.camera_index(0)
        lon, lat, h = ecef_to_geodetic(ground_points(xyz))
        self.warn_heights(h)
        lon = self.wrapped(lon)
        with np.errstate(divide="ignore", invalid="ignore"):
            own_col, own_row, jac = self.rpc.ground_to_image_jacobian(lon, lat, h)
        col, row = self.correct(own_col, own_row)
        (_, a1, a2), (_, b1, b2) = self.correction
        jac = np.array([[1.0 + a1, a2], [b1, 1.0 + b2]]) @ jac @ geodetic_by_ecef(lon, lat, h)
        bad = self.far(lon, lat) | ~np.isfinite(col) | ~np.isfinite(row) | ~np.all(np.isfinite(jac), axis=(1, 2))
        jac[bad] = np.nan
        return tuple(np.where(bad, np.nan, v) for v in (col, row, own_col, own_row)) + (jac,)

    def wrapped(self, lon) -> np.ndarray:
        """Longitudes (deg) within 180 degrees of the RPC's longitude offset."""
        return self.rpc.lon_off + (lon - self.rpc.lon_off + 180.0) % 360.0 - 180.0

    def far(self, lon, lat) -> np.ndarray:
        """Mask of ground points (deg) beyond MAX_NORMALISED of the RPC's ground domain."""
        r = self.rpc
        return (np.abs((lon - r.lon_off) / r.lon_scale) > MAX_NORMALISED) | \
            (np.abs((lat - r.lat_off) / r.lat_scale) > MAX_NORMALISED)

    def image_to_ground(self, col, row, height, camera: int = 0) -> np.ndarray:
        """ECEF points (n, 3) seen at image points on the surface of ellipsoidal height
        ``height`` (m): each a single value or (n,) (core.model.sensor.as_points); NaN where the RPC's
        inversion does not converge."""
        self.camera_index(camera)
        col, row, height = as_points(col, row, height=height)
        self.warn_heights(height)
        lon, lat = self._lonlat(col, row, height)
        return geodetic_to_ecef(lon, lat, height)

    def image_to_ground_dem(self, col, row, dem, camera: int = 0, tol: float = 1e-3,
                            max_iter: int = 40) -> np.ndarray:
        """ECEF points (n, 3) where image rays meet a DEM (``height(lon, lat)``, ellipsoidal m):
        the height under the point iterated (halved steps after ten, for steep terrain seen
        obliquely, where the plain iteration oscillates). NaN where a ray leaves the DEM or
        does not converge."""
        self.camera_index(camera)
        col, row = as_points(col, row)
        h = np.full(col.shape, float(np.mean(dem.height_range)))
        lon = np.full(col.shape, np.nan)
        lat = np.full(col.shape, np.nan)
        active = np.ones(col.shape, bool)
        for it in range(max_iter):
            idx = np.nonzero(active)[0]
            if idx.size == 0:
                break
            lon[idx], lat[idx] = self._lonlat(col[idx], row[idx], h[idx])
            under = dem.height(lon[idx], lat[idx])
            step = under - h[idx]
            lost = ~np.isfinite(step)
            h[idx] = np.where(lost, np.nan, h[idx] + (step if it < 10 else 0.5 * step))
            active[idx[lost | (np.abs(step) < tol)]] = False
        h[active] = np.nan
        ok = np.isfinite(h)
        if (~ok).any():
            log.warning("%d image points do not meet the DEM (off its edge, on its nodata, or no convergence)",
                        int((~ok).sum()))
        self.warn_heights(h[ok])
        out = np.full((col.size, 3), np.nan)
        out[ok] = geodetic_to_ecef(lon[ok], lat[ok], h[ok])
        return out

    # --- correction and checks -------------------------------------------------------------
    # --- what it answers of its kind (core.model.kinds) ---------------------------------------
    def rigorous_part(self) -> None:
        """None: an RPC scene holds no rigorous scene."""
        return None

    def rpc_images(self) -> list["RpcScene"]:
        """The scene itself: its one image."""
        return [self]

    def block_members(self) -> list[str]:
        """[]: a scene on its own (a block of one)."""
        return []

    def answer(self, question):
        """``question.rpc(self)``."""
        return question.rpc(self)

    def correct(self, col, row) -> tuple[np.ndarray, np.ndarray]:
        """Corrected image positions of the RPC's own (col, row)."""
        a, b = self.correction
        return col + a[0] + a[1] * col + a[2] * row, row + b[0] + b[1] * col + b[2] * row

    def uncorrect(self, col, row) -> tuple[np.ndarray, np.ndarray]:
        """The RPC's own (col, row) of corrected image positions (the correction inverted)."""
        (a0, a1, a2), (b0, b1, b2) = self.correction
        det = (1.0 + a1) * (1.0 + b2) - a2 * b1  # the 2 x 2 inverse in closed form (LAPACK's costs more per call)
        if det == 0.0:
            raise np.linalg.LinAlgError("Singular matrix")
        dc, dr = col - a0, row - b0
        return ((1.0 + b2) * dc - a2 * dr) / det, ((1.0 + a1) * dr - b1 * dc) / det

    def _lonlat(self, col, row, h) -> tuple[np.ndarray, np.ndarray]:
        c, r = self.uncorrect(col, row)
        return self.rpc.image_to_ground(c, r, h, converged_only=True)

    def warn_heights(self, h) -> int:
        """Log a warning for heights (m) outside the RPC's height range; their count."""
        lo, hi = self.height_range
        h = np.asarray(h, dtype=float)
        with np.errstate(invalid="ignore"):
            out = int(np.sum((h < lo) | (h > hi)))
        if out:
            log.warning("%d of %d heights are outside the RPC's height range %.0f to %.0f m: the RPC is "
                        "extrapolated there", out, h.size, lo, hi)
        return out

    def check_surface(self, height_range: tuple[float, float], what: str) -> str | None:
        """A surface's (lowest, highest) heights against the RPC's height range: InputError naming
        ``what`` when they do not overlap it at all; a warning text when part lies outside."""
        lo, hi = self.height_range
        s_lo, s_hi = (float(v) for v in height_range)
        if s_hi < lo or s_lo > hi:
            raise InputError(f"{what}: heights {s_lo:.0f} to {s_hi:.0f} m lie outside the RPC's height range "
                             f"{lo:.0f} to {hi:.0f} m (ellipsoidal): is it the scene's terrain, with ellipsoidal "
                             f"heights (see DEM_DATUM)?")
        if s_lo < lo or s_hi > hi:
            return (f"{what}: heights {s_lo:.0f} to {s_hi:.0f} m extend past the RPC's height range {lo:.0f} to "
                    f"{hi:.0f} m; the RPC is extrapolated there")
        return None


# --- the image an RPC describes --------------------------------------------------------------
def image_border(cols: int, rows: int) -> tuple[list[str], np.ndarray, np.ndarray]:
    """The names and GDAL (col (9,), row (9,)) of an image's four corners, the middles of its four edges
    and its centre."""
    names = ["upper-left corner", "upper-right corner", "lower-left corner", "lower-right corner",
             "top edge's middle", "bottom edge's middle", "left edge's middle", "right edge's middle", "centre"]
    col = np.array([0, cols, 0, cols, cols / 2, cols / 2, 0, cols, cols / 2], dtype=float)
    row = np.array([0, 0, rows, rows, 0, rows, rows / 2, rows / 2, rows / 2], dtype=float)
    return names, col, row


def check_image_domain(rpc: RpcModel, cols: int, rows: int, source: str) -> None:
    """MetadataError naming ``source`` when an image of cols x rows px cannot be the one the RPC describes.

    Checked is the RPC's domain, not its offsets (a crop may keep the full product's LINE_OFF/SAMP_OFF with
    its origin folded into the numerators, or have them moved; both are accepted): the image's corners, edge
    middles and centre, at the bottom, middle and top of the RPC's height range, must map onto the ground
    within the RPC's latitude/longitude validity (offset +- scale, widened by DOMAIN_MARGIN of the scale),
    and that ground back onto the same image points (within ROUND_TRIP_PX). The message names the first
    point that fails, where it landed and the validity box."""
    if cols <= 0 or rows <= 0:
        raise MetadataError(f"{source}: the image has {cols} x {rows} px; an image has at least one pixel")
    names, col, row = image_border(cols, rows)
    lo, hi = rpc.height_off - abs(rpc.height_scale), rpc.height_off + abs(rpc.height_scale)
    h = np.repeat([lo, rpc.height_off, hi], col.size)
    col, row = np.tile(col, 3), np.tile(row, 3)
    with np.errstate(all="ignore"):
        lon, lat = rpc.image_to_ground(col, row, h, converged_only=True)
        back_col, back_row = rpc.ground_to_image(lon, lat, h)
        reach = np.maximum(np.abs((lon - rpc.lon_off) / rpc.lon_scale), np.abs((lat - rpc.lat_off) / rpc.lat_scale))
        miss = np.hypot(back_col - col, back_row - row)
    lost = ~np.isfinite(reach) | ~np.isfinite(miss)
    outside = ~lost & (reach > 1.0 + DOMAIN_MARGIN)
    unclosed = ~lost & ~outside & (miss > ROUND_TRIP_PX)
    bad = np.nonzero(lost | outside | unclosed)[0]
    if bad.size == 0:
        return
    k = bad[0]
    where = f"its {names[k % len(names)]} ({col[k]:g}, {row[k]:g}) at {h[k]:.0f} m"
    if lost[k]:
        what = "does not map onto the ground through the RPC (its inversion does not converge there)"
    elif outside[k]:
        what = (f"lands at latitude {lat[k]:.5f}, longitude {lon[k]:.5f}, {reach[k]:.2f} times the RPC's ground "
                "scale from its centre")
    else:
        what = f"maps onto ground that the RPC maps back {miss[k]:.3g} px away (more than {ROUND_TRIP_PX} px)"
    box = (f"latitude {rpc.lat_off - abs(rpc.lat_scale):.5f} to {rpc.lat_off + abs(rpc.lat_scale):.5f}, longitude "
           f"{rpc.lon_off - abs(rpc.lon_scale):.5f} to {rpc.lon_off + abs(rpc.lon_scale):.5f}, heights {lo:.0f} to "
           f"{hi:.0f} m")
    raise MetadataError(f"{source}: the image ({cols} x {rows} px) cannot be the one its RPC describes: {where} "
                        f"{what}; the RPC is valid over {box} (accepted up to {1.0 + DOMAIN_MARGIN:g} times its "
                        "scales). Is it the image this RPC belongs to?")


def size_note(camera) -> str:
    """For the refusal of an image whose size is not the camera's: '' when the camera's size is its
    image's (every rigorous camera, an RPC camera read with its image), else a clause saying that
    the size was assumed, from what, and where the image was looked for."""
    source = getattr(camera, "size_source", "")
    return f" (the scene's size {camera.cols} x {camera.rows} px was assumed: {source})" if source else ""


def size_from_rpc(rpc: RpcModel) -> tuple[int, int]:
    """(cols, rows) of the image whose pixels the RPC's sample/line range spans."""
    return (int(math.floor(rpc.samp_off - rpc.origin + 1.0 + abs(rpc.samp_scale))),
            int(math.floor(rpc.line_off - rpc.origin + 1.0 + abs(rpc.line_scale))))
