"""Maxar/DigitalGlobe image support data (the ``isd`` XML of WorldView, QuickBird, GeoEye).

Sections used: IMD (image size, line timing table and scan direction, view angles), EPH (ECEF
positions and velocities at a fixed interval), ATT (attitude quaternions at the same instants), GEO
(principal distance, detector array, camera attitude, perspective centre) and RPB (the vendor
RPC00B model; or the ``<name>.RPB`` beside the XML), which the model is checked against on load
(:mod:`core.formats.vendorcheck`).

Vendor conventions and how they are converted here:
  - Image: DigitalGlobe's detector index and TLC line numbers are 0-based pixel centres,
    so GDAL col = detector + 0.5 and row = line + 0.5 (the RPB likewise, as RPC00B).
  - Focal plane (GEO, millimetres): detector d sits at x = DETORIGINX + d*pitch*sin(r),
    y = DETORIGINY - d*pitch*cos(r) (r = DETROTANGLE, in degrees or in radians, told from its
    value: :func:`detector_rotation`) in the camera frame whose
    x is along track and z toward the scene; the line of sight is (x, y, PD) - no
    inversion (the detector coordinates are those of the positive image plane).
    In :class:`core.model.camera.Chip` terms: x0, y0, theta = pi - r, metres.
  - Quaternions (ATT, CAMERA_ATTITUDE): scalar last (q1, q2, q3, q4 = w). ATT rotates the
    body frame to ECEF; CAMERA_ATTITUDE rotates the camera frame to the body frame.
  - Time: UTC strings; the scene epoch is the first line time, every time is seconds from it.
    EPH and ATT sample k (1-based index) is at STARTTIME + (k - 1) * TIMEINTERVAL. The TLC
    line times decrease with the line in a reverse scan (SCANDIRECTION Reverse; GeoEye-1).
These conventions were checked on two WorldView-2 scenes: the model meets the vendor RPB to
0.18/0.38 px and the IMD corner coordinates to 0.07 px (tests/unit/formats/test_maxar.py); a
reversed detector, a scalar-first reading or an inverted attitude would be pixels to
kilometres off.

Corrections - the rule and its sources. The ATT quaternions are the measured attitude of the
spacecraft, so the line of sight needs velocity aberration (~25 urad, ~15 m) and atmospheric
refraction to meet the ground, for every Maxar satellite and ISD version: Maxar's own RPB and
IMD corners include both (WorldView-2, ISD 24.06: 35-40 px off without them), and the NASA Ames
Stereo Pipeline applies both to every WorldView product with no rule per version or date
(ASP 3.4.0, 2024, NEWS.rst and docs/tutorial.rst "dg_csm"; src/asp/Camera/LinescanDGModel.cc).
No published source (DigitalGlobe ISD documentation v1.1.2, 2014; ASP; GDAL and OSSIM read only
the RPB) describes a generation whose attitude already contains them. The reader therefore
applies both, and ``info["corrections"]`` says so and why. What does differ between files is
who made the RPB: the Ames Stereo Pipeline's ``dg_mosaic`` (the tool that joins a tiled
product, output ``*.r100.xml``) replaces Maxar's RPB by an RPC that ``rpc_gen`` fits to ASP's
own model; ASP 3.1.0-3.3.0 (May 2022 - June 2024) had velocity aberration and refraction off
by default, so such an RPB is ~15 m (tens of px) from Maxar's geometry. It is recognised from
the metadata: rpc_gen's normalisation (one pixel scale max(rows, cols)/2 for line and sample,
offsets at half the image size, src/asp/Tools/rpc_gen.cc) and no TIL section (dg_mosaic
removes it). ``info["rpb_origin"]`` names the maker and a warning explains the offset. A
satellite or ISD version the reader cannot place (SATID not one of QB02, WV01-WV04, GE01;
IMD/VERSION missing, not a number, or newer than the newest checked, 28) gets a warning naming
what was assumed; warnings are logged and listed in ``info["warnings"]``, which the Processing
algorithms show.
"""
from __future__ import annotations

