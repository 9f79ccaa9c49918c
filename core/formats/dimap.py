"""Pleiades/SPOT DIMAP sensor-geometry products: the rigorous sensor model.

Two layouts hold the same model under different names (:data:`LAYOUTS`, one set of paths each):
  - DIMAP 2.0 as in the PHR DIMAP of tests/data/pleiades (``PHR_Dimap_Document``), under
    ``Geometric_Data/Sensor_Model_Characteristics``;
  - DIMAP 2.15 (``Dimap_Document``, DIM_<id>.XML of Airbus' Pleiades Imagery User Guide, as the
    NASA Ames Stereo Pipeline reads it: src/asp/Camera/PleiadesXML.cc), under
    ``Geometric_Data/Refined_Model``.

The model, in the terms of both:
  - START (2.0 ``UTC_Sensor_Model_Range/START``, 2.15 ``Time/Time_Range/START``): UTC time of the
    centre of image row 1; the scene epoch. END bounds the model's time range.
  - line period (``SENSOR_LINE_PERIOD``, ``Time/Time_Stamp/LINE_PERIOD``): milliseconds unless its
    ``unit`` says microseconds; time of row r (1-based) = START + (r - 1) * period.
  - ephemeris (``Sensor_Ephemeris/Point_List``, ``Ephemeris/Point_List``): ECEF positions (m) and
    velocities (m/s) with UTC times, interpolated with 8-point Lagrange windows.
  - attitude (``Sensor_Attitudes`` with ``Polynomial_Models``, ``Attitudes/Polynomial_Quaternions``):
    quaternion polynomials Q0 (scalar part) .. Q3 in u = (t - OFFSET) / SCALE, t in UTC seconds of
    the day of START, rotating the body frame to ECEF.
  - look angles: PsiX, PsiY (rad) as polynomials in (k - 1), k the 1-based retina column (2.0
    ``Viewing_Directions/PsiX_Model`` with DEGREE/COEFFICIENTS; 2.15
    ``Polynomial_Look_Angles/XLOS_0, XLOS_1 ...`` and ``YLOS_0 ...``); image column c is retina
    column FIRST_COL + c - 1 (2.0 ``Position_In_Retina``, 2.15 ``Swath_Range``; the retina range may
    be wider than the image); the body line of sight is (PsiY, -PsiX, 1) with the angles themselves
    (not their tangents), i.e. camera ux = PsiY, uy = -PsiX, installation = identity.
The vendor's RFM (:mod:`core.formats.dimaprfm`: the document's ``Global_RFM`` in 2.0, the product's
``RPC_<id>.XML`` in 2.15) gives the height range and is what the model is checked against on load
(:mod:`core.formats.vendorcheck`).

Vendor conventions converted here: DIMAP pixel coordinates are 1-based pixel centres, so GDAL
col = c - 0.5 and row = r - 0.5. The rigorous model needs neither velocity aberration nor
refraction: the vendor's viewing directions and attitudes already absorb them (the model
meets the vendor's own RFM and localisation grid to a millimetre only with both off; velocity
aberration would move the ground by 18 m, refraction by 0.7-0.8 m in this scene).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from xml.etree import ElementTree

import numpy as np

from ..model.camera import Camera, Chip, LineTiming
from ..errors import MetadataError
from ..model.sensor import SceneModel
from ..model.trajectory import Ephemeris, Platform, QuaternionPolynomial
from .dimaprfm import (GLOBAL_RFM, find_element as _find, is_number as _is_number, join as _join,
                       number as _number, read_dimap_rfm, rpc_file_of, text as _text)
from .vendorcheck import VendorRpc
from .vendor_xml import parse_floats as _floats, parse_xml

PLATFORMS = {"PHR": "Pleiades", "SPOT": "SPOT"}
MAX_LOOK_ANGLE = 0.5  # rad: half the widest field of view a pushbroom retina could have
LINE_PERIOD_UNITS = {"ms": 1e-3, "millisecond": 1e-3, "milliseconds": 1e-3, "microsecond": 1e-6,
                     "microseconds": 1e-6, "us": 1e-6}


@dataclass(frozen=True)
class DimapLayout:
    """Where one DIMAP version keeps the rigorous sensor model: ``model`` and ``raster`` from the
    document's root, the rest below ``model``. ``look_x``/``look_y``: the PsiX/PsiY polynomial
    element (DEGREE, COEFFICIENTS), or with ``look_terms`` the prefix of its coefficient elements
    (XLOS_0, XLOS_1, ...)."""
    version: str
    model: str
    raster: str
    start: str
    end: str
    period: str
    points: str
    location: str
    velocity: str
    time: str
    attitude: str
    quaternions: str
    retina: str
    look_x: str
    look_y: str
    look_terms: bool
    incidence: str


LAYOUTS = (
    DimapLayout("2.0", "Geometric_Data/Sensor_Model_Characteristics", "Raster_Dimensions",
                "UTC_Sensor_Model_Range/START", "UTC_Sensor_Model_Range/END", "SENSOR_LINE_PERIOD",
                "Sensor_Ephemeris/Point_List", "LOCATION_VALUES", "VELOCITY_VALUES", "UTC_TIME",
                "Sensor_Attitudes", "Sensor_Attitudes/Polynomial_Models", "Sensor_Viewing_Model/Position_In_Retina",
                "Sensor_Viewing_Model/Viewing_Directions/PsiX_Model",
                "Sensor_Viewing_Model/Viewing_Directions/PsiY_Model", False,
                "Data_Strip/Geometric_Header_List/Located_Geometric_Header/Incidences/GLOBAL_INCIDENCE"),
    DimapLayout("2.15", "Geometric_Data/Refined_Model", "Raster_Data/Raster_Dimensions",
                "Time/Time_Range/START", "Time/Time_Range/END", "Time/Time_Stamp/LINE_PERIOD",
                "Ephemeris/Point_List", "LOCATION_XYZ", "VELOCITY_XYZ", "TIME",
                "Attitudes/Polynomial_Quaternions", "Attitudes/Polynomial_Quaternions",
                "Geometric_Calibration/Instrument_Calibration/Swath_Range",
                "Geometric_Calibration/Instrument_Calibration/Polynomial_Look_Angles/XLOS_",
                "Geometric_Calibration/Instrument_Calibration/Polynomial_Look_Angles/YLOS_", True,
                "Geometric_Data/Use_Area/Located_Geometric_Values/Acquisition_Angles/INCIDENCE_ANGLE"),
)


def read_dimap(path: str | Path, root: ElementTree.Element) -> tuple[SceneModel, VendorRpc]:
    """SceneModel (one look-angle camera, no aberration or refraction) from a parsed Pleiades
    DIMAP document of either layout, and the vendor RFM to check it against. Raises
    MetadataError naming the missing or malformed element."""
    src, path = str(path), Path(path)
    layout = _layout(root, src)
    model = root.find(layout.model)
    where = layout.model
    start = _utc(_text(model, layout.start, src, where), src, f"{where}/{layout.start}")
    epoch_dt = start.astype("datetime64[us]").astype("datetime64[ns]")  # exactly the epoch string
    epoch = str(np.datetime_as_string(epoch_dt, unit="us")) + "Z"
    rows = int(_number(root, f"{layout.raster}/NROWS", src, ""))
    cols = int(_number(root, f"{layout.raster}/NCOLS", src, ""))
    if rows < 2 or cols < 2:
        raise MetadataError(f"{src}: {layout.raster}: image of {cols} x {rows} pixels is too small")
    timing = _read_timing(model, layout, src, start, epoch_dt, rows)
    band = root.findtext("Image_Interpretation/Spectral_Band_Info/BAND_ID") or root.findtext(".//BAND_ID") or "P"
    camera = Camera(name=band.strip(), cols=cols, rows=rows, timing=timing,
                    chips=[_read_look_angles(model, layout, src, cols)])
    platform = Platform(_read_ephemeris(model, layout, src, epoch_dt),
                        _read_attitude(model, layout, src, epoch_dt, timing, rows))
    vendor = _vendor_rfm(path, root, layout)
    rpc = vendor.rpc
    info = {
        "sensor": _sensor_name(root),
        "product_id": root.findtext("Dataset_Identification/DATASET_NAME", "").strip(),
        "data_strip_id": root.findtext("Data_Strip/Data_Strip_Identification/DATA_STRIP_ID", "").strip(),
        "source": src,
        "format": f"Pleiades DIMAP {layout.version} (sensor geometry)",
        "height_range": [rpc.height_off - rpc.height_scale, rpc.height_off + rpc.height_scale],
    }
    incidence = [float(x.text) for x in root.findall(layout.incidence) if _is_number(x.text)]
    if incidence:
        info["incidence_deg"] = incidence[len(incidence) // 2]
    scene = SceneModel(epoch=epoch, platform=platform, cameras=[camera], aberration=False, refraction=False,
                       info=info)
    scene.info["gsd_m"] = _ground_sample_distance(scene)
    return scene, vendor


def _layout(root, src: str) -> DimapLayout:
    """The layout whose sensor model block the document holds."""
    for layout in LAYOUTS:
        if root.find(layout.model) is not None:
            return layout
    names = " and ".join(f"<{layout.model}> (DIMAP {layout.version})" for layout in LAYOUTS)
    raise MetadataError(f"{src}: {names} are both missing (the rigorous sensor model); the file is not a complete "
                        "Pleiades DIMAP sensor-geometry product")


def _vendor_rfm(path: Path, root, layout: DimapLayout) -> VendorRpc:
    """The vendor RFM: the document's Global_RFM, else the product's RPC_*.XML beside it."""
    if root.find(GLOBAL_RFM) is not None:
        return VendorRpc(read_dimap_rfm(path, root)[0], f"{path.name} (its Global_RFM)")
    rpc_file = rpc_file_of(path, root)
    if rpc_file is None:
        raise MetadataError(f"{path}: no vendor RFM: neither <{GLOBAL_RFM}> in the document nor the product's "
                            f"RPC_*.XML beside it (looked for the RPC component it names and "
                            f"{'RPC_' + path.name[4:] if path.name.upper().startswith('DIM_') else 'RPC_<id>.XML'}"
                            f" in {path.parent}); DIMAP {layout.version} products ship one: it gives the height "
                            "range and checks the rigorous model")
    return VendorRpc(read_dimap_rfm(rpc_file, parse_xml(rpc_file))[0], str(rpc_file))


# --- blocks of the sensor model --------------------------------------------------------------
def _read_timing(model, layout: DimapLayout, src: str, start: np.datetime64, epoch_dt: np.datetime64,
                 rows: int) -> LineTiming:
    """Row r (1-based) is seen at START + (r - 1) * period, i.e. GDAL row r - 0.5: so t0 is
    START in seconds from the epoch (START to the microsecond)."""
    where = f"{layout.model}/{layout.period}"
    unit = model.find(layout.period).get("unit", "ms") if model.find(layout.period) is not None else "ms"
    if unit.strip().lower() not in LINE_PERIOD_UNITS:
        raise MetadataError(f"{src}: <{where}> is in {unit!r}; expected milliseconds (ms) or microseconds")
    scale = LINE_PERIOD_UNITS[unit.strip().lower()]
    period = _number(model, layout.period, src, layout.model) * scale
    if not period > 0:
        raise MetadataError(f"{src}: {where} must be positive (got {period / scale} {unit})")
    end_text = model.findtext(layout.end)
    if end_text:
        span = _seconds(_utc(end_text, src, f"{layout.model}/{layout.end}"), start)
        if abs(rows * period - span) > 0.05 * span:
            raise MetadataError(f"{src}: {where} ({period / scale:g} {unit}, read in "
                                f"{'milliseconds' if scale == 1e-3 else 'microseconds'}) times {rows} rows does not "
                                f"match the model time range ({span:.3f} s)")
    return LineTiming(t0=_seconds(start, epoch_dt), period=period)


def _read_ephemeris(model, layout: DimapLayout, src: str, epoch_dt: np.datetime64) -> Ephemeris:
    where = f"{layout.model}/{layout.points}"
    points = _find(model, layout.points, src, "the ephemeris", layout.model).findall("Point")
    if len(points) < 8:
        raise MetadataError(f"{src}: {where} holds {len(points)} <Point> samples; 8 are needed for the "
                            "Lagrange interpolation of the orbit")
    for tag, unit in ((layout.location, "m"), (layout.velocity, "m/s")):
        units = {p.find(tag).get("unit", unit) for p in points if p.find(tag) is not None}
        if units - {unit}:
            raise MetadataError(f"{src}: {where}/Point/{tag} is in {sorted(units)}, expected {unit!r}")
    pos, vel = (np.array([_floats(_text(p, tag, src, f"{where}/Point"), src, f"{where}/Point/{tag}", 3)[:3]
                          for p in points]) for tag in (layout.location, layout.velocity))
    times = np.array([_seconds(_utc(_text(p, layout.time, src, f"{where}/Point"), src,
                                    f"{where}/Point/{layout.time}"), epoch_dt) for p in points])
    try:
        return Ephemeris(times, pos, vel, order=8)
    except MetadataError as exc:
        raise MetadataError(f"{src}: {where}: {exc}") from None


def _read_attitude(model, layout: DimapLayout, src: str, epoch_dt: np.datetime64, timing: LineTiming, rows: int
                   ) -> QuaternionPolynomial:
    """Q0..Q3 polynomials; OFFSET is in UTC seconds of the day of START, made relative to it."""
    where = f"{layout.model}/{layout.attitude}"
    att = _find(model, layout.attitude, src, "the attitude", layout.model)
    polys = _find(model, layout.quaternions, src, "the attitude quaternion polynomials", layout.model)
    coefficients = [_polynomial(polys, q, src, f"{layout.model}/{layout.quaternions}",
                                "an attitude quaternion polynomial") for q in ("Q0", "Q1", "Q2", "Q3")]
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


def _read_look_angles(model, layout: DimapLayout, src: str, cols: int) -> Chip:
    """PsiX, PsiY (rad) polynomials in the retina index d = k - 1 (k the 1-based retina column).

    The retina range FIRST_COL..LAST_COL (``Position_In_Retina``, ``Swath_Range``) holds the
    retina columns the model covers; image column c (1-based) is retina column FIRST_COL + c - 1,
    so a product cut across track from a wider acquisition keeps the retina's polynomials and
    starts at its own FIRST_COL. The range may be wider than the image (a real Pleiades product's
    model covers 1..NCOLS+1); without LAST_COL it is taken to end with the image. One narrower than
    the image, or look angles beyond MAX_LOOK_ANGLE over the image, are refused.
    """
    where = f"{layout.model}/{layout.retina}"
    retina = _find(model, layout.retina, src, "the retina columns of the model", layout.model)
    first = _number(retina, "FIRST_COL", src, where)
    last = _number(retina, "LAST_COL", src, where) if retina.find("LAST_COL") is not None else first + cols - 1
    if first != int(first) or last != int(last) or first < 1 or last - first + 1 < cols:
        raise MetadataError(f"{src}: {where}: retina columns {first:g}..{last:g} do not cover "
                            f"the image's {cols} columns ({layout.raster}/NCOLS); expected whole column numbers "
                            f"from 1 with LAST_COL - FIRST_COL + 1 >= {cols}")
    shift = np.polynomial.Polynomial([first - 1.0, 1.0])  # retina index of image index c - 1
    psi = {}
    for name, element in (("PsiX", layout.look_x), ("PsiY", layout.look_y)):
        full = f"{layout.model}/{element}{'*' if layout.look_terms else ''}"  # XLOS_* of 2.15
        poly = np.polynomial.Polynomial(_look_terms(model, element, src, layout.model) if layout.look_terms else
                                        _polynomial(model, element, src, layout.model, "a look-angle polynomial"))
        psi[name] = poly(shift).coef if first > 1 else poly.coef
        ends = poly(np.array([first - 1.0, first + cols - 2.0]))
        if not np.all(np.abs(ends) <= MAX_LOOK_ANGLE):
            raise MetadataError(f"{src}: {full}: look angles {ends[0]:.4g} and "
                                f"{ends[1]:.4g} rad at the image's first and last columns; a pushbroom "
                                f"retina sees within +-{MAX_LOOK_ANGLE} rad of its axis (radians expected)")
    return Chip(col_offset=0.0, n_pixels=cols, kind="look_angle", ux_poly=psi["PsiY"], uy_poly=-psi["PsiX"],
                name="retina")


def _look_terms(model, prefix: str, src: str, where: str) -> np.ndarray:
    """Ascending coefficients of a DIMAP 2.15 look angle: the elements <prefix>0, <prefix>1, ...
    (XLOS_0, XLOS_1) of its parent, in order; at least <prefix>0."""
    parent_path, _, stem = prefix.rpartition("/")
    parent = _find(model, parent_path, src, "the look angles", where)
    values = []
    while parent.find(f"{stem}{len(values)}") is not None:
        values.append(_number(parent, f"{stem}{len(values)}", src, f"{where}/{parent_path}"))
    if not values:
        raise MetadataError(f"{src}: <{where}/{parent_path}/{stem}0> is missing (a look-angle coefficient)")
    return np.array(values)


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
    """'Pleiades 1B' from the 2.0 data strip's platform, or the 2.15 source's MISSION and MISSION_INDEX."""
    name = (root.findtext("Data_Strip/Data_Strip_Identification/PLATFORM_NAME")
            or root.findtext(".//Strip_Source/MISSION") or "").strip()
    serial = (root.findtext("Data_Strip/Data_Strip_Identification/PLATFORM_SERIAL_NUMBER")
              or root.findtext(".//Strip_Source/MISSION_INDEX") or "").strip()
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


def _utc(text: str, src: str, where: str) -> np.datetime64:
    """UTC 'YYYY-MM-DDTHH:MM:SS.fffffffZ' -> datetime64[ns]."""
    try:
        return np.datetime64(text.strip().rstrip("Z"), "ns")
    except ValueError:
        raise MetadataError(f"{src}: {where}: {text!r} is not a UTC time (expected YYYY-MM-DDTHH:MM:SS.fffZ)") from None


def _seconds(t: np.datetime64, epoch: np.datetime64) -> float:
    """Seconds from epoch to t, exact to the nanosecond before the conversion to float."""
    return float((t - epoch) / np.timedelta64(1, "ns")) * 1e-9
