"""Vendor products the format documents allow, written in the tests from the real products of
tests/data (their derivation is in tests/data/README.md, "Products derived in the tests"):

- :func:`geoeye_like`: the WorldView-1 product as a GeoEye-1 product writes its focal plane:
  SATID GE01, DETROTANGLE 3.141592653589793 (180 degrees, in radians, as a GeoEye-1 ISD 28.3
  product writes it), with the same detector positions: the camera frame turned by 180 degrees
  about its z axis (CAMERA_ATTITUDE) and DETORIGINX/Y negated. The model is the same.
- :func:`reverse_scan`: the product's image rows flipped (row' = N - 1 - row): TLC times decreasing
  with the line, SCANDIRECTION Reverse, FIRSTLINETIME the time of the new first line, the IMD corners
  swapped top/bottom, and the RPB rewritten exactly (LINEOFFSET' = N - 1 - LINEOFFSET, the line
  numerator negated).
- :func:`write_dimap215`: the Pleiades DIMAP 2.0 product's rigorous model under the DIMAP 2.15 names
  (DIM_<id>.XML, element texts copied unchanged) and its Global_RFM as the product's RPC_<id>.XML
  (the RPC_*.XML layout GDAL reads, coefficients copied unchanged).
"""
from __future__ import annotations

from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np

DETROTANGLE = "GEO/DETECTOR_MOUNTING/BAND_P/DETECTOR_ARRAY/DETROTANGLE"


def edited(path: Path, edit) -> str:
    """The XML text of ``path`` after ``edit`` (a function changing the parsed root in place)."""
    root = ET.parse(str(path)).getroot()
    edit(root)
    return ET.tostring(root, encoding="unicode")


def set_text(root, path: str, value) -> None:
    """Set the text of every element at ``path`` (at least one)."""
    found = root.findall(path)
    assert found, path
    for elem in found:
        elem.text = value if isinstance(value, str) else repr(float(value))


def geoeye_like(root) -> None:
    """The WorldView-1 focal plane as GeoEye-1 writes it (module docstring); the source's detector
    rotation must be 0 and its camera attitude the identity."""
    array = root.find("GEO/DETECTOR_MOUNTING/BAND_P/DETECTOR_ARRAY")
    assert float(array.findtext("DETROTANGLE")) == 0.0
    attitude = root.find("GEO/CAMERA_ATTITUDE")
    assert [float(attitude.findtext(k)) for k in ("QCS1", "QCS2", "QCS3", "QCS4")] == [0.0, 0.0, 0.0, 1.0]
    for key, value in zip(("QCS1", "QCS2", "QCS3", "QCS4"), (0.0, 0.0, 1.0, 0.0)):  # 180 deg about z, scalar last
        set_text(attitude, key, value)
    for key in ("DETORIGINX", "DETORIGINY"):
        set_text(array, key, -float(array.findtext(key)))
    set_text(array, "DETROTANGLE", "3.141592653589793")
    for elem in root.iter("SATID"):
        elem.text = "GE01"


def reverse_scan(root) -> None:
    """The image rows flipped (module docstring)."""
    rows = int(root.findtext("IMD/NUMROWS"))
    image = root.find("IMD/IMAGE")
    table = np.array([[float(v) for v in e.text.split()[:2]] for e in image.find("TLCLISTList").findall("TLCLIST")])
    flipped = np.c_[rows - 1.0 - table[:, 0], table[:, 1]][::-1]
    for elem, (line, t) in zip(image.find("TLCLISTList").findall("TLCLIST"), flipped):
        elem.text = f"{line!r} {t!r}"
    set_text(image, "SCANDIRECTION", "Reverse")
    first = np.interp(rows - 1.0, table[:, 0], table[:, 1])  # the old time of the new first line
    tlc = np.datetime64(image.findtext("TLCTIME").rstrip("Z"), "ns")
    set_text(image, "FIRSTLINETIME", f"{np.datetime_as_string(tlc + np.timedelta64(round(first * 1e9), 'ns'))}Z")
    band = root.find("IMD/BAND_P")
    for top, bottom in (("UL", "LL"), ("UR", "LR")):
        for part in ("LON", "LAT", "HAE"):
            a, b = band.find(top + part), band.find(bottom + part)
            a.text, b.text = b.text, a.text
    rpb = root.find("RPB/IMAGE")
    set_text(rpb, "LINEOFFSET", rows - 1.0 - float(rpb.findtext("LINEOFFSET")))
    coef = rpb.find("LINENUMCOEFList/LINENUMCOEF")
    coef.text = " ".join(repr(-float(v)) for v in coef.text.split())