import logging
from pathlib import Path
from xml.etree import ElementTree

import numpy as np

from ..model.camera import Camera, Chip, LineTiming
from ..errors import MetadataError
from ..rotations import quat_to_matrix
from ..model.rpc import RpcModel
from ..model.sensor import SceneModel
from ..model.trajectory import Ephemeris, Platform, QuaternionSamples
from ..validation import rpc_value_problem
from .rpcfiles import parse_rpb, rpc_from_metadata
from .vendorcheck import VendorRpc
from .vendor_xml import parse_floats as _floats, parse_xml

log = logging.getLogger(__name__)

MM = 1e-3  # GEO lengths are millimetres
SATELLITES = {"QB02": "QuickBird", "WV01": "WorldView-1", "WV02": "WorldView-2", "WV03": "WorldView-3",
              "WV04": "WorldView-4", "GE01": "GeoEye-1"}
MAX_IMAGE_SIZE = 10_000_000  # pixels per side: far beyond any Maxar strip (WorldView-3: 43008 detectors)
NEWEST_ISD_MAJOR = 28  # IMD/VERSION of the newest product checked (WorldView-3, 2022: 28.3)
# The detector line lies across track: DETROTANGLE (GEO/DETECTOR_MOUNTING) at 0 or 180 degrees, within this
ACROSS_TRACK_TOLERANCE_DEG = 1.0
CORRECTIONS_REASON = ("velocity aberration and atmospheric refraction applied: the ATT quaternions are the "
                      "measured attitude, and Maxar's own models include both corrections for every satellite "
                      "and ISD version (as the NASA Ames Stereo Pipeline applies them to every WorldView product)")


