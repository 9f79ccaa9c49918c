"""Vector layers with OGR: opening a layer, the WGS84 3D frame of ground layers, and writing
layers whose fields come from parallel numpy arrays, one geometry per row.

Types follow the arrays: strings -> String, booleans and integers -> Integer, floats ->
Real (NaN written as NULL). The file is written completely or not at all
(:func:`core.files.atomic_output`).
"""
from __future__ import annotations

import itertools
import uuid
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from osgeo import gdal, ogr, osr

from .errors import InputError
from .files import OutputError, OutputSet, atomic_output, closing_errors, write_failure

ogr.UseExceptions()

# Layers of WKT geometries and plain columns are appended through an in-memory CSV, this many rows at a time
# (gdal.VectorTranslate: the rows never pass through Python one field at a time; 100,000 rows are ~25 MB of text).
CSV_ROWS = 100_000
CSV_GEOMETRY = "pushbroom_wkt_geometry"
CSV_TYPES = {"U": "String", "S": "String", "b": "Integer64", "i": "Integer64", "u": "Integer64", "f": "Real"}
# SQLite's page cache (MB) while rows are appended: the layer's R-tree takes each point in turn, and with SQLite's
# default 2 MB most insertions read its pages back from the file (300,000 points written: 15.5 -> 13.7 s CPU).
# The cache grows only as pages are read, up to the file's size.
SQLITE_CACHE_MB = 512


def _field_type(values: np.ndarray) -> int:
    kind = np.asarray(values).dtype.kind
    return ogr.OFTString if kind in "UOS" else ogr.OFTInteger if kind in "biu" else ogr.OFTReal


def _setter(index: int, values: np.ndarray):
    """(put(feature, value), the column as a Python list) for field ``index`` of ``values``' type: the
    field set by index with OGR's typed setter (by name, OGR searches the fields for every value),
    NaN left NULL. Python lists: numpy scalars cost more to convert."""
    kind = values.dtype.kind
    if kind in "US":
        return (lambda feat, v: feat.SetFieldString(index, v)), values.astype(str).tolist()
    if kind in "biu":
        return (lambda feat, v: feat.SetFieldInteger64(index, v)), values.astype(np.int64).tolist()

    def put(feat, v):
        if isinstance(v, str) or v == v:  # NaN -> NULL
            feat.SetField(index, int(v) if isinstance(v, bool) else v)
    return put, values.tolist()


def open_layer(path, layer: str | None = None):
    """(data source, layer) of a vector file's named (or first) layer; InputError naming the
    file when it cannot be read. Keep the data source: the layer lives only as long as it."""
    try:
        ds = ogr.Open(str(path))
    except RuntimeError as exc:
        raise InputError(f"{path}: cannot be opened as a vector file ({exc})") from None
    lyr = ds.GetLayerByName(layer) if layer else ds.GetLayer(0)
    if lyr is None:
        raise InputError(f"{path}: no layer {layer!r}")
    return ds, lyr


def layer_fields(path, layer: str | None = None) -> list[str]:
    """The field names of a vector file's named (or first) layer (InputError as :func:`open_layer`)."""
    ds, lyr = open_layer(path, layer)  # ds held while the layer is read
    defn = lyr.GetLayerDefn()
    return [defn.GetFieldDefn(i).GetName() for i in range(defn.GetFieldCount())]


def wgs84_3d() -> osr.SpatialReference:
    """EPSG:4979 (WGS84 longitude, latitude in degrees, ellipsoidal height in metres), in
    longitude/latitude axis order: the frame of every ground layer the core writes."""
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(4979)
    srs.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    return srs


def layer_to_wgs84_3d(lyr) -> osr.CoordinateTransformation | None:
    """The transformation of an OGR layer's coordinates to :func:`wgs84_3d`; None when the layer
    has no CRS or is in that frame already."""
    srs = lyr.GetSpatialRef()
    target = wgs84_3d()
    if srs is None or srs.IsSame(target):
        return None
    srs = srs.Clone()
    srs.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    return osr.CoordinateTransformation(srs, target)


def feature_count(path) -> int | None:
    """Features in the first layer of a vector file; None when it cannot be read."""
    try:
        ds = ogr.Open(str(path))
    except RuntimeError:
        return None
    if ds is None or ds.GetLayerCount() == 0:
        return None
    return ds.GetLayer(0).GetFeatureCount()


