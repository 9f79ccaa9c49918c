"""Pleiades DIMAP metadata (``PHR_Dimap_Document``, sensor-geometry primary products).

Blocks used, under ``Geometric_Data/Sensor_Model_Characteristics``:
  - ``UTC_Sensor_Model_Range/START``: UTC time of the centre of image row 1; the scene epoch.
  - ``Sensor_Ephemeris/Point_List``: ECEF positions (m) and velocities (m/s) every 30 s,
    interpolated with 8-point Lagrange windows.
  - ``Sensor_Attitudes``: quaternion polynomials Q0 (scalar part) .. Q3 in u = (t - OFFSET) /
    SCALE, t in UTC seconds of the day of START, rotating the body frame to ECEF.
  - ``SENSOR_LINE_PERIOD`` (ms): time of row r (1-based) = START + (r - 1) * period.
  - ``Sensor_Viewing_Model``: look angles PsiX, PsiY (rad) as polynomials in (k - 1), k the
    1-based retina column; image column c is retina column Position_In_Retina/FIRST_COL + c - 1
    (the retina range may be wider than the image); the body line of sight is (PsiY, -PsiX, 1) with the
    angles themselves (not their tangents), i.e. camera ux = PsiY, uy = -PsiX, installation = identity.
The vendor's ``Geoposition/Rational_Sensor_Model/Global_RFM`` (direct image -> ground and
inverse ground -> image rational functions, normalisation in ``RFM_Validity`` as A = scale,
B = offset) is read by :func:`read_dimap_rfm`.

Vendor conventions converted here: DIMAP pixel coordinates are 1-based pixel centres, so GDAL
col = c - 0.5 and row = r - 0.5. The rigorous model needs neither velocity aberration nor
refraction: the vendor's viewing directions and attitudes already absorb them (the model
meets the vendor's own RFM and localisation grid to a millimetre only with both off; velocity
aberration would move the ground by 18 m, refraction by 0.7-0.8 m in this scene).
"""
from __future__ import annotations

from pathlib import Path
from xml.etree import ElementTree

import numpy as np

from ..model.camera import Camera, Chip, LineTiming
from ..errors import MetadataError
from ..model.rpc import RationalDirectModel, RpcModel
from ..model.sensor import SceneModel
from ..model.trajectory import Ephemeris, Platform, QuaternionPolynomial
from ..validation import rpc_value_problem
from .vendor_xml import parse_floats as _floats, parse_xml

SENSOR_MODEL = "Geometric_Data/Sensor_Model_Characteristics"
GLOBAL_RFM = "Geoposition/Rational_Sensor_Model/Global_RFM"
PLATFORMS = {"PHR": "Pleiades", "SPOT": "SPOT"}
MAX_LOOK_ANGLE = 0.5  # rad: half the widest field of view a pushbroom retina could have