def read_maxar(path: str | Path, root: ElementTree.Element) -> tuple[SceneModel, VendorRpc | None]:
    """SceneModel (one pushbroom camera, velocity aberration and refraction on) from a parsed
    Maxar isd XML, and the product's RPB to check it against (:mod:`core.formats.vendorcheck`;
    None, with a warning, when the product has none). Raises MetadataError naming the missing or
    malformed section/field."""
    src = str(path)
    imd = _section(root, "IMD", src, "image metadata")
    _check_sensor_geometry_product(imd, src)
    image = _child(imd, "IMAGE", src, "IMD")
    first_line = _utc(_text(image, "FIRSTLINETIME", src, "IMD/IMAGE"), src, "IMD/IMAGE/FIRSTLINETIME")
    epoch_dt = first_line.astype("datetime64[us]").astype("datetime64[ns]")  # exactly the epoch string
    epoch = str(np.datetime_as_string(epoch_dt, unit="us")) + "Z"
    ephemeris = _read_ephemeris(root, src, epoch_dt)
    attitude = _read_attitude(root, src, epoch_dt)
    geo = _section(root, "GEO", src, "camera geometry")
    installation = quat_to_matrix(_scalar_last(
        [_number(_child(geo, "CAMERA_ATTITUDE", src, "GEO"), k, src, "GEO/CAMERA_ATTITUDE")
         for k in ("QCS1", "QCS2", "QCS3", "QCS4")]))
    ephemeris = _apply_perspective_centre(geo, ephemeris, attitude, src)
    cols = _image_size(imd, "NUMCOLUMNS", src)
    timing, scan, scan_warning = _read_line_timing(image, src, epoch_dt)
    chip, rotation = _read_chip(geo, cols, src)
    camera = Camera(name=_text(imd, "BANDID", src, "IMD"), cols=cols,
                    rows=_image_size(imd, "NUMROWS", src),
                    timing=timing,
                    chips=[chip],
                    focal_length=_number(_child(geo, "PRINCIPAL_DISTANCE", src, "GEO"), "PD", src,
                                         "GEO/PRINCIPAL_DISTANCE") * MM,
                    installation=installation)
    _check_no_distortion(geo, src)
    info = {
        "sensor": _text(image, "SATID", src, "IMD/IMAGE"),
        "catalog_id": _text(image, "CATID", src, "IMD/IMAGE"),
        "product_id": imd.findtext("PRODUCTCATALOGID", ""),
        "source": src,
        "format": "Maxar/DigitalGlobe isd XML",
        "gsd_m": _optional_number(image, "MEANPRODUCTGSD"),
        "off_nadir_deg": _optional_number(image, "MEANOFFNADIRVIEWANGLE"),
    }
    info["isd_version"] = imd.findtext("VERSION", "").strip() or None
    info["corrections"] = {"aberration": True, "refraction": True, "reason": CORRECTIONS_REASON}
    info["scan_direction"] = scan
    info["detector_rotation"] = rotation
    warnings = [w for w in [_unplaced_generation(info["sensor"], info["isd_version"]), scan_warning] if w]
    vendor = _vendor_rpc(Path(path), root)
    if vendor is None:
        warnings.append(f"no RPB (neither an RPB section nor {Path(path).stem}.RPB beside it): the rigorous model "
                        "could not be checked against Maxar's RPC")
    else:
        rpc = vendor.rpc
        info["height_range"] = [rpc.height_off - rpc.height_scale, rpc.height_off + rpc.height_scale]
        info["rpb_origin"] = _rpb_origin(rpc, camera.cols, camera.rows, root.find("TIL") is not None)
        vendor.refit_without_corrections = info["rpb_origin"] != "Maxar"
        vendor.assumed = (rotation["read_as"], f"IMD/IMAGE/TLCLISTList read as a {scan.lower()} scan")
        if vendor.refit_without_corrections:
            warnings.append(f"the RPB was refitted by {info['rpb_origin']}, not made by Maxar; ASP 3.1.0-3.3.0 "
                            "fitted it to a model without velocity aberration and refraction, so it can lie ~15 m "
                            "(tens of pixels) from this rigorous model, which applies both as Maxar does")
    if warnings:
        info["warnings"] = [f"{src}: {w}" for w in warnings]
        for w in info["warnings"]:
            log.warning(w)
    return SceneModel(epoch=epoch, platform=Platform(ephemeris, attitude), cameras=[camera],
                      aberration=True, refraction=True, info=info), vendor


def _vendor_rpc(path: Path, root: ElementTree.Element) -> VendorRpc | None:
    """The product's RPB: the XML's RPB section, else an ``.RPB`` file of the XML's name beside it
    (as Maxar delivers it: <name>.XML, <name>.RPB); None when neither exists."""
    if root.find("RPB") is not None:
        return VendorRpc(read_maxar_rpc(path, root), f"{path.name} (its RPB section)")
    beside = [p for p in (path.with_suffix(".RPB"), path.with_suffix(".rpb")) if p.is_file()]
    if not beside:
        return None
    try:
        text = beside[0].read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise MetadataError(f"{beside[0]}: the RPB beside {path.name} cannot be read as text ({exc})") from None
    return VendorRpc(rpc_from_metadata(parse_rpb(text), str(beside[0])), str(beside[0]))