@dataclass
class LayerData:
    """One layer to write: name, CRS, OGR geometry type, columns {name: (n,) array}, n OGR
    geometries (or WKT strings), optional layer metadata items."""
    name: str
    srs: osr.SpatialReference | None
    geometry_type: int
    columns: dict
    geometries: object
    metadata: dict | None = None


def write_layer(path, layer: str, srs: osr.SpatialReference, geometry_type: int, columns: dict,
                geometries, metadata: dict | None = None, files: OutputSet | None = None) -> None:
    """Write a GeoPackage layer: ``columns`` {name: (n,) array}, ``geometries`` n OGR
    geometries (or WKT strings), optional layer metadata items. Replaces the file, completely
    or not at all (with ``files``, as part of that set)."""
    write_layers(path, [LayerData(layer, srs, geometry_type, columns, geometries, metadata)], files)


def write_layers(path, layers: list[LayerData], files: OutputSet | None = None) -> None:
    """Write a GeoPackage holding ``layers``; replaces the file, completely or not at all."""
    path = Path(path)
    if path.suffix.lower() != ".gpkg":
        raise InputError(f"{path}: layers are written as GeoPackage; use a .gpkg file name")
    with atomic_output(path, files) as tmp:
        failed = ""
        for layer in layers:
            failed = failed or _write_gpkg(tmp, layer.name, layer.srs, layer.geometry_type, layer.columns,
                                           layer.geometries, layer.metadata)
        if failed:  # while the file still fills the disk: a full disk is named as such
            raise OutputError(f"cannot write {path}: {write_failure(path, failed)}")


def _write_gpkg(path, layer: str, srs, geometry_type: int, columns: dict, geometries, metadata) -> str:
    """Write a layer into a GeoPackage (created when absent; see :func:`write_layer`) and close
    it; '' or OGR's error (returned, not raised: the error's traceback would hold the file open).
    Geometries as WKT with string, integer and float columns are appended by :func:`_append_csv`;
    others feature by feature."""
    failed, written = "", 0
    arrays = {name: np.asarray(v) for name, v in columns.items()}
    geometries = iter(geometries)
    first = next(geometries, None)
    geometries = itertools.chain([] if first is None else [first], geometries)
    bulk = isinstance(first, str) and all(v.dtype.kind in CSV_TYPES for v in arrays.values())
    try:
        exists = Path(path).exists()
        ds = ogr.Open(str(path), update=1) if exists else ogr.GetDriverByName("GPKG").CreateDataSource(str(path))
        lyr = ds.CreateLayer(layer, srs, geometry_type, options=["FID=fid"])
        for name, values in arrays.items():
            lyr.CreateField(ogr.FieldDefn(name, _field_type(values)))
        for key, value in (metadata or {}).items():
            lyr.SetMetadataItem(key, value)
        defn = lyr.GetLayerDefn()
        setters = [] if bulk else [_setter(defn.GetFieldIndex(name), values) for name, values in arrays.items()]
        lyr.StartTransaction()
        for geom, *row in zip(geometries if setters or not arrays else (), *(column for _, column in setters)):
            feat = ogr.Feature(defn)  # OGR writes feature by feature
            for (put, _), v in zip(setters, row):
                put(feat, v)
            feat.SetGeometry(ogr.CreateGeometryFromWkt(geom) if isinstance(geom, str) else geom)
            lyr.CreateFeature(feat)
            written += 1
        lyr.CommitTransaction()
    except RuntimeError as exc:  # OGR: disk full, file system errors
        failed = str(exc)
    finally:
        with closing_errors() as closing:
            feat = lyr = ds = None  # closes the file, flushing what is left
        failed = failed or closing.message
    if bulk and arrays and not failed:
        failed, written = _append_csv(path, layer, arrays, geometries)
    count = None if failed else _layer_count(path, layer)
    if not failed and count is None:
        failed = f"the layer {layer} cannot be read back after writing"
    elif not failed and count != written:
        failed = f"the layer {layer} holds {count} of {written} features"
    return failed


def _csv_text(values: np.ndarray) -> list[str]:
    """A column as CSV fields: strings quoted (RFC 4180), integers and booleans as integers, floats by
    repr (they read back to the bit), NaN empty (NULL)."""
    kind = values.dtype.kind
    if kind in "US":
        return ['"' + v.replace('"', '""') + '"' for v in values.astype(str).tolist()]
    if kind in "biu":
        return [str(v) for v in values.astype(np.int64).tolist()]
    return [repr(v) if v == v else "" for v in values.astype(float).tolist()]


