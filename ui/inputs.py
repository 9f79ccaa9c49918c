"""QGIS parameters and layers to core inputs (scenes, layers' files, CRSs, attributes, rasters, heights,
matching settings); every refusal names the parameter at fault."""
from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np
from pyproj import CRS
from pyproj.exceptions import CRSError
from qgis.core import (NULL, QgsCoordinateReferenceSystem, QgsMapLayer, QgsProcessing, QgsProcessingException,
                       QgsProcessingParameterDefinition, QgsProcessingParameterMultipleLayers,
                       QgsProcessingParameterRasterLayer, QgsProcessingUtils, QgsProperty, QgsProviderRegistry,
                       QgsWkbTypes)

from ..core.errors import PushbroomError
from ..core.observations.tables import present
from ..core.rasters import check_input_raster
from ..core.runs import region, scenes
from ..core.runs.layers import PointHeights
from . import parameters as vocabulary
from .feedback import error_message, processing_errors, push_lines
from .parameters import DEM, HEIGHT_SOURCE, Z_DATUM, enum_value

# The core's names of the scene, camera and DEM inputs (InputError.parameter) -> the shared parameters
SCENE_PARAMETERS = {"scene": vocabulary.SCENE, scenes.SCENES: vocabulary.SCENES, "camera": vocabulary.CAMERA,
                    "dem": DEM}


# --- scenes and cameras ------------------------------------------------------------------------
def add_scene_parameters(alg, with_camera: bool = True, or_scenes: bool = False) -> None:
    """SCENE (any supported metadata or scene JSON) and, optionally, CAMERA; with ``or_scenes``
    SCENE is optional and SCENES follows it (a block of scenes instead of one)."""
    alg.addParameter(vocabulary.scene(optional=or_scenes))
    if or_scenes:
        alg.addParameter(vocabulary.scenes())
    if with_camera:
        alg.addParameter(vocabulary.camera())


def scene_or_block(alg, parameters, context, feedback=None) -> tuple[str, tuple[str, ...]]:
    """(SCENE's file, ()) for one scene, ('', SCENES' product files: folders and list files expanded by
    core.runs.region, logged to ``feedback``) for a block; refused naming both when both are given
    (saying what SCENE_OR_SCENES does with each) or neither."""
    scene = alg.parameterAsFile(parameters, vocabulary.SCENE, context)
    block = tuple(path for path in alg.parameterAsFileList(parameters, vocabulary.SCENES, context) if path)
    if block and scene:
        one, several = alg.SCENE_OR_SCENES
        raise QgsProcessingException(f"SCENE and SCENES are both given: give SCENE to {one}, or SCENES to "
                                     f"{several}, not both")
    if not block and not scene:
        raise QgsProcessingException("give SCENE (one scene) or SCENES (a block of scenes): neither is given")
    if not block:
        return scene, ()
    with processing_errors(f"{vocabulary.SCENES}: "):
        files, lines = region.expand_scenes(block)
    if feedback is not None:
        push_lines(feedback, lines)
    return "", files


def source_and_features(alg, parameters, context, input_name: str = "INPUT") -> tuple:
    """(feature source, its features) of a feature source parameter; errors name the parameter."""
    source = alg.parameterAsSource(parameters, input_name, context)
    if source is None:
        raise QgsProcessingException(alg.invalidSourceError(parameters, input_name))
    return source, source_features(input_name, source)


def block_scene_names(paths) -> list[str]:
    """The name of each scene file of a block (SCENES): :func:`core.runs.scenes.block_scene_names`,
    its refusal (two scenes of one name) naming SCENES."""
    with processing_errors(f"{vocabulary.SCENES}: "):
        return scenes.block_scene_names(paths)


def crs_text(crs: QgsCoordinateReferenceSystem) -> str | None:
    """A CRS string pyproj reads (the authority id, else WKT); None for an invalid CRS."""
    if not crs.isValid():
        return None
    return crs.authid() if crs.authid().upper().startswith("EPSG:") else \
        crs.toWkt(QgsCoordinateReferenceSystem.WKT_PREFERRED)


# --- the files behind layers -------------------------------------------------------------------
def layer_file(layer: QgsMapLayer | None) -> str:
    """The file behind a layer ('' for memory layers, databases and services)."""
    if layer is None:
        return ""
    return QgsProviderRegistry.instance().decodeUri(layer.providerType(), layer.source()).get("path") or ""