def read_dimap(path: str | Path, root: ElementTree.Element) -> SceneModel:
    """SceneModel (one look-angle camera, no aberration or refraction) from a parsed Pleiades
    DIMAP document. Raises MetadataError naming the missing or malformed element."""
    src = str(path)
    model = _find(root, SENSOR_MODEL, src, "the rigorous sensor model")
    start = _utc(_text(model, "UTC_Sensor_Model_Range/START", src, SENSOR_MODEL), src,
                 f"{SENSOR_MODEL}/UTC_Sensor_Model_Range/START")
    epoch_dt = start.astype("datetime64[us]").astype("datetime64[ns]")  # exactly the epoch string
    epoch = str(np.datetime_as_string(epoch_dt, unit="us")) + "Z"
    rows = int(_number(root, "Raster_Dimensions/NROWS", src, ""))
    cols = int(_number(root, "Raster_Dimensions/NCOLS", src, ""))
    if rows < 2 or cols < 2:
        raise MetadataError(f"{src}: Raster_Dimensions: image of {cols} x {rows} pixels is too small")
    timing = _read_timing(model, src, start, epoch_dt, rows)
    camera = Camera(name=root.findtext("Image_Interpretation/Spectral_Band_Info/BAND_ID", "PA").strip(),
                    cols=cols, rows=rows, timing=timing, chips=[_read_look_angles(model, src, cols)])
    platform = Platform(_read_ephemeris(model, src, epoch_dt), _read_attitude(model, src, epoch_dt, timing, rows))
    inverse, _ = read_dimap_rfm(path, root)
    info = {
        "sensor": _sensor_name(root),
        "product_id": root.findtext("Dataset_Identification/DATASET_NAME", "").strip(),
        "data_strip_id": root.findtext("Data_Strip/Data_Strip_Identification/DATA_STRIP_ID", "").strip(),
        "source": src,
        "format": "Pleiades DIMAP (sensor geometry)",
        "height_range": [inverse.height_off - inverse.height_scale, inverse.height_off + inverse.height_scale],
    }
    incidence = [float(x.text) for x in root.findall("Data_Strip/Geometric_Header_List/Located_Geometric_Header/"
                                                "Incidences/GLOBAL_INCIDENCE") if _is_number(x.text)]
    if incidence:
        info["incidence_deg"] = incidence[len(incidence) // 2]
    scene = SceneModel(epoch=epoch, platform=platform, cameras=[camera], aberration=False, refraction=False,
                       info=info)
    scene.info["gsd_m"] = _ground_sample_distance(scene)
    return scene


# RFM_Validity's elements: the RpcModel fields (<field>_off, <field>_scale) their B and A fill
RFM_FIELDS = {"Lon": "lon", "Lat": "lat", "Alt": "height", "Col": "samp", "Row": "line"}


def read_dimap_rfm(path: str | Path, root: ElementTree.Element | None = None
                   ) -> tuple[RpcModel, RationalDirectModel]:
    """The vendor's Global_RFM: (inverse model ground -> image, direct model image -> ground),
    both in 1-based pixel-centre model coordinates (``origin`` = 1) and converted to GDAL
    (col, row) by the model classes."""
    src = str(path)
    if root is None:
        root = parse_xml(path)
    # in the DIMAP document itself, or in an RPC_*.XML file (<Rational_Function_Model/Global_RFM>)
    rfm = root.find(GLOBAL_RFM) if root.find(GLOBAL_RFM) is not None else root.find(".//Global_RFM")
    if rfm is None:
        _find(root, GLOBAL_RFM, src, "the vendor rational function model")  # names the missing element
    norm = {}
    for tag in ("Lon", "Lat", "Alt", "Col", "Row"):
        where = f"{GLOBAL_RFM}/RFM_Validity/{tag}"
        elem = _find(rfm, f"RFM_Validity/{tag}", src, "RFM normalisation", GLOBAL_RFM)
        scale, offset = _number(elem, "A", src, where), _number(elem, "B", src, where)
        for letter, value, field, word in (("A", scale, "scale", "scale"), ("B", offset, "off", "offset")):
            problem = rpc_value_problem(f"{RFM_FIELDS[tag]}_{field}", value)
            if problem:
                raise MetadataError(f"{src}: <{where}/{letter}> ({word}) is {value:g}; {problem}")
        norm[tag] = (offset, scale)
    coef = {tag: _rfm_coefficients(rfm, path_, src) for tag, path_ in
            (("lon", "Direct_Model/F_LON"), ("lat", "Direct_Model/F_LAT"),
             ("col", "Inverse_Model/F_COL"), ("row", "Inverse_Model/F_ROW"))}
    scalars = dict(lon_off=norm["Lon"][0], lon_scale=norm["Lon"][1], lat_off=norm["Lat"][0],
                   lat_scale=norm["Lat"][1], height_off=norm["Alt"][0], height_scale=norm["Alt"][1],
                   line_off=norm["Row"][0], line_scale=norm["Row"][1], samp_off=norm["Col"][0],
                   samp_scale=norm["Col"][1], origin=1.0)
    inverse = RpcModel(line_num=coef["row"][:20], line_den=coef["row"][20:], samp_num=coef["col"][:20],
                       samp_den=coef["col"][20:], **scalars)
    direct = RationalDirectModel(lon_num=coef["lon"][:20], lon_den=coef["lon"][20:], lat_num=coef["lat"][:20],
                                 lat_den=coef["lat"][20:], **scalars)
    return inverse, direct


# --- blocks of the sensor model --------------------------------------------------------------
def _read_timing(model, src: str, start: np.datetime64, epoch_dt: np.datetime64, rows: int) -> LineTiming:
    """Row r (1-based) is seen at START + (r - 1) * period, i.e. GDAL row r - 0.5: so t0 is
    START in seconds from the epoch (START to the microsecond)."""
    period = _number(model, "SENSOR_LINE_PERIOD", src, SENSOR_MODEL) * 1e-3
    if not period > 0:
        raise MetadataError(f"{src}: {SENSOR_MODEL}/SENSOR_LINE_PERIOD must be positive (got {period * 1e3} ms)")
    end_text = model.findtext("UTC_Sensor_Model_Range/END")
    if end_text:
        span = _seconds(_utc(end_text, src, f"{SENSOR_MODEL}/UTC_Sensor_Model_Range/END"), start)
        if abs(rows * period - span) > 0.05 * span:
            raise MetadataError(f"{src}: {SENSOR_MODEL}/SENSOR_LINE_PERIOD ({period * 1e3} ms, expected in "
                                f"milliseconds) times {rows} rows does not match the model time range "
                                f"({span:.3f} s)")
    return LineTiming(t0=_seconds(start, epoch_dt), period=period)


def _read_ephemeris(model, src: str, epoch_dt: np.datetime64) -> Ephemeris:
    where = f"{SENSOR_MODEL}/Sensor_Ephemeris/Point_List"
    points = _find(model, "Sensor_Ephemeris/Point_List", src, "the ephemeris", SENSOR_MODEL).findall("Point")
    if len(points) < 8:
        raise MetadataError(f"{src}: {where} holds {len(points)} <Point> samples; 8 are needed for the "
                            "Lagrange interpolation of the orbit")
    for tag, unit in (("LOCATION_VALUES", "m"), ("VELOCITY_VALUES", "m/s")):
        units = {p.find(tag).get("unit", unit) for p in points if p.find(tag) is not None}
        if units - {unit}:
            raise MetadataError(f"{src}: {where}/Point/{tag} is in {sorted(units)}, expected {unit!r}")
    pos = np.array([_floats(_text(p, "LOCATION_VALUES", src, f"{where}/Point"), src,
                            f"{where}/Point/LOCATION_VALUES", 3)[:3] for p in points])
    vel = np.array([_floats(_text(p, "VELOCITY_VALUES", src, f"{where}/Point"), src,
                            f"{where}/Point/VELOCITY_VALUES", 3)[:3] for p in points])
    times = np.array([_seconds(_utc(_text(p, "UTC_TIME", src, f"{where}/Point"), src, f"{where}/Point/UTC_TIME"),
                               epoch_dt) for p in points])
    try:
        return Ephemeris(times, pos, vel, order=8)
    except MetadataError as exc:
        raise MetadataError(f"{src}: {where}: {exc}") from None


def _read_attitude(model, src: str, epoch_dt: np.datetime64, timing: LineTiming, rows: int
                   ) -> QuaternionPolynomial:
    """Q0..Q3 polynomials; OFFSET is in UTC seconds of the day of START, made relative to it."""
    where = f"{SENSOR_MODEL}/Sensor_Attitudes"
    att = _find(model, "Sensor_Attitudes", src, "the attitude", SENSOR_MODEL)
    polys = _find(att, "Polynomial_Models", src, "the attitude quaternion polynomials", where)
    coefficients = [_polynomial(polys, q, src, f"{where}/Polynomial_Models", "an attitude quaternion polynomial")
                     for q in ("Q0", "Q1", "Q2", "Q3")]
    width = max(c.size for c in coefficients)
    table = np.array([np.pad(c, (0, width - c.size)) for c in coefficients])
    day = epoch_dt.astype("datetime64[D]").astype("datetime64[ns]")
    offset = _number(att, "OFFSET", src, where) - _seconds(epoch_dt, day)
    scale = _number(att, "SCALE", src, where)
    t_mid = float(timing.time(np.array([0.5 * rows])))
    if not scale > 0 or abs(t_mid - offset) > scale:
        raise MetadataError(f"{src}: {where}: the polynomial domain OFFSET +- SCALE (UTC seconds of the day) "
                            "does not cover the image acquisition time")
    return QuaternionPolynomial(offset, scale, table)


def _read_look_angles(model, src: str, cols: int) -> Chip:
    """PsiX, PsiY (rad) polynomials in the retina index d = k - 1 (k the 1-based retina column).

    ``Position_In_Retina`` FIRST_COL..LAST_COL is the range of retina columns the model covers;
    image column c (1-based) is retina column FIRST_COL + c - 1, so a product cut across track
    from a wider acquisition keeps the retina's polynomials and starts at its own FIRST_COL. The
    range may be wider than the image (a real Pleiades product's model covers 1..NCOLS+1); one
    narrower than the image, or look angles beyond MAX_LOOK_ANGLE over the image, are refused.
    """
    where = f"{SENSOR_MODEL}/Sensor_Viewing_Model"
    view = _find(model, "Sensor_Viewing_Model", src, "the viewing directions", SENSOR_MODEL)
    first = _number(view, "Position_In_Retina/FIRST_COL", src, where)
    last = _number(view, "Position_In_Retina/LAST_COL", src, where)
    if first != int(first) or last != int(last) or first < 1 or last - first + 1 < cols:
        raise MetadataError(f"{src}: {where}/Position_In_Retina: retina columns {first:g}..{last:g} do not cover "
                            f"the image's {cols} columns (Raster_Dimensions/NCOLS); expected whole column numbers "
                            f"from 1 with LAST_COL - FIRST_COL + 1 >= {cols}")
    shift = np.polynomial.Polynomial([first - 1.0, 1.0])  # retina index of image index c - 1
    psi = {}
    for name in ("PsiX", "PsiY"):
        poly = np.polynomial.Polynomial(_polynomial(view, f"Viewing_Directions/{name}_Model", src, where,
                                                    "a look-angle polynomial"))
        psi[name] = poly(shift).coef if first > 1 else poly.coef
        ends = poly(np.array([first - 1.0, first + cols - 2.0]))
        if not np.all(np.abs(ends) <= MAX_LOOK_ANGLE):
            raise MetadataError(f"{src}: {where}/Viewing_Directions/{name}_Model: look angles {ends[0]:.4g} and "
                                f"{ends[1]:.4g} rad at the image's first and last columns; a pushbroom "
                                f"retina sees within +-{MAX_LOOK_ANGLE} rad of its axis (radians expected)")
    return Chip(col_offset=0.0, n_pixels=cols, kind="look_angle", ux_poly=psi["PsiY"], uy_poly=-psi["PsiX"],
                name="retina")


def _polynomial(parent, path: str, src: str, where: str, what: str) -> np.ndarray:
    """Ascending coefficients of a <DEGREE>/<COEFFICIENTS> polynomial element at path."""
    elem = _find(parent, path, src, what, where)
    full = _join(where, path)
    c = _floats(_text(elem, "COEFFICIENTS", src, full), src, f"{full}/COEFFICIENTS")
    degree = int(_number(elem, "DEGREE", src, full))
    if c.size != degree + 1:
        raise MetadataError(f"{src}: <{full}>: {c.size} coefficients for DEGREE {degree}")
    return c


def _sensor_name(root) -> str:
    name = root.findtext("Data_Strip/Data_Strip_Identification/PLATFORM_NAME", "").strip()
    serial = root.findtext("Data_Strip/Data_Strip_Identification/PLATFORM_SERIAL_NUMBER", "").strip()
    return f"{PLATFORMS.get(name, name)} {serial}".strip() or "Pleiades"


def _ground_sample_distance(scene: SceneModel) -> float:
    """Geometric mean (m) of the ground distances between neighbouring pixel centres (across
    and along track) at the image centre and the middle of the height range."""
    cam = scene.cameras[0]
    c, r = 0.5 * cam.cols, 0.5 * cam.rows
    g = scene.image_to_ground(np.array([c, c + 1.0, c]), np.array([r, r, r + 1.0]), np.mean(scene.height_range))
    gsd = float(np.sqrt(np.linalg.norm(g[1] - g[0]) * np.linalg.norm(g[2] - g[0])))
    if not np.isfinite(gsd):
        raise MetadataError(f"{scene.info['source']}: the image centre's line of sight misses the Earth: "
                            "inconsistent ephemeris, attitude or viewing directions")
    return gsd


# --- element access with clear errors ----------------------------------------------------------
def _find(parent, path: str, src: str, what: str, where: str = ""):
    """Element at ``path`` below parent; MetadataError names the first missing element."""
    elem = parent
    done = where
    for part in path.split("/"):
        elem = elem.find(part)
        done = _join(done, part)
        if elem is None:
            raise MetadataError(f"{src}: <{done}> is missing ({what}); the file is not a complete Pleiades "
                                "DIMAP sensor-geometry product")
    return elem


def _text(parent, path: str, src: str, where: str) -> str:
    found = parent.findall(path)
    full = _join(where, path)
    if not found:
        raise MetadataError(f"{src}: <{full}> is missing")
    if len(found) > 1:
        raise MetadataError(f"{src}: <{full}> appears {len(found)} times; expected once")
    elem = found[0]
    text = (elem.text or "").strip()
    if not text:
        raise MetadataError(f"{src}: <{full}> is empty")
    return text


def _number(parent, path: str, src: str, where: str) -> float:
    text = _text(parent, path, src, where)
    if not _is_number(text):
        raise MetadataError(f"{src}: <{_join(where, path)}>: {text!r} is not a finite number")
    return float(text)


def _join(where: str, path: str) -> str:
    return f"{where}/{path}" if where else path


def _is_number(text) -> bool:
    try:
        return bool(np.isfinite(float(text)))
    except (TypeError, ValueError):
        return False


def _rfm_coefficients(rfm, path: str, src: str) -> np.ndarray:
    """The 40 numbers (20 numerator, 20 denominator) of a Global_RFM F_* list."""
    full = f"{GLOBAL_RFM}/{path}"
    values = _floats(_text(rfm, path, src, GLOBAL_RFM), src, full)
    if values.size != 40:
        raise MetadataError(f"{src}: <{full}>: expected 40 coefficients (20 numerator, 20 denominator), "
                            f"got {values.size}")
    return values


def _utc(text: str, src: str, where: str) -> np.datetime64:
    """UTC 'YYYY-MM-DDTHH:MM:SS.fffffffZ' -> datetime64[ns]."""
    try:
        return np.datetime64(text.strip().rstrip("Z"), "ns")
    except ValueError:
        raise MetadataError(f"{src}: {where}: {text!r} is not a UTC time (expected YYYY-MM-DDTHH:MM:SS.fffZ)") from None


def _seconds(t: np.datetime64, epoch: np.datetime64) -> float:
    """Seconds from epoch to t, exact to the nanosecond before the conversion to float."""
    return float((t - epoch) / np.timedelta64(1, "ns")) * 1e-9