def _append_csv(path, layer: str, arrays: dict, geometries) -> tuple[str, int]:
    """Append rows of ``arrays`` {field: (n,) string, integer or float array} with WKT ``geometries`` to
    the existing ``layer`` of the GeoPackage ``path``, CSV_ROWS at a time through an in-memory CSV and
    gdal.VectorTranslate; ('' or GDAL's error, rows appended). One thread appends a chunk while this one
    writes the next one's text: GDAL releases the GIL, so the two overlap on two cores (2,000,000 rows:
    the text about 35 s, the append about 58 s)."""
    names = list(arrays)
    stem = f"/vsimem/pushbroom_{uuid.uuid4().hex}"
    header = ",".join(['"' + n.replace('"', '""') + '"' for n in [*names, CSV_GEOMETRY]]) + "\n"
    types = ",".join([CSV_TYPES[arrays[n].dtype.kind] for n in names] + ["WKT"])
    failed, written, n = "", 0, min(len(v) for v in arrays.values())
    pending = None  # (the future of the chunk being appended, its rows)
    with ThreadPoolExecutor(max_workers=1) as appender:
        for k, start in enumerate(range(0, n, CSV_ROWS)):
            wkt = ['"' + g + '"' for g in itertools.islice(geometries, min(CSV_ROWS, n - start))]
            if not wkt:
                break
            fields = [_csv_text(arrays[key][start:start + len(wkt)]) for key in names] + [wkt]
            text = (header + "\n".join(map(",".join, zip(*fields))) + "\n").encode()
            failed, written = _appended(pending, written)
            pending = None if failed else (appender.submit(_append_chunk, f"{stem}_{k}", text, types, path, layer),
                                           len(wkt))
            if failed:
                break
        if pending is not None:
            failed, written = _appended(pending, written)
    return failed, written


def _appended(pending, written: int) -> tuple[str, int]:
    """('' or GDAL's error, rows appended) once the chunk ``pending`` (future, rows; None: none) is."""
    if pending is None:
        return "", written
    failed = pending[0].result()
    return failed, written + (0 if failed else pending[1])


def _append_chunk(stem: str, text: bytes, types: str, path, layer: str) -> str:
    """Append the CSV ``text`` (column types ``types``) to ``layer`` of ``path`` through the in-memory files
    ``stem``.csv and .csvt, removed afterwards; '' or GDAL's error (quiet: returned, not printed)."""
    gdal.PushErrorHandler("CPLQuietErrorHandler")  # GDAL's error handlers are per thread
    try:
        gdal.FileFromMemBuffer(stem + ".csvt", types)
        gdal.FileFromMemBuffer(stem + ".csv", text)
        return _translate(stem + ".csv", path, layer)
    finally:
        gdal.PopErrorHandler()
        for suffix in (".csv", ".csvt"):
            gdal.Unlink(stem + suffix)


def _translate(source: str, path, layer: str) -> str:
    """Append the CSV ``source`` (geometry in column CSV_GEOMETRY, types in its .csvt) to ``layer`` of
    ``path``; '' or GDAL's error."""
    src = out = None
    failed = ""
    cache = gdal.GetThreadLocalConfigOption("OGR_SQLITE_CACHE", None)
    gdal.SetThreadLocalConfigOption("OGR_SQLITE_CACHE", str(SQLITE_CACHE_MB))
    try:
        src = gdal.OpenEx(source, gdal.OF_VECTOR,
                          open_options=[f"GEOM_POSSIBLE_NAMES={CSV_GEOMETRY}", "KEEP_GEOM_COLUMNS=NO"])
        out = None if src is None else gdal.VectorTranslate(str(path), src, accessMode="append", layerName=layer,
                                                             options=["-gt", "unlimited"])
        if out is None:
            failed = gdal.GetLastErrorMsg() or f"{source} could not be appended to the layer {layer}"
    except RuntimeError as exc:
        failed = str(exc)
    finally:
        with closing_errors() as closing:
            out = src = None  # closes the file, flushing what is left
        gdal.SetThreadLocalConfigOption("OGR_SQLITE_CACHE", cache)
        failed = failed or closing.message
    return failed


def _layer_count(path, layer: str) -> int | None:
    try:
        ds = ogr.Open(str(path))
        lyr = ds.GetLayerByName(layer) if ds is not None else None
    except RuntimeError:
        return None
    return None if lyr is None else lyr.GetFeatureCount()