def read_maxar_rpc(path: str | Path, root: ElementTree.Element | None = None) -> RpcModel:
    """The vendor RPC00B model of the RPB section (0-based pixel centres, as GDAL reads RPCs)."""
    src = str(path)
    if root is None:
        root = parse_xml(path)
    rpb = _section(root, "RPB", src, "vendor RPC")
    img = _child(rpb, "IMAGE", src, "RPB")
    where = "RPB/IMAGE"
    coef = {}
    for key, tag in (("line_num", "LINENUMCOEF"), ("line_den", "LINEDENCOEF"),
                     ("samp_num", "SAMPNUMCOEF"), ("samp_den", "SAMPDENCOEF")):
        text = _text(_child(img, tag + "List", src, where), tag, src, f"{where}/{tag}List")
        coef[key] = _floats(text, src, f"{where}/{tag}List/{tag}")
    tags = (("lon_off", "LONGOFFSET"), ("lon_scale", "LONGSCALE"), ("lat_off", "LATOFFSET"),
            ("lat_scale", "LATSCALE"), ("height_off", "HEIGHTOFFSET"), ("height_scale", "HEIGHTSCALE"),
            ("line_off", "LINEOFFSET"), ("line_scale", "LINESCALE"), ("samp_off", "SAMPOFFSET"),
            ("samp_scale", "SAMPSCALE"))
    scalars = {key: _number(img, tag, src, where) for key, tag in tags}
    for key, tag in tags:
        problem = rpc_value_problem(key, scalars[key])
        if problem:
            raise MetadataError(f"{src}: {where}/{tag} is {scalars[key]:g}; {problem}")
    try:
        return RpcModel(**coef, **scalars, origin=0.0)
    except MetadataError as exc:
        raise MetadataError(f"{src}: {where}: {exc}") from None


# --- product generation and corrections -------------------------------------------------------
def _unplaced_generation(satid: str, version: str | None) -> str | None:
    """Warning text when the satellite or the ISD version is not one this reader can place
    (None when it can): what is unknown and the convention assumed."""
    if satid not in SATELLITES:
        unknown = f"satellite IMD/IMAGE/SATID {satid!r} is none of {', '.join(SATELLITES)}"
    elif version is None:
        unknown = "IMD/VERSION (the ISD version) is missing"
    else:
        try:
            major = int(float(version))
        except ValueError:
            major = None
        if major is None:
            unknown = f"IMD/VERSION {version!r} is not an ISD version number"
        elif major > NEWEST_ISD_MAJOR:
            unknown = f"ISD version {version} is newer than the newest checked ({NEWEST_ISD_MAJOR}.x)"
        else:
            return None
    return (f"cannot place this product's generation: {unknown}; assumed the convention of the Maxar "
            "products checked (WorldView-2 ISD 24.06, WorldView-3 ISD 28.3): ATT is the measured attitude, "
            "velocity aberration and atmospheric refraction applied")


def _check_sensor_geometry_product(imd, src: str) -> None:
    """Refuse a map-projected product (Standard2A, ORStandard2A, ortho; IMD/MAPPROJECTEDPRODUCT):
    its image no longer has the sensor's lines and detectors. Only Basic1B and Stereo1B keep
    them (the Ames Stereo Pipeline accepts only these for WorldView, LinescanDGModel.cc); a
    file without IMAGEDESCRIPTOR (older products) is taken as 1B."""
    descriptor = imd.findtext("IMAGEDESCRIPTOR", "").strip()
    if imd.find("MAPPROJECTEDPRODUCT") is not None:
        what = "IMD/MAPPROJECTEDPRODUCT is present (a map-projected product)"
    elif descriptor and not descriptor.upper().endswith("1B"):
        what = f"IMD/IMAGEDESCRIPTOR is {descriptor!r}"
    else:
        return
    raise MetadataError(f"{src}: {what}, not a Basic1B or Stereo1B product: its image no longer keeps the "
                        "sensor's lines and detectors, so the pushbroom model cannot describe it (use its RPB)")


def _rpb_origin(rpc: RpcModel, cols: int, rows: int, has_til: bool) -> str:
    """Who made the RPB: "Maxar", or the Ames Stereo Pipeline when the file carries the
    normalisation of its rpc_gen (as dg_mosaic writes it: one pixel scale max(rows, cols)/2 for
    line and sample, offsets at half the image size, to 1 px for reduced-resolution mosaics)
    and no TIL section (dg_mosaic removes it; Maxar products have one)."""
    half = max(rows, cols) / 2.0
    rpc_gen = (abs(rpc.line_scale - half) <= 1.0 and abs(rpc.samp_scale - half) <= 1.0
               and abs(rpc.line_off - rows / 2.0) <= 1.0 and abs(rpc.samp_off - cols / 2.0) <= 1.0)
    if rpc_gen and not has_til:
        return "the Ames Stereo Pipeline (dg_mosaic, rpc_gen)"
    return "Maxar"


