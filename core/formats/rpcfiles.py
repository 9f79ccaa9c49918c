"""RPC files: reading an RPC scene from GDAL's RPC metadata of an image, a ``_RPC.TXT``, an
``.RPB`` or a DIMAP ``RPC_*.XML``, and writing an RPC00B model as those files (or into a GeoTIFF's
RPC tag, or a VRT showing an image with it).

Conventions: GDAL's 'RPC' metadata domain (keys LINE_OFF ... HEIGHT_SCALE and the four *_COEFF
lists of 20 numbers); its model coordinates (sample, line) are 0 at the CENTRE of the first
pixel: sample = col - 0.5, line = row - 0.5 in GDAL image coordinates (:class:`core.model.rpc.RpcModel`
with ``origin`` = 0). Ground: longitude, latitude (degrees, WGS84), ellipsoidal height (m).
"""
from __future__ import annotations

import json
import math
import os
import re
from pathlib import Path
from xml.etree import ElementTree

import numpy as np
from osgeo import gdal

from ..errors import InputError, MetadataError
from ..files import OutputSet, check_closed, closing_errors, output_set, write_text
from ..rasters import copy_statistics, open_input_raster
from ..model.rpc import RpcModel
from ..validation import rpc_value_problem
from ..model.rpcscene import RpcCamera, RpcScene, check_image_domain, size_from_rpc
from .dimaprfm import read_dimap_rfm
from .vendor_xml import parse_xml

gdal.UseExceptions()

# GDAL's RPC metadata keys of the offsets and scales, the RpcModel fields they fill and their units
RPC_KEYS = ("LINE_OFF", "SAMP_OFF", "LAT_OFF", "LONG_OFF", "HEIGHT_OFF", "LINE_SCALE", "SAMP_SCALE",
            "LAT_SCALE", "LONG_SCALE", "HEIGHT_SCALE")
RPC_FIELDS = ("line_off", "samp_off", "lat_off", "lon_off", "height_off", "line_scale", "samp_scale",
              "lat_scale", "lon_scale", "height_scale")
RPC_UNITS = ("pixels", "pixels", "degrees", "degrees", "meters", "pixels", "pixels", "degrees", "degrees", "meters")
# the coefficient lists: (metadata key, RpcModel field)
RPC_COEFFS = (("LINE_NUM_COEFF", "line_num"), ("LINE_DEN_COEFF", "line_den"), ("SAMP_NUM_COEFF", "samp_num"),
              ("SAMP_DEN_COEFF", "samp_den"))
# the same in an .RPB file, in its order: its names of the offsets and scales, then of the lists
RPB_SCALARS = ("lineOffset", "sampOffset", "latOffset", "longOffset", "heightOffset", "lineScale", "sampScale",
               "latScale", "longScale", "heightScale")
RPB_COEFFS = ("lineNumCoef", "lineDenCoef", "sampNumCoef", "sampDenCoef")
RPB_NAMES = {**dict(zip(RPB_SCALARS, RPC_KEYS)), **dict(zip(RPB_COEFFS, (key for key, _ in RPC_COEFFS)))}
# rasters GDAL pairs with an _RPC.TXT or .RPB beside them
IMAGE_SUFFIXES = (".tif", ".tiff", ".ntf", ".jp2", ".img", ".vrt")
RPC_TXT_SUFFIX = "_RPC.TXT"  # GDAL's RPC sidecar of <name>.tif: <name>_RPC.TXT


# --- reading -----------------------------------------------------------------------------------
def rpc_from_metadata(md: dict, source: str) -> RpcModel:
    """RpcModel (origin 0) of GDAL 'RPC' metadata (keys LINE_OFF..., coefficient lists as text
    of 20 numbers or lists); MetadataError naming ``source`` and the key when one is missing,
    not a finite number, or an offset or scale is beyond any scene on the Earth
    (core.validation.PLAUSIBLE_RPC)."""
    values = {}
    for key, fld in zip(RPC_KEYS, RPC_FIELDS):
        if key not in md or str(md[key]).strip() == "":
            raise MetadataError(f"{source}: {key} is missing")
        values[fld] = _number(md[key], source, key)
        problem = rpc_value_problem(fld, values[fld])
        if problem:
            raise MetadataError(f"{source}: {key} is {md[key]!r}; {problem}")
    for key, fld in RPC_COEFFS:
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


