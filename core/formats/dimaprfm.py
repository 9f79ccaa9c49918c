"""DIMAP rational function models, and the element access the DIMAP readers share.

A Pleiades/SPOT product ships its vendor RFM (``Global_RFM``: an inverse model ground -> image and a
direct model image -> ground, 20-term cubic ratios in the RPC00B monomial order) in one of two layouts:
  - in the DIMAP document (``Geoposition/Rational_Sensor_Model/Global_RFM``, the PHR DIMAP of
    tests/data/pleiades): normalisation ``RFM_Validity/Lon|Lat|Alt|Col|Row`` with A = scale,
    B = offset, coefficients as lists of 40 numbers (20 numerator, 20 denominator) in
    ``Direct_Model/F_LON|F_LAT`` and ``Inverse_Model/F_COL|F_ROW``;
  - in the product's ``RPC_<id>.XML`` beside its ``DIM_<id>.XML`` (DIMAP 2.x, as GDAL reads it,
    gcore/mdreader/reader_pleiades.cpp): normalisation ``RFM_Validity/LONG_OFF, LONG_SCALE, LAT_*,
    HEIGHT_*, SAMP_*, LINE_*``, one element per coefficient ``SAMP_NUM_COEFF_1`` ...
    ``LINE_DEN_COEFF_20`` in ``Inverse_Model`` (DIMAP 3: ``GroundtoImage_Values``); the direct
    model's ``SAMP_*`` coefficients give the longitude and ``LINE_*`` the latitude.
Model coordinates are 1-based pixel centres (``origin`` 1), or, in DIMAP 3, the FIRST_COL of
``ImagetoGround_Validity_Domain`` (GDAL subtracts it from both offsets).
"""
from __future__ import annotations

from pathlib import Path
from xml.etree import ElementTree

import numpy as np

from ..errors import MetadataError
from ..model.rpc import RationalDirectModel, RpcModel
from ..validation import rpc_value_problem
from .vendor_xml import parse_floats, parse_xml

GLOBAL_RFM = "Geoposition/Rational_Sensor_Model/Global_RFM"
# RFM_Validity of the document layout: its elements and the RpcModel fields (<field>_off, <field>_scale) B, A fill
RFM_FIELDS = {"Lon": "lon", "Lat": "lat", "Alt": "height", "Col": "samp", "Row": "line"}
# RFM_Validity of the RPC_*.XML layout: the RpcModel field of each <NAME>_OFF / <NAME>_SCALE
RPC_XML_FIELDS = {"LONG": "lon", "LAT": "lat", "HEIGHT": "height", "SAMP": "samp", "LINE": "line"}
# the coefficient elements of the RPC_*.XML layout (inverse, direct): DIMAP 2 names, then DIMAP 3 names
INVERSE_BLOCKS = ("Inverse_Model", "GroundtoImage_Values")
DIRECT_BLOCKS = ("Direct_Model", "ImagetoGround_Values")


def read_dimap_rfm(path: str | Path, root: ElementTree.Element | None = None
                   ) -> tuple[RpcModel, RationalDirectModel | None]:
    """The vendor's Global_RFM of a DIMAP document or RPC_*.XML, either layout (module docstring):
    (inverse model ground -> image, direct model image -> ground or None when the file has none),
    converted to GDAL (col, row) by the model classes through their ``origin``."""
    src = str(path)
    if root is None:
        root = parse_xml(path)
    rfm = root.find(GLOBAL_RFM) if root.find(GLOBAL_RFM) is not None else root.find(".//Global_RFM")
    if rfm is None:
        raise MetadataError(f"{src}: <{GLOBAL_RFM}> (or <Rational_Function_Model/Global_RFM> in an RPC_*.XML) is "
                            "missing: no vendor rational function model")
    if rfm.find("RFM_Validity/LONG_SCALE") is not None:
        return _rpc_xml_rfm(root, rfm, src)
    return _document_rfm(rfm, src)


def _document_rfm(rfm, src: str) -> tuple[RpcModel, RationalDirectModel]:
    """The Global_RFM of a DIMAP document: RFM_Validity A/B, F_* lists of 40 numbers, origin 1."""
    norm = {}
    for tag, fld in RFM_FIELDS.items():
        where = f"{GLOBAL_RFM}/RFM_Validity/{tag}"
        elem = find_element(rfm, f"RFM_Validity/{tag}", src, "RFM normalisation", GLOBAL_RFM)
        norm[f"{fld}_scale"] = _checked(number(elem, "A", src, where), f"{fld}_scale", src, f"{where}/A", "scale")
        norm[f"{fld}_off"] = _checked(number(elem, "B", src, where), f"{fld}_off", src, f"{where}/B", "offset")
    coef = {tag: _coefficient_list(rfm, path_, src) for tag, path_ in
            (("lon", "Direct_Model/F_LON"), ("lat", "Direct_Model/F_LAT"),
             ("col", "Inverse_Model/F_COL"), ("row", "Inverse_Model/F_ROW"))}
    inverse = RpcModel(line_num=coef["row"][:20], line_den=coef["row"][20:], samp_num=coef["col"][:20],
                       samp_den=coef["col"][20:], **norm, origin=1.0)
    direct = RationalDirectModel(lon_num=coef["lon"][:20], lon_den=coef["lon"][20:], lat_num=coef["lat"][:20],
                                 lat_den=coef["lat"][20:], **norm, origin=1.0)
    return inverse, direct


