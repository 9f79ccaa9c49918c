"""RPC-only scenes: an image and its rational polynomial model (RPC00B), as a scene.

:class:`RpcScene` offers the interface the algorithms use on a rigorous
:class:`core.sensor.SceneModel` (cameras, camera_index, height_range, ground_to_image,
image_to_ground, image_to_ground_dem, info), so every algorithm that takes a scene takes one.

Frames and units as in core.sensor: ground points ECEF metres (n, 3), image points GDAL
(col, row) floats (pixel centres at +0.5), heights ellipsoidal metres.

ground -> image is the RPC followed by an image-space correction (Grodecki & Dial 2003):
    col' = col + a0 + a1 * col + a2 * row,    row' = row + b0 + b1 * col + b2 * row
with (col, row) the RPC's own image position (zero correction: the vendor model). image ->
ground inverts the correction (a 2 x 2 linear system), then the RPC by Newton at a height, and
on a DEM by iterating the height under the point.

Sources (:func:`read_rpc_source`): GDAL's RPC metadata of an image (tags, ``_RPC.TXT`` or
``.RPB`` beside it), a ``_RPC.TXT`` or ``.RPB`` file alone, a DIMAP ``RPC_*.XML``, or the
scene JSON written by :func:`RpcScene.to_dict` (``"model": "rpc"``).
"""
from __future__ import annotations

import logging
import math
import re
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..errors import InputError, MetadataError
from ..geodesy import ecef_to_geodetic, geodetic_to_ecef
from .rpc import RpcModel
from ..products.rpcfit import _COEFFS, _FIELDS, RPC_KEYS, rpc_metadata
from .sensor import _as_points

log = logging.getLogger(__name__)

MODEL = "rpc"
# The image may extend past the RPC's line/sample range by this share of the range's half-width
# (vendors round the scales): beyond it, the image is not the one the RPC describes.
SIZE_MARGIN = 0.1
# Normalised ground coordinates beyond which the cubic ratios are extrapolated too far to mean
# anything (|x| <= 1 is the fitted domain): no image position there.
MAX_NORMALISED = 2.0
RPB_NAMES = dict(zip(("lineOffset", "sampOffset", "latOffset", "longOffset", "heightOffset", "lineScale",
                      "sampScale", "latScale", "longScale", "heightScale"), RPC_KEYS))
RPB_NAMES.update(lineNumCoef="LINE_NUM_COEFF", lineDenCoef="LINE_DEN_COEFF", sampNumCoef="SAMP_NUM_COEFF",
                 sampDenCoef="SAMP_DEN_COEFF")


@dataclass
class RpcChip:
    """The single 'chip' of an RPC camera: the image is one continuous array."""
    col_offset: float = 0.0
    name: str = "image"