def rotated_camera(degrees: float):
    """An edit turning the camera frame by ``degrees`` about its z axis (a yaw error of the
    installation): CAMERA_ATTITUDE, from the identity."""
    def edit(root) -> None:
        half = np.radians(degrees) / 2.0
        attitude = root.find("GEO/CAMERA_ATTITUDE")
        for key, value in zip(("QCS1", "QCS2", "QCS3", "QCS4"), (0.0, 0.0, np.sin(half), np.cos(half))):
            set_text(attitude, key, value)
    return edit


# --- DIMAP 2.15 --------------------------------------------------------------------------------
MODEL_20 = "Geometric_Data/Sensor_Model_Characteristics"


def write_dimap215(source: Path, folder: Path, product_id: str = "PHR1B_P_201812261048554_SEN_TEST-001",
                   line_period: tuple[str, float] = ("ms", 1.0)) -> tuple[Path, Path]:
    """DIM_<id>.XML and RPC_<id>.XML in ``folder``: the DIMAP 2.0 product ``source`` under the
    DIMAP 2.15 names (module docstring). ``line_period``: (unit attribute, factor on the 2.0 value
    in milliseconds), e.g. ("microsecond", 1000.0)."""
    old = ET.parse(str(source)).getroot()
    model = old.find(MODEL_20)
    dim, rpc = folder / f"DIM_{product_id}.XML", folder / f"RPC_{product_id}.XML"
    root = ET.Element("Dimap_Document")
    meta = _sub(root, "Metadata_Identification")
    _sub(meta, "METADATA_FORMAT", "DIMAP", version="2.15")
    _sub(meta, "METADATA_PROFILE", "PHR_SENSOR")
    _sub(meta, "METADATA_SUBPROFILE", "PRODUCT")
    _sub(_sub(root, "Dataset_Identification"), "DATASET_NAME", old.findtext("Dataset_Identification/DATASET_NAME"))
    component = _sub(_sub(_sub(root, "Dataset_Content"), "Dataset_Components"), "Component")
    _sub(component, "COMPONENT_TITLE", "RPC Model")
    _sub(component, "COMPONENT_PATH", href=rpc.name)
    strip = _sub(_sub(_sub(root, "Dataset_Sources"), "Source_Identification"), "Strip_Source")
    _sub(strip, "MISSION", old.findtext("Data_Strip/Data_Strip_Identification/PLATFORM_NAME"))
    _sub(strip, "MISSION_INDEX", old.findtext("Data_Strip/Data_Strip_Identification/PLATFORM_SERIAL_NUMBER"))
    dims = _sub(_sub(root, "Raster_Data"), "Raster_Dimensions")
    for key in ("NROWS", "NCOLS", "NBANDS"):
        _sub(dims, key, old.findtext(f"Raster_Dimensions/{key}"))
    refined = _sub(_sub(root, "Geometric_Data"), "Refined_Model")
    time = _sub(refined, "Time")
    time_range = _sub(time, "Time_Range")
    for key in ("START", "END"):
        _sub(time_range, key, model.findtext(f"UTC_Sensor_Model_Range/{key}"))
    unit, factor = line_period
    period = model.findtext("SENSOR_LINE_PERIOD")
    _sub(_sub(time, "Time_Stamp"), "LINE_PERIOD", period if factor == 1.0 else repr(float(period) * factor), unit=unit)
    points = _sub(_sub(refined, "Ephemeris"), "Point_List")
    for point in model.findall("Sensor_Ephemeris/Point_List/Point"):
        new = _sub(points, "Point")
        _sub(new, "LOCATION_XYZ", point.findtext("LOCATION_VALUES"), unit="m")
        _sub(new, "VELOCITY_XYZ", point.findtext("VELOCITY_VALUES"), unit="m/s")
        _sub(new, "TIME", point.findtext("UTC_TIME"))
    quaternions = _sub(_sub(refined, "Attitudes"), "Polynomial_Quaternions")
    for key in ("OFFSET", "SCALE"):
        _sub(quaternions, key, model.findtext(f"Sensor_Attitudes/{key}"))
    for q in ("Q0", "Q1", "Q2", "Q3"):
        poly = _sub(quaternions, q)
        for key in ("DEGREE", "COEFFICIENTS"):
            _sub(poly, key, model.findtext(f"Sensor_Attitudes/Polynomial_Models/{q}/{key}"))
    calibration = _sub(_sub(refined, "Geometric_Calibration"), "Instrument_Calibration")
    swath = _sub(calibration, "Swath_Range")
    for key in ("FIRST_COL", "LAST_COL"):
        _sub(swath, key, model.findtext(f"Sensor_Viewing_Model/Position_In_Retina/{key}"))
    look = _sub(calibration, "Polynomial_Look_Angles")
    for axis, name in (("XLOS", "PsiX"), ("YLOS", "PsiY")):
        for k, value in enumerate(model.findtext(f"Sensor_Viewing_Model/Viewing_Directions/{name}_Model/"
                                                 "COEFFICIENTS").split()):
            _sub(look, f"{axis}_{k}", value)
    dim.write_text(ET.tostring(root, encoding="unicode"))
    rpc.write_text(rpc_xml(old))
    return dim, rpc


