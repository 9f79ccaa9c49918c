"""Vector layers with OGR: opening a layer, the WGS84 3D frame of ground layers, and writing
layers whose fields come from parallel numpy arrays, one geometry per row.

Types follow the arrays: strings -> String, booleans and integers -> Integer, floats ->
Real (NaN written as NULL). The file is written completely or not at all
(:func:`core.files.atomic_output`).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from osgeo import ogr, osr

from .errors import InputError
from .files import OutputError, OutputSet, atomic_output, closing_errors, write_failure

ogr.UseExceptions()


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
    it; '' or OGR's error (returned, not raised: the error's traceback would hold the file open)."""
    failed, written = "", 0
    try:
        exists = Path(path).exists()
        ds = ogr.Open(str(path), update=1) if exists else ogr.GetDriverByName("GPKG").CreateDataSource(str(path))
        lyr = ds.CreateLayer(layer, srs, geometry_type, options=["FID=fid"])
        arrays = {name: np.asarray(v) for name, v in columns.items()}
        for name, values in arrays.items():
            lyr.CreateField(ogr.FieldDefn(name, _field_type(values)))
        for key, value in (metadata or {}).items():
            lyr.SetMetadataItem(key, value)
        defn = lyr.GetLayerDefn()
        setters = [_setter(defn.GetFieldIndex(name), values) for name, values in arrays.items()]
        lyr.StartTransaction()
        for geom, *row in zip(geometries, *(column for _, column in setters)):  # OGR writes feature by feature
            feat = ogr.Feature(defn)
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
    count = None if failed else _layer_count(path, layer)
    if not failed and count is None:
        failed = f"the layer {layer} cannot be read back after writing"
    elif not failed and count != written:
        failed = f"the layer {layer} holds {count} of {written} features"
    return failed


def _layer_count(path, layer: str) -> int | None:
    try:
        ds = ogr.Open(str(path))
        lyr = ds.GetLayerByName(layer) if ds is not None else None
    except RuntimeError:
        return None
    return None if lyr is None else lyr.GetFeatureCount()