def is_rpc_text(path: Path, head: bytes) -> bool:
    """Whether a file is an RPC text (``_RPC.TXT`` / ``.RPB`` layout), by name or first line."""
    name = path.name.upper()
    return name.endswith(("_RPC.TXT", ".RPB")) or head.upper().startswith((b"LINE_OFF", b"SATID"))


def image_stem(path) -> str:
    """The stem of the image GDAL pairs an RPC file with: ``<name>`` of ``<name>_RPC.TXT`` (any case)
    or of ``<name>.RPB``; '' for a file named ``_RPC.TXT`` alone."""
    path = Path(path)
    return path.name[:-len(RPC_TXT_SUFFIX)] if path.name.upper().endswith(RPC_TXT_SUFFIX) else path.stem


def image_name(path) -> str:
    """The name of the image an RPC file describes (a scene's name): :func:`image_stem`, or for a
    file with nothing before the suffix (``_RPC.TXT``) the name of its folder."""
    path = Path(path)
    return image_stem(path) or path.resolve().parent.name or path.stem


def read_rpc_text(path: Path) -> RpcScene:
    """The RPC scene of a ``_RPC.TXT`` or ``.RPB`` file; the image size from an image beside it
    that GDAL would pair with it, else from the RPC's line/sample range (with a warning saying
    the size assumed and where the image was looked for, also kept for the refusal of an image of
    another size: :func:`core.model.rpcscene.size_note`)."""
    try:
        text = path.read_text(encoding="utf-8-sig", errors="strict")
    except UnicodeDecodeError:
        raise MetadataError(f"{path}: not a text RPC file (not UTF-8/ASCII text)") from None
    md = parse_rpb(text) if ("BEGIN_GROUP" in text.upper() or path.suffix.upper() == ".RPB") else parse_rpc_txt(text)
    rpc = rpc_from_metadata(md, str(path))
    stem = image_stem(path)
    image = next((p for p in sorted(path.parent.glob(stem + ".*")) if p.suffix.lower() in IMAGE_SUFFIXES), None)
    warnings, assumed = [], ""
    if image is not None:
        cols, rows = _raster_size(image)
    else:
        cols, rows = size_from_rpc(rpc)
        assumed = (f"taken from the RPC's sample/line range, as no image was found beside {path.name} (looked for "
                   f"{stem}{', '.join(IMAGE_SUFFIXES)} in {path.parent})")
        warnings.append(f"its image's size {cols} x {rows} px is {assumed}; an image of another size given with "
                        "this scene is refused: put the image beside its RPC file")
    check_image_domain(rpc, cols, rows, str(image or path))
    info = {"source": str(path), "image": str(image) if image else None, "warnings": warnings}
    return RpcScene(rpc, RpcCamera(image_name(path), cols, rows, size_source=assumed), info=info)


def _raster_size(path: Path) -> tuple[int, int]:
    try:
        ds = open_input_raster(path)
    except RuntimeError as exc:
        raise MetadataError(f"{path}: cannot be opened as a raster ({exc})") from None
    return ds.RasterXSize, ds.RasterYSize


def read_rpc_image(path: Path) -> RpcScene | None:
    """The RPC scene of a raster GDAL reads with RPC metadata (tags, ``_RPC.TXT`` or ``.RPB``
    beside it); None when GDAL cannot open it or it has no RPC."""
    try:
        ds = open_input_raster(path)
    except RuntimeError:
        return None
    md = ds.GetMetadata("RPC") or {}
    if not md:
        return None
    rpc = rpc_from_metadata(md, f"{path} (RPC metadata)")
    check_image_domain(rpc, ds.RasterXSize, ds.RasterYSize, str(path))
    info = {"source": str(path), "image": str(path), "warnings": []}
    return RpcScene(rpc, RpcCamera(path.stem, ds.RasterXSize, ds.RasterYSize), info=info)