# --- raster inputs: read by GDAL, never loaded as QGIS layers (why: ui.parameters.CheckedByGdal) ---
def is_raster_input(definition) -> bool:
    """Whether a parameter definition takes rasters (a raster layer, or several)."""
    return isinstance(definition, QgsProcessingParameterRasterLayer) or (
        isinstance(definition, QgsProcessingParameterMultipleLayers)
        and definition.layerType() == QgsProcessing.TypeRaster)


def _given_values(value, context) -> list:
    """The items of a parameter value (lists flattened, properties evaluated), None and '' left out."""
    if isinstance(value, QgsProperty):
        value = value.valueAsString(context.expressionContext(), "")
    if isinstance(value, (list, tuple)):
        return [item for v in value for item in _given_values(v, context)]
    return [] if value is None or value == NULL or value == "" else [value]


def raster_files(alg, parameters, name: str, context) -> list[str]:
    """The files of raster parameter ``name`` ([] when not given), none loaded as a QGIS layer: a layer of
    the project (itself, its id or name) gives its file ('' when it has none), a path is the file."""
    value = parameters.get(name) if name in parameters else alg.parameterDefinition(name).defaultValue()
    files = []
    for item in _given_values(value, context):
        layer = item if isinstance(item, QgsMapLayer) else \
            QgsProcessingUtils.mapLayerFromString(str(item), context, False)  # False: never a new layer
        files.append(str(item) if layer is None else layer_file(layer))
    return files


def raster_file(alg, parameters, name: str, context) -> str:
    """The file of raster parameter ``name`` ('' when not given); see :func:`raster_files`."""
    files = raster_files(alg, parameters, name, context)
    return files[0] if files else ""


# What a raster parameter takes, for its refusals (None: any other raster parameter).
RASTER_KINDS = {DEM: "a DEM: heights in metres on a map grid with a CRS, in any raster format GDAL reads (GeoTIFF, "
                     "VRT, ...)",
                None: "a raster file GDAL reads (GeoTIFF, VRT, ...)"}


def raster_refusal(alg, parameters, definition, context) -> str:
    """Why the value of raster parameter ``definition`` cannot be read by GDAL ('' when it can)."""
    name = definition.name()
    files = raster_files(alg, parameters, name, context)
    if not files and not definition.flags() & QgsProcessingParameterDefinition.FlagOptional:
        return f"{name}: no raster given"
    for path in files:
        if alg.IMAGE_FOLDERS and name == vocabulary.INPUTS and len(files) == 1 and \
                (Path(path).is_dir() or region.is_list_file(Path(path))):
            return ""    # a folder or list file of a block's raw images, read by the core
        try:
            check_input_raster(path)
        except PushbroomError as exc:
            return error_message(exc, f"{name}: ") + f"; give {RASTER_KINDS.get(name, RASTER_KINDS[None])}"
    return ""


def split_ogr_source(source: str) -> tuple[str, str | None]:
    """(file path, layer name or None for the first) of an OGR layer's source 'path|layername=...'."""
    path, _, options = source.partition("|")
    return path, dict(o.split("=", 1) for o in options.split("|") if "=" in o).get("layername")


def ogr_source(parameter_name: str, layer, what: str) -> tuple[str, str | None]:
    """(file path, layer name or None) of a file-based OGR vector layer given by a parameter;
    ``what``: the layer's kind, for the messages."""
    if layer is None:
        raise QgsProcessingException(f"{parameter_name}: no {what} given")
    path, name = split_ogr_source(layer.source())
    if layer.providerType() != "ogr" or not Path(path).is_file():
        raise QgsProcessingException(f"{parameter_name}: {layer.source()} is not a file-based vector layer; save the "
                                     f"{what} to a GeoPackage or shapefile first")
    return path, name


# --- coordinates and attributes ----------------------------------------------------------------
def layer_crs(parameter_name: str, crs) -> CRS:
    """pyproj's CRS of a layer's QgsCoordinateReferenceSystem; refused, naming the parameter, when the
    layer has none or pyproj does not know it."""
    if not crs.isValid():
        raise QgsProcessingException(f"{parameter_name}: the layer has no valid CRS; assign one first")
    try:
        return CRS.from_wkt(crs.toWkt(QgsCoordinateReferenceSystem.WKT_PREFERRED))
    except CRSError as exc:
        raise QgsProcessingException(f"{parameter_name}: unknown CRS {crs.authid() or crs.description()} ({exc})") \
            from None