def rpc_xml(document) -> str:
    """The Global_RFM of a DIMAP 2.0 document as an RPC_*.XML (RFM_Validity <NAME>_OFF/_SCALE,
    one element per coefficient; the direct model's SAMP_* are its F_LON, LINE_* its F_LAT)."""
    rfm = document.find("Geoposition/Rational_Sensor_Model/Global_RFM")
    root = ET.Element("Dimap_Document")
    meta = _sub(root, "Metadata_Identification")
    _sub(meta, "METADATA_FORMAT", "DIMAP", version="2.15")
    _sub(meta, "METADATA_SUBPROFILE", "RPC")
    out = _sub(_sub(root, "Rational_Function_Model"), "Global_RFM")
    for block, lists in (("Direct_Model", (("SAMP", "F_LON"), ("LINE", "F_LAT"))),
                         ("Inverse_Model", (("SAMP", "F_COL"), ("LINE", "F_ROW")))):
        new = _sub(out, block)
        for axis, name in lists:
            values = rfm.findtext(f"{block}/{name}").split()
            assert len(values) == 40
            for part, chunk in (("NUM", values[:20]), ("DEN", values[20:])):
                for k, value in enumerate(chunk, 1):
                    _sub(new, f"{axis}_{part}_COEFF_{k}", value)
    validity = _sub(out, "RFM_Validity")
    domain = _sub(validity, "Direct_Model_Validity_Domain")
    for key in ("FIRST_ROW", "FIRST_COL", "LAST_ROW", "LAST_COL"):
        _sub(domain, key, rfm.findtext(f"RFM_Validity/Direct_Model_Validity_Domain/{key}"))
    for name, tag in (("LONG", "Lon"), ("LAT", "Lat"), ("HEIGHT", "Alt"), ("SAMP", "Col"), ("LINE", "Row")):
        _sub(validity, f"{name}_SCALE", rfm.findtext(f"RFM_Validity/{tag}/A"))
        _sub(validity, f"{name}_OFF", rfm.findtext(f"RFM_Validity/{tag}/B"))
    return ET.tostring(root, encoding="unicode")


def _sub(parent, tag: str, text: str | None = None, **attrib):
    elem = ET.SubElement(parent, tag, attrib)
    if text is not None:
        elem.text = text
    return elem