def read_dimap_rpc(path: Path, root) -> RpcScene:
    """The RPC scene of a DIMAP ``RPC_<id>.XML`` (the vendor's Global_RFM inverse model, either
    layout of :mod:`core.formats.dimaprfm`). The image size is the product's: Raster_Dimensions of
    its ``DIM_<id>.XML`` beside it (DIMAP 2.x: under Raster_Data), else the size of its single
    image tile ``IMG_<id>_R1C1.*`` beside it; else it is assumed from the RFM's direct-model
    validity domain (LAST_COL, LAST_ROW) or its sample/line range, with a warning saying so and where
    the product was looked for."""
    rpc, _ = read_dimap_rfm(path, root)
    product_id = path.stem[4:]
    dim, tiles = path.with_name(f"DIM_{product_id}.XML"), sorted(path.parent.glob(f"IMG_{product_id}_R*C*.*"))
    warnings, assumed = [], ""
    if dim.is_file():
        cols, rows = _dimap_size(dim)
    elif len(tiles) == 1 and tiles[0].suffix.lower() in IMAGE_SUFFIXES:
        cols, rows = _raster_size(tiles[0])
    else:
        domain = root.find(".//Direct_Model_Validity_Domain")
        try:
            cols, rows = int(domain.findtext("LAST_COL")), int(domain.findtext("LAST_ROW"))
            what = "the RFM's direct-model validity domain (LAST_COL, LAST_ROW)"
        except (AttributeError, TypeError, ValueError):
            cols, rows = size_from_rpc(rpc)
            what = "the RFM's sample/line range"
        assumed = (f"taken from {what}, as neither {dim.name} nor a single image tile IMG_{product_id}_R1C1.* was "
                   f"found beside {path.name} in {path.parent}")
        warnings.append(f"its image's size {cols} x {rows} px is {assumed}; an image of another size given with "
                        "this scene is refused: keep the RPC file with its product")
    check_image_domain(rpc, cols, rows, str(path))
    return RpcScene(rpc, RpcCamera(path.stem, cols, rows, size_source=assumed),
                    info={"source": str(path), "warnings": warnings})


def _dimap_size(path: Path) -> tuple[int, int]:
    """(NCOLS, NROWS) of a DIMAP document's Raster_Dimensions (at its root, or under Raster_Data)."""
    root = parse_xml(path)
    dims = root.find("Raster_Data/Raster_Dimensions")
    dims = root.find("Raster_Dimensions") if dims is None else dims
    try:
        return int(dims.findtext("NCOLS")), int(dims.findtext("NROWS"))
    except (AttributeError, TypeError, ValueError):
        raise MetadataError(f"{path}: Raster_Dimensions/NCOLS and NROWS (the image size) are missing or not whole "
                            "numbers") from None


# --- writing -----------------------------------------------------------------------------------
def rpc_metadata(rpc: RpcModel) -> dict:
    """GDAL's 'RPC' metadata domain (string values) of a model (origin converted to 0)."""
    # GDAL's model coordinates are 0 at the first pixel's centre: move other origins there
    values = dict(line_off=rpc.line_off - rpc.origin, samp_off=rpc.samp_off - rpc.origin)
    md = {}
    for key, fld in zip(RPC_KEYS, RPC_FIELDS):
        md[key] = repr(float(values.get(fld, getattr(rpc, fld))))
    for key, fld in RPC_COEFFS:
        md[key] = " ".join(repr(float(v)) for v in getattr(rpc, fld))
    return md


def rpc_txt(rpc: RpcModel) -> str:
    """The model as GDAL's ``_RPC.TXT`` text (the DigitalGlobe "KEY: value units" layout)."""
    md = rpc_metadata(rpc)
    lines = [f"{key}: {md[key]} {unit}" for key, unit in zip(RPC_KEYS, RPC_UNITS)]
    for key, _ in RPC_COEFFS:
        lines += [f"{key}_{i + 1}: {v}" for i, v in enumerate(md[key].split())]
    return "\n".join(lines) + "\n"


def rpc_rpb(rpc: RpcModel, sat_id: str = "PUSHBROOM") -> str:
    """The model as an ``.RPB`` file (the RPC00B keyword layout that GDAL reads)."""
    md = rpc_metadata(rpc)
    out = [f'satId = "{sat_id}";', 'bandId = "P";', 'SpecId = "RPC00B";', "BEGIN_GROUP = IMAGE",
           "\terrBias = -1.0;", "\terrRand = -1.0;"]
    out += [f"\t{n} = {md[k]};" for n, k in zip(RPB_SCALARS, RPC_KEYS)]
    for n, (key, _) in zip(RPB_COEFFS, RPC_COEFFS):
        vals = md[key].split()
        out.append(f"\t{n} = (")
        out += [f"\t\t\t{v}," for v in vals[:-1]] + [f"\t\t\t{vals[-1]});"]
    out += ["END_GROUP = IMAGE", "END;"]
    return "\n".join(out) + "\n"