@dataclass
class RpcCamera:
    """The image an RPC describes: name and size (px)."""
    name: str
    cols: int
    rows: int
    chips: list = field(default_factory=lambda: [RpcChip()])

    def chip_index(self, col) -> np.ndarray:
        return np.zeros(np.shape(col), dtype=np.int64)

    def chip_range(self, k: int) -> tuple[float, float]:
        return 0.0, float(self.cols)


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

    # --- the interface of core.sensor.SceneModel -------------------------------------------
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

    def prepare(self) -> None:
        """Nothing to tabulate (kept for the SceneModel interface)."""

    def ground_to_image(self, xyz, camera: int = 0, **_) -> tuple[np.ndarray, np.ndarray]:
        """GDAL (col (n,), row (n,)) of ECEF points (n, 3): the RPC and the correction. NaN far
        outside the RPC's ground domain (normalised |lon| or |lat| > MAX_NORMALISED) and where its
        denominator vanishes."""
        self.camera_index(camera)
        p = np.atleast_2d(np.asarray(xyz, dtype=float))
        if not np.all(np.isfinite(p)):
            raise InputError("ground coordinates contain NaN or infinite values")
        lon, lat, h = ecef_to_geodetic(p)
        return self.ground_to_image_geodetic(lon, lat, h)

    def ground_to_image_geodetic(self, lon, lat, h, camera: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """ground_to_image for (lon, lat) degrees and ellipsoidal heights (m)."""
        lon, lat, h = np.broadcast_arrays(*(np.atleast_1d(np.asarray(a, dtype=float)) for a in (lon, lat, h)))
        self.warn_heights(h)
        r = self.rpc
        lon = r.lon_off + (lon - r.lon_off + 180.0) % 360.0 - 180.0
        with np.errstate(divide="ignore", invalid="ignore"):
            col, row = r.ground_to_image(lon, lat, h)
        far = (np.abs((lon - r.lon_off) / r.lon_scale) > MAX_NORMALISED) | \
              (np.abs((lat - r.lat_off) / r.lat_scale) > MAX_NORMALISED)
        col, row = self.correct(col, row)
        bad = far | ~np.isfinite(col) | ~np.isfinite(row)
        return np.where(bad, np.nan, col), np.where(bad, np.nan, row)

    def image_to_ground(self, col, row, height, camera: int = 0) -> np.ndarray:
        """ECEF points (n, 3) seen at image points on the surface of ellipsoidal height
        ``height`` (m, scalar or (n,)); NaN where the RPC's inversion does not converge."""
        self.camera_index(camera)
        col, row = _as_points(col, row)
        height = np.broadcast_to(np.asarray(height, dtype=float), col.shape)
        if not np.all(np.isfinite(height)):
            raise InputError("heights contain NaN or infinite values")
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
        col, row = _as_points(col, row)
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
    def correct(self, col, row) -> tuple[np.ndarray, np.ndarray]:
        """Corrected image positions of the RPC's own (col, row)."""
        a, b = self.correction
        return col + a[0] + a[1] * col + a[2] * row, row + b[0] + b[1] * col + b[2] * row

    def uncorrect(self, col, row) -> tuple[np.ndarray, np.ndarray]:
        """The RPC's own (col, row) of corrected image positions (the correction inverted)."""
        (a0, a1, a2), (b0, b1, b2) = self.correction
        m = np.array([[1.0 + a1, a2], [b1, 1.0 + b2]])
        inv = np.linalg.inv(m)
        dc, dr = col - a0, row - b0
        return inv[0, 0] * dc + inv[0, 1] * dr, inv[1, 0] * dc + inv[1, 1] * dr

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

    # --- scene JSON ------------------------------------------------------------------------
    def to_dict(self) -> dict:
        from ..formats.scene_json import FORMAT, VERSION
        md = rpc_metadata(self.rpc)
        rpc = {key: float(md[key]) for key in RPC_KEYS}
        rpc.update({key: [float(v) for v in md[key].split()] for key, _ in _COEFFS})
        return {"format": FORMAT, "version": VERSION, "model": MODEL,
                "camera": {"name": self.camera.name, "cols": self.camera.cols, "rows": self.camera.rows},
                "rpc": rpc, "correction": {"col": self.correction[0].tolist(), "row": self.correction[1].tolist()},
                "info": self.info}

    @classmethod
    def from_dict(cls, d: dict, source: str) -> "RpcScene":
        """The scene of a checked scene-JSON object with ``"model": "rpc"`` (see
        :func:`core.validation.check_rpc_scene_dict`)."""
        from ..validation import check_rpc_scene_dict
        d = check_rpc_scene_dict(d, source)
        rpc = rpc_from_metadata(d["rpc"], f"{source}: rpc")
        cam = d["camera"]
        camera = RpcCamera(str(cam["name"]), int(cam["cols"]), int(cam["rows"]))
        correction = np.array([d.get("correction", {}).get("col", [0, 0, 0]),
                               d.get("correction", {}).get("row", [0, 0, 0])], dtype=float)
        scene = cls(rpc, camera, correction, dict(d.get("info", {})))
        check_image_size(rpc, camera.cols, camera.rows, source)
        return scene


# --- the refined RPC --------------------------------------------------------------------------
def refined_rpc(scene: RpcScene) -> tuple[RpcModel, str]:
    """An RPC00B model of the corrected scene, GDAL and QGIS use directly, and how it was made:
    'folded' when each image coordinate's correction depends on that coordinate alone (a1 = 0 on
    rows, a2 = b1 = 0: col' = (1 + a1) col + a0 is an exact change of the sample numerator, as a
    multiple of the numerator plus one of the denominator; likewise rows), else 'refitted' (a
    correction mixing rows and columns, e.g. a drift of the columns along the rows, is not a ratio
    with the same denominator: the RPC is fitted anew to the corrected scene over the whole image
    and the RPC's height range, :func:`core.rpcfit.fit_rpc`, to about 1e-5 px)."""
    (a0, a1, a2), (b0, b1, b2) = scene.correction
    r = scene.rpc
    if a2 == 0.0 and b1 == 0.0:
        def fold(num, den, off, scale, gain, shift):
            # model' = gain * (model - origin + 0.5) + shift + origin - 0.5 with model = num/den * scale + off
            constant = (gain - 1.0) * off + shift - (gain - 1.0) * (r.origin - 0.5)
            return gain * num + constant / scale * den
        return replace(r, samp_num=fold(r.samp_num, r.samp_den, r.samp_off, r.samp_scale, 1.0 + a1, a0),
                       line_num=fold(r.line_num, r.line_den, r.line_off, r.line_scale, 1.0 + b2, b0)), "folded"
    from ..products.rpcfit import fit_rpc
    rpc, _ = fit_rpc(scene, 0, scene.height_range)
    return rpc, "refitted"


# --- reading RPC sources ----------------------------------------------------------------------
def rpc_from_metadata(md: dict, source: str) -> RpcModel:
    """RpcModel (origin 0) of GDAL 'RPC' metadata (keys LINE_OFF..., coefficient lists as text
    of 20 numbers or lists); MetadataError naming ``source`` and the key when one is missing,
    not a number, or a scale is zero."""
    values = {}
    for key, fld in zip(RPC_KEYS, _FIELDS):
        if key not in md or str(md[key]).strip() == "":
            raise MetadataError(f"{source}: {key} is missing")
        values[fld] = _number(md[key], source, key)
        if fld.endswith("_scale") and not (values[fld] != 0 and math.isfinite(values[fld])):
            raise MetadataError(f"{source}: {key} is {md[key]!r}; a scale must be a non-zero number")
    for key, fld in _COEFFS:
        if key not in md:
            raise MetadataError(f"{source}: {key} is missing (20 coefficients expected)")
        raw = md[key]
        items = raw if isinstance(raw, (list, tuple)) else str(raw).replace(",", " ").split()
        coefficients = [_number(v, source, key) for v in items]
        if len(coefficients) != 20:
            raise MetadataError(f"{source}: {key} holds {len(coefficients)} numbers; RPC00B has 20")
        values[fld] = np.array(coefficients)
    for fld in ("line_den", "samp_den"):
        if values[fld][0] == 0:
            raise MetadataError(f"{source}: the constant term of {fld.upper()}_COEFF is 0: the denominator vanishes "
                                "at the scene centre")
    return RpcModel(**values, origin=0.0)


def _number(text, source: str, key: str) -> float:
    try:
        v = float(str(text).strip().split()[0]) if not isinstance(text, (int, float)) else float(text)
    except (ValueError, IndexError):
        raise MetadataError(f"{source}: {key} is {str(text)[:40]!r}, not a number") from None
    if not math.isfinite(v):
        raise MetadataError(f"{source}: {key} is {text!r}, not a finite number")
    return v


def parse_rpc_txt(text: str) -> dict:
    """GDAL 'RPC' metadata of a ``_RPC.TXT`` text ("KEY: value [unit]", coefficients one per line
    as KEY_1..KEY_20)."""
    md: dict = {}
    lists: dict = {}
    for line in text.splitlines():
        key, sep, value = line.partition(":")
        if not sep:
            continue
        key, value = key.strip().upper(), value.strip()
        m = re.fullmatch(r"(\w+_COEFF)_(\d+)", key)
        if m:
            lists.setdefault(m.group(1), {})[int(m.group(2))] = value
        else:
            md[key] = value
    for key, items in lists.items():
        md[key] = [items[i] for i in sorted(items)]
    return md


def parse_rpb(text: str) -> dict:
    """GDAL 'RPC' metadata of an ``.RPB`` text ("name = value;", lists in parentheses)."""
    md = {}
    for name, value in re.findall(r"(\w+)\s*=\s*([^;]*);", text):
        key = RPB_NAMES.get(name)
        if key:
            md[key] = value.strip().strip("()").replace(",", " ")
    return md


def check_image_size(rpc: RpcModel, cols: int, rows: int, source: str) -> None:
    """MetadataError when an image of cols x rows px reaches past the RPC's sample/line range
    (by more than SIZE_MARGIN of its half-width): the RPC describes another image (a crop of an
    image, with its offsets moved, lies inside the range and is accepted)."""
    for what, n, off, scale in (("columns", cols, rpc.samp_off, rpc.samp_scale),
                                ("rows", rows, rpc.line_off, rpc.line_scale)):
        centre, half = off - rpc.origin + 0.5, abs(scale)
        slack = SIZE_MARGIN * half + 1.0
        if n <= 0 or n > centre + half + 0.5 + slack or centre - half - 0.5 > slack:
            raise MetadataError(f"{source}: the image has {n} {what} but its RPC covers {what} "
                                f"{round(centre - half - 0.5)} to {round(centre + half + 0.5)}: is it the image this "
                                "RPC belongs to?")


def size_from_rpc(rpc: RpcModel) -> tuple[int, int]:
    """(cols, rows) of the image whose pixels the RPC's sample/line range spans."""
    return (int(math.floor(rpc.samp_off - rpc.origin + 1.0 + abs(rpc.samp_scale))),
            int(math.floor(rpc.line_off - rpc.origin + 1.0 + abs(rpc.line_scale))))


def is_rpc_text(path: Path, head: bytes) -> bool:
    """Whether a file is an RPC text (``_RPC.TXT`` / ``.RPB`` layout), by name or first line."""
    name = path.name.upper()
    return name.endswith(("_RPC.TXT", ".RPB")) or head.upper().startswith((b"LINE_OFF", b"SATID"))


def read_rpc_text(path: Path) -> RpcScene:
    """The RPC scene of a ``_RPC.TXT`` or ``.RPB`` file; the image size from an image beside it
    that GDAL would pair with it, else from the RPC's line/sample range (with a warning)."""
    try:
        text = path.read_text(encoding="utf-8-sig", errors="strict")
    except UnicodeDecodeError:
        raise MetadataError(f"{path}: not a text RPC file (not UTF-8/ASCII text)") from None
    md = parse_rpb(text) if ("BEGIN_GROUP" in text.upper() or path.suffix.upper() == ".RPB") else parse_rpc_txt(text)
    rpc = rpc_from_metadata(md, str(path))
    stem = path.name[:-8] if path.name.upper().endswith("_RPC.TXT") else path.stem
    image = next((p for p in sorted(path.parent.glob(stem + ".*")) if p.suffix.lower() in IMAGE_SUFFIXES), None)
    warnings = []
    if image is not None:
        cols, rows = _raster_size(image)
    else:
        cols, rows = size_from_rpc(rpc)
        warnings.append(f"no image beside {path.name}: its size {cols} x {rows} px is taken from the RPC's "
                        "sample/line range")
    check_image_size(rpc, cols, rows, str(image or path))
    info = {"source": str(path), "image": str(image) if image else None, "warnings": warnings}
    return RpcScene(rpc, RpcCamera(stem or "image", cols, rows), info=info)


IMAGE_SUFFIXES = (".tif", ".tiff", ".ntf", ".jp2", ".img", ".vrt")


def _raster_size(path: Path) -> tuple[int, int]:
    from osgeo import gdal
    gdal.UseExceptions()
    try:
        ds = gdal.Open(str(path))
    except RuntimeError as exc:
        raise MetadataError(f"{path}: cannot be opened as a raster ({exc})") from None
    return ds.RasterXSize, ds.RasterYSize


def read_rpc_image(path: Path) -> RpcScene | None:
    """The RPC scene of a raster GDAL reads with RPC metadata (tags, ``_RPC.TXT`` or ``.RPB``
    beside it); None when GDAL cannot open it or it has no RPC."""
    from osgeo import gdal
    gdal.UseExceptions()
    try:
        ds = gdal.Open(str(path))
    except RuntimeError:
        return None
    md = ds.GetMetadata("RPC") or {}
    if not md:
        return None
    rpc = rpc_from_metadata(md, f"{path} (RPC metadata)")
    check_image_size(rpc, ds.RasterXSize, ds.RasterYSize, str(path))
    info = {"source": str(path), "image": str(path), "warnings": []}
    return RpcScene(rpc, RpcCamera(path.stem, ds.RasterXSize, ds.RasterYSize), info=info)


def read_dimap_rpc(path: Path, root) -> RpcScene:
    """The RPC scene of a DIMAP ``RPC_*.XML`` (the vendor's Global_RFM inverse model); the image
    size from the RFM's direct-model validity domain."""
    from ..formats.dimap import read_dimap_rfm
    rpc, _ = read_dimap_rfm(path, root)
    domain = root.find(".//Direct_Model_Validity_Domain")
    try:
        cols, rows = int(domain.findtext("LAST_COL")), int(domain.findtext("LAST_ROW"))
    except (AttributeError, TypeError, ValueError):
        cols, rows = size_from_rpc(rpc)
    check_image_size(rpc, cols, rows, str(path))
    return RpcScene(rpc, RpcCamera(path.stem, cols, rows), info={"source": str(path), "warnings": []})