def _rpc_xml_rfm(root, rfm, src: str) -> tuple[RpcModel, RationalDirectModel | None]:
    """The Global_RFM of an RPC_*.XML: RFM_Validity <NAME>_OFF / _SCALE, one element per coefficient."""
    where = "Global_RFM/RFM_Validity"
    validity = find_element(rfm, "RFM_Validity", src, "RFM normalisation", "Global_RFM")
    norm = {}
    for name, fld in RPC_XML_FIELDS.items():
        for part, word in (("SCALE", "scale"), ("OFF", "offset")):
            key = f"{fld}_{'off' if part == 'OFF' else 'scale'}"
            norm[key] = _checked(number(validity, f"{name}_{part}", src, where), key, src, f"{where}/{name}_{part}",
                                 word)
    domain = root.find(".//ImagetoGround_Validity_Domain")
    origin = 1.0 if domain is None or domain.find("FIRST_COL") is None else \
        number(domain, "FIRST_COL", src, "ImagetoGround_Validity_Domain")
    inverse_block = _first_block(rfm, INVERSE_BLOCKS, src)
    inverse = RpcModel(**{f"{axis}_{part}": _coefficients(inverse_block, f"{axis.upper()}_{part.upper()}_COEFF", src)
                          for axis in ("line", "samp") for part in ("num", "den")}, **norm, origin=origin)
    if not any(rfm.find(b) is not None for b in DIRECT_BLOCKS):
        return inverse, None
    direct_block = _first_block(rfm, DIRECT_BLOCKS, src)
    direct = RationalDirectModel(**{f"{out}_{part}": _coefficients(direct_block, f"{axis}_{part.upper()}_COEFF", src)
                                    for out, axis in (("lon", "SAMP"), ("lat", "LINE")) for part in ("num", "den")},
                                 **norm, origin=origin)
    return inverse, direct


def _first_block(rfm, names: tuple[str, ...], src: str):
    for name in names:
        if rfm.find(name) is not None:
            return rfm.find(name)
    raise MetadataError(f"{src}: <Global_RFM/{names[0]}> (DIMAP 3: <Global_RFM/{names[1]}>) is missing: no "
                        "coefficients of the rational function model")


def _coefficients(block, name: str, src: str) -> np.ndarray:
    """The 20 coefficients <name>_1 ... <name>_20 of an RPC_*.XML block."""
    where = f"Global_RFM/{block.tag}"
    return np.array([number(block, f"{name}_{k}", src, where) for k in range(1, 21)])


def _checked(value: float, fld: str, src: str, where: str, word: str) -> float:
    """An RFM offset or scale, refused when no scene on the Earth has it (core.validation)."""
    problem = rpc_value_problem(fld, value)
    if problem:
        raise MetadataError(f"{src}: <{where}> ({word}) is {value:g}; {problem}")
    return value


def _coefficient_list(rfm, path: str, src: str) -> np.ndarray:
    """The 40 numbers (20 numerator, 20 denominator) of a document Global_RFM F_* list."""
    full = f"{GLOBAL_RFM}/{path}"
    values = parse_floats(text(rfm, path, src, GLOBAL_RFM), src, full)
    if values.size != 40:
        raise MetadataError(f"{src}: <{full}>: expected 40 coefficients (20 numerator, 20 denominator), "
                            f"got {values.size}")
    return values


def rpc_file_of(path: Path, root: ElementTree.Element) -> Path | None:
    """The product's RPC_*.XML beside a DIMAP document: the RPC component it names
    (``COMPONENT_PATH href="RPC_..."``), else ``RPC_<id>.XML`` for a ``DIM_<id>.XML``; None when
    neither exists."""
    named = [e.get("href", "") for e in root.iter("COMPONENT_PATH")]
    candidates = [path.parent / h for h in named if Path(h).name.upper().startswith("RPC_")]
    if path.name.upper().startswith("DIM_"):
        candidates.append(path.with_name("RPC_" + path.name[4:]))
    return next((p for p in candidates if p.is_file()), None)


# --- element access with clear errors ----------------------------------------------------------
def find_element(parent, path: str, src: str, what: str, where: str = ""):
    """Element at ``path`` below parent; MetadataError names the first missing element."""
    elem = parent
    done = where
    for part in path.split("/"):
        elem = elem.find(part)
        done = join(done, part)
        if elem is None:
            raise MetadataError(f"{src}: <{done}> is missing ({what}); the file is not a complete Pleiades "
                                "DIMAP sensor-geometry product")
    return elem


def text(parent, path: str, src: str, where: str) -> str:
    """The text of the one element at ``path``; MetadataError when it is missing, repeated or empty."""
    found = parent.findall(path)
    full = join(where, path)
    if not found:
        raise MetadataError(f"{src}: <{full}> is missing")
    if len(found) > 1:
        raise MetadataError(f"{src}: <{full}> appears {len(found)} times; expected once")
    value = (found[0].text or "").strip()
    if not value:
        raise MetadataError(f"{src}: <{full}> is empty")
    return value


def number(parent, path: str, src: str, where: str) -> float:
    """The finite number of the one element at ``path``."""
    value = text(parent, path, src, where)
    if not is_number(value):
        raise MetadataError(f"{src}: <{join(where, path)}>: {value!r} is not a finite number")
    return float(value)


def join(where: str, path: str) -> str:
    return f"{where}/{path}" if where else path


def is_number(value) -> bool:
    try:
        return bool(np.isfinite(float(value)))
    except (TypeError, ValueError):
        return False