def write_rpc(rpc: RpcModel, path, report: dict | None = None, files: OutputSet | None = None) -> Path:
    """Write the model to ``path``: ``.RPB`` -> RPB layout, anything else (``*_RPC.TXT``) -> GDAL's
    RPC text layout. GDAL reads it for an image ``<name>.<ext>`` in the same folder when the file
    is called ``<name>_RPC.TXT`` or ``<name>.RPB``. With ``report``, also writes it as JSON to
    ``<path>.json``. Both files are renamed into place only when both are written, so a failure
    leaves nothing behind (with ``files``, they are part of that set, committed by its owner)."""
    path = Path(path)
    with output_set(files) as out:
        write_text(path, rpc_rpb(rpc) if path.suffix.lower() == ".rpb" else rpc_txt(rpc), out, encoding="ascii")
        if report is not None:
            write_text(report_path(path), json.dumps(report, indent=2), out)
    return path


def report_path(path) -> Path:
    """Where :func:`write_rpc` puts the fit report of an RPC file: ``<path>.json``."""
    return Path(f"{path}.json")


def sidecar_path(image, kind: str = "txt") -> Path:
    """Where GDAL looks for an image's RPC file: ``<stem>_RPC.TXT`` (kind 'txt') or ``<stem>.RPB``."""
    image = Path(image)
    return image.with_name(image.stem + ("_RPC.TXT" if kind == "txt" else ".RPB"))


def set_geotiff_rpc(rpc: RpcModel, tif_path) -> None:
    """Store the model in a GeoTIFF's RPC tag (GDAL metadata domain 'RPC'), IN PLACE.

    Only for files the caller owns (an output or a copy): never point it at a user's input."""
    try:
        ds = gdal.Open(str(tif_path), gdal.GA_Update)
    except RuntimeError as exc:
        raise InputError(f"cannot open {tif_path} for update: {exc}") from None
    if ds.GetDriver().ShortName != "GTiff":
        raise InputError(f"{tif_path} is not a GeoTIFF; write an _RPC.TXT or .RPB beside it instead")
    ds.SetMetadata(rpc_metadata(rpc), "RPC")
    with closing_errors() as closing:
        ds = None  # closes the file, writing the tag: GDAL's error then (a full disk) is kept, not printed
    check_closed(tif_path, closing)


def image_vrt_with_rpc(rpc: RpcModel, image, vrt_path, cols: int | None = None, rows: int | None = None,
                       files: OutputSet | None = None, shown_as=None) -> Path:
    """A VRT at ``vrt_path`` that shows ``image`` (unchanged, referenced by path: relative to the
    VRT's folder when it lies in or below it) with the model in its RPC metadata, so GDAL and
    QGIS use the RPC for it. With cols/rows, checks that the image has the camera's size
    (InputError otherwise). Written completely or not at all (with ``files``, as part of that set).
    ``shown_as``: the path the VRT names for the image instead of ``image`` (the final name of an
    image still being written under a temporary one)."""
    vrt_path = Path(vrt_path)
    try:
        src = open_input_raster(image)
    except RuntimeError as exc:
        raise InputError(f"image {image}: cannot be opened as a raster ({exc})") from None
    if cols is not None and (src.RasterXSize, src.RasterYSize) != (int(cols), int(rows)):
        raise InputError(f"image {image} is {src.RasterXSize} x {src.RasterYSize} pixels but the camera's image is "
                         f"{cols} x {rows}: it is not this camera's image")
    vrt = gdal.Translate("", src, format="VRT")  # in memory: its XML is written below
    copy_statistics(src, vrt)
    vrt.SetMetadata(rpc_metadata(rpc), "RPC")
    xml = ElementTree.fromstring(vrt.GetMetadata("xml:VRT")[0])
    vrt = None
    for name in xml.iter("SourceFilename"):  # relative to the VRT's folder when the image lies in or below it
        relative = os.path.relpath(os.path.realpath(shown_as or name.text), os.path.dirname(os.path.realpath(vrt_path)))
        if name.get("relativeToVRT") != "1" and not relative.startswith(os.pardir):
            name.text = relative
            name.set("relativeToVRT", "1")
    write_text(vrt_path, ElementTree.tostring(xml, encoding="unicode"), files)
    return vrt_path