# --- sections ------------------------------------------------------------------------------
def _read_ephemeris(root, src: str, epoch_dt: np.datetime64) -> Ephemeris:
    """EPHEMLIST rows: index (1-based), X, Y, Z (m), VX, VY, VZ (m/s), covariances."""
    eph = _section(root, "EPH", src, "ephemeris")
    rows = _sample_table(eph, "EPHEMLIST", 7, src, "EPH")
    times = _sample_times(eph, rows[:, 0], src, "EPH", epoch_dt)
    return Ephemeris(times, rows[:, 1:4], rows[:, 4:7], order=8)


def _read_attitude(root, src: str, epoch_dt: np.datetime64) -> QuaternionSamples:
    """ATTLIST rows: index (1-based), q1, q2, q3, q4 (scalar last, body -> ECEF), covariances."""
    att = _section(root, "ATT", src, "attitude")
    rows = _sample_table(att, "ATTLIST", 5, src, "ATT")
    times = _sample_times(att, rows[:, 0], src, "ATT", epoch_dt)
    try:
        return QuaternionSamples(times, _scalar_last(rows[:, 1:5].T), order=4)
    except MetadataError as exc:
        raise MetadataError(f"{src}: ATT: {exc}") from None


def _read_line_timing(image, src: str, epoch_dt: np.datetime64) -> tuple[LineTiming, str, str | None]:
    """TLC table: (line, seconds after TLCTIME) pairs, line = 0-based pixel-centre row; the times
    decrease with the line in a reverse scan. A single entry is completed with AVGLINERATE in the
    direction of SCANDIRECTION ("Reverse": times decreasing); LineTiming extrapolates past the
    table. Returns the timing, the scan direction it shows ("Forward" or "Reverse") and a warning
    when SCANDIRECTION names the other one (the table, which is the geometry, is followed)."""
    where = "IMD/IMAGE"
    t_ref = _seconds(_utc(_text(image, "TLCTIME", src, where), src, f"{where}/TLCTIME"), epoch_dt)
    entries = [_floats(e.text or "", src, f"{where}/TLCLISTList/TLCLIST", 2)[:2]
               for e in _child(image, "TLCLISTList", src, where).findall("TLCLIST")]
    if not entries:
        raise MetadataError(f"{src}: {where}/TLCLISTList has no TLCLIST entries (line timing)")
    stated = image.findtext("SCANDIRECTION", "").strip()
    table = np.array(entries)
    if table.shape[0] == 1:
        rate = _number(image, "AVGLINERATE", src, where)
        table = np.vstack([table, table[0] + [rate, -1.0 if stated.lower() == "reverse" else 1.0]])
    try:
        timing = LineTiming(lines=table[:, 0], times=table[:, 1] + t_ref)
    except MetadataError as exc:
        raise MetadataError(f"{src}: {where}/TLCLISTList: {exc}") from None
    shown = "Reverse" if timing.reverse else "Forward"
    warning = None
    if stated and stated.lower() != shown.lower():
        warning = (f"{where}/SCANDIRECTION is {stated!r} but the line times of {where}/TLCLISTList "
                   f"{'decrease' if timing.reverse else 'increase'} with the line: read as the table gives them "
                   f"({shown} scan)")
    return timing, shown, warning