def source_features(parameter_name: str, source) -> list:
    """The features of a feature source a parameter gives; QgsProcessingException naming the
    parameter and the layer when it has none."""
    features = list(source.getFeatures())
    if not features:
        raise QgsProcessingException(f"{parameter_name}: the layer {source.sourceName()!r} is empty (it has no "
                                     "features)")
    return features


def require_points(parameter_name: str, source) -> None:
    """Refuse a feature source whose geometries are not points (a line or polygon layer where
    points are meant: taking one vertex of each would be silently wrong), naming the layer."""
    kind = QgsWkbTypes.geometryType(source.wkbType())
    if kind == QgsWkbTypes.NullGeometry:
        raise QgsProcessingException(f"{parameter_name}: the layer {source.sourceName()!r} has no geometries (a "
                                     "table); a point layer is needed")
    if kind != QgsWkbTypes.PointGeometry:
        raise QgsProcessingException(f"{parameter_name}: the layer {source.sourceName()!r} holds "
                                     f"{QgsWkbTypes.displayString(source.wkbType())} geometries; a point layer is "
                                     "needed")


def field_values(alg, parameters, context, source, features) -> Callable[[str, bool], list | None]:
    """column(param, required, conventional=None): the values of ``features`` in the field string
    parameter ``param`` names, else in the field ``conventional`` when the layer has one, else None
    (or, ``required``, an error). Errors name the parameter and list the layer's fields."""
    names = source.fields().names()

    def column(param: str, required: bool, conventional: str | None = None):
        name = alg.parameterAsString(parameters, param, context).strip() or \
            (present(names, conventional) if conventional else None)
        if not name:
            if required:
                raise QgsProcessingException(f"{param}: name the field of the layer that holds it")
            return None
        if name not in names:
            raise QgsProcessingException(f"{param}: the layer has no field {name!r} (fields: {', '.join(names)})")
        return [f[name] for f in features]

    return column


def point_xyz(features) -> np.ndarray:
    """(n, 3) x, y, z of point features in their layer's CRS (a multipoint's first); NaN: no geometry, no Z."""
    xyz = np.full((len(features), 3), np.nan)
    for i, f in enumerate(features):
        g = f.geometry()
        if not (g.isNull() or g.isEmpty()):
            p = g.vertexAt(0)
            xyz[i] = p.x(), p.y(), p.z()
    return xyz


def attribute_floats(values) -> np.ndarray:
    """Attribute values as floats; NULL and non-numeric text become NaN (reported with ids by the core)."""
    def number(v):
        try:
            return float(v)
        except (TypeError, ValueError):
            return np.nan
    return np.array([number(v) for v in values], dtype=float)


def attribute_texts(values):
    """Attribute values as stripped strings (NULL -> ''); None (no field) stays None."""
    return None if values is None else ["" if v is None or v == NULL else str(v).strip() for v in values]


# --- terrain and heights -----------------------------------------------------------------------
def add_dem_parameters(alg) -> None:
    """Add the optional DEM raster, its height datum and the constant-height fallback."""
    for p in (vocabulary.dem(), vocabulary.dem_datum(), vocabulary.height()):
        alg.addParameter(p)


def point_heights(alg, parameters, context) -> PointHeights:
    """Where imported points take their heights (:class:`core.runs.layers.PointHeights`): HEIGHT_SOURCE,
    Z_DATUM (None: what the points' CRS says) and the terrain of the DEM parameters."""
    return PointHeights(enum_value(alg, parameters, HEIGHT_SOURCE, context),
                        enum_value(alg, parameters, Z_DATUM, context) or None, alg.terrain(parameters, context))


def matching_settings(alg, parameters, context) -> dict:
    """The values of the matching parameters (ui.parameters.matching_parameters) by
    :class:`core.measure.matching.MatchSettings` field, which the use case checks."""
    return {"spacing": alg.parameterAsDouble(parameters, vocabulary.SPACING, context),
            "count": alg.parameterAsInt(parameters, vocabulary.N_POINTS, context),
            "window": alg.parameterAsInt(parameters, vocabulary.WINDOW, context),
            "min_correlation": alg.parameterAsDouble(parameters, vocabulary.MIN_CORRELATION, context),
            "search": alg.parameterAsDouble(parameters, vocabulary.SEARCH_RANGE, context),
            "fine_radius": alg.parameterAsInt(parameters, vocabulary.FINE_RADIUS, context)}