def _read_chip(geo, n_pixels: int, src: str) -> tuple[Chip, dict]:
    """The detector array of GEO/DETECTOR_MOUNTING (the first band: a 1B product has one), and
    how its DETROTANGLE was read (:func:`detector_rotation`)."""
    mounting = _child(geo, "DETECTOR_MOUNTING", src, "GEO")
    bands = [b for b in mounting if b.tag.startswith("BAND_")]
    if not bands:
        raise MetadataError(f"{src}: GEO/DETECTOR_MOUNTING has no BAND_* detector array")
    where = f"GEO/DETECTOR_MOUNTING/{bands[0].tag}"
    det = _child(bands[0], "DETECTOR_ARRAY", src, where)
    where += "/DETECTOR_ARRAY"
    v = {k: _number(det, k, src, where) for k in ("DETORIGINX", "DETORIGINY", "DETROTANGLE", "DETPITCH")}
    rotation = detector_rotation(v["DETROTANGLE"], f"{where}/DETROTANGLE")
    log.info("%s: %s", src, rotation["read_as"])
    return Chip(col_offset=0.0, n_pixels=n_pixels, kind="focal_plane", x0=v["DETORIGINX"] * MM,
                y0=v["DETORIGINY"] * MM, pitch=v["DETPITCH"] * MM,
                theta=np.pi - rotation["radians"], name=bands[0].tag[5:]), rotation


def detector_rotation(value: float, where: str) -> dict:
    """DETROTANGLE in radians, with the unit it was read in and a sentence saying so.

    WorldView products write 0 (no unit to tell); a GeoEye-1 product of ISD 28.3 writes
    3.141592653589793, i.e. 180 degrees in radians, and the Ames Stereo Pipeline's reader took the
    field in degrees in older versions and in radians in later ones (LinescanDGModel.cc). The unit
    is told from the value: the detector line lies across track, at 0 or 180 degrees (within
    ACROSS_TRACK_TOLERANCE_DEG). A value beyond 2 pi is degrees; one that lies across track only
    when read as radians is radians; any other (0 included) is degrees. The product's RPB then
    confirms the reading, or refuses the product (:mod:`core.formats.vendorcheck`)."""
    def across(deg: float) -> bool:
        return abs((deg + 90.0) % 180.0 - 90.0) <= ACROSS_TRACK_TOLERANCE_DEG

    radians = abs(value) <= 2.0 * np.pi and across(np.degrees(value)) and not across(value)
    deg = float(np.degrees(value)) if radians else value
    unit = "radians" if radians else "degrees"
    return {"value": value, "unit": unit, "radians": float(value if radians else np.radians(value)),
            "read_as": f"{where} {value!r} read as {unit} ({deg:g} deg)"}


def _check_no_distortion(geo, src: str) -> None:
    """The model has no DigitalGlobe optical-distortion polynomials: refuse non-zero ones."""
    dist = geo.find("OPTICAL_DISTORTION")
    if dist is None or float(dist.findtext("POLYORDER", "-1") or -1) <= 0:
        return
    values = [_floats(e.text or "", src, "GEO/OPTICAL_DISTORTION") for e in dist.iter()
              if e.tag in ("ALIST", "BLIST")]
    if any(np.any(v != 0) for v in values):
        raise MetadataError(f"{src}: GEO/OPTICAL_DISTORTION has non-zero polynomials, which this "
                            "reader does not model")


def _apply_perspective_centre(geo, ephemeris: Ephemeris, attitude: QuaternionSamples, src: str) -> Ephemeris:
    """Move the ephemeris from the body origin to the perspective centre (GEO CX, CY, CZ:
    body-frame offset in metres, turned to ECEF by the attitude at each ephemeris time)."""
    pc = geo.find("PERSPECTIVE_CENTER")
    if pc is None:
        return ephemeris
    offset = np.array([_number(pc, k, src, "GEO/PERSPECTIVE_CENTER") for k in ("CX", "CY", "CZ")])
    if not np.any(offset):
        return ephemeris
    shift = attitude.rotation(ephemeris.times) @ offset
    return Ephemeris(ephemeris.times, ephemeris.positions + shift, ephemeris.velocities, ephemeris.order)


# --- sample tables and times -----------------------------------------------------------------
def _sample_table(section, item: str, min_cols: int, src: str, where: str) -> np.ndarray:
    """Rows of numbers (n, min_cols) from <ITEMList><ITEM>...; checks NUMPOINTS."""
    lst = _child(section, item + "List", src, where)
    rows = [_floats(e.text or "", src, f"{where}/{item}List/{item}", min_cols) for e in lst.findall(item)]
    expected = int(_number(section, "NUMPOINTS", src, where))
    if len(rows) != expected or expected < 2:
        raise MetadataError(f"{src}: {where}/{item}List holds {len(rows)} samples but NUMPOINTS says "
                            f"{expected} (at least 2 needed): the file is truncated or inconsistent")
    return np.array([r[:min_cols] for r in rows])


def _sample_times(section, index: np.ndarray, src: str, where: str, epoch_dt: np.datetime64) -> np.ndarray:
    """Times (s from the epoch) of samples numbered ``index`` (1-based) from STARTTIME at TIMEINTERVAL."""
    start = _seconds(_utc(_text(section, "STARTTIME", src, where), src, f"{where}/STARTTIME"), epoch_dt)
    step = _number(section, "TIMEINTERVAL", src, where)
    if not step > 0:
        raise MetadataError(f"{src}: {where}/TIMEINTERVAL must be positive (got {step})")
    return start + (index - 1.0) * step


def _utc(text: str, src: str, where: str) -> np.datetime64:
    """Parse a UTC time 'YYYY-MM-DDTHH:MM:SS.ffffffZ' to nanoseconds."""
    try:
        return np.datetime64(text.strip().rstrip("Z"), "ns")
    except ValueError:
        raise MetadataError(f"{src}: {where}: {text!r} is not a UTC time "
                            "(expected YYYY-MM-DDTHH:MM:SS.ffffffZ)") from None


def _seconds(t: np.datetime64, epoch: np.datetime64) -> float:
    """Seconds from epoch to t (exact to the nanosecond before the conversion to float)."""
    return float((t - epoch) / np.timedelta64(1, "ns")) * 1e-9


def _scalar_last(q) -> np.ndarray:
    """(q1, q2, q3, q4) with q4 the scalar part -> scalar-first (q4, q1, q2, q3), along axis 0."""
    q = np.asarray(q, dtype=float)
    return np.stack([q[3], q[0], q[1], q[2]], axis=-1)


# --- element access with clear errors ---------------------------------------------------------
def _section(root, tag: str, src: str, what: str):
    elem = root.find(tag)
    if elem is None:
        raise MetadataError(f"{src}: the <{tag}> section ({what}) is missing; a Maxar isd XML with "
                            "IMD, EPH, ATT, GEO and RPB sections is needed")
    return elem


def _child(parent, tag: str, src: str, where: str):
    elem = parent.find(tag)
    if elem is None:
        raise MetadataError(f"{src}: {where}/{tag} is missing")
    return elem


def _text(parent, tag: str, src: str, where: str) -> str:
    text = (_child(parent, tag, src, where).text or "").strip()
    if not text:
        raise MetadataError(f"{src}: {where}/{tag} is empty")
    return text


def _number(parent, tag: str, src: str, where: str) -> float:
    text = _text(parent, tag, src, where)
    try:
        value = float(text)
    except ValueError:
        raise MetadataError(f"{src}: {where}/{tag}: {text!r} is not a number") from None
    if not np.isfinite(value):
        raise MetadataError(f"{src}: {where}/{tag} is not finite ({text!r})")
    return value


def _image_size(imd, tag: str, src: str) -> int:
    """IMD/NUMCOLUMNS or NUMROWS: a whole number of pixels from 1 to MAX_IMAGE_SIZE."""
    value = _number(imd, tag, src, "IMD")
    if value != int(value) or not 1 <= value <= MAX_IMAGE_SIZE:
        raise MetadataError(f"{src}: IMD/{tag} is {value:g}; expected a whole number of pixels "
                            f"from 1 to {MAX_IMAGE_SIZE}")
    return int(value)


def _optional_number(parent, tag: str) -> float | None:
    """A descriptive number (None when absent or malformed: it never changes the geometry)."""
    try:
        value = float(parent.findtext(tag, ""))
    except ValueError:
        return None
    return value if np.isfinite(value) else None


