"""Glue shared by the Processing algorithms: core errors -> QgsProcessingException,
feedback -> core progress/cancel callbacks, DEM parameters -> core surfaces, output styling.

The core knows nothing of QGIS; everything that adapts one to the other lives here.
"""
from __future__ import annotations

import logging
from contextlib import contextmanager
from pathlib import Path
from typing import Callable

import numpy as np
from pyproj import CRS, Transformer
from pyproj.exceptions import CRSError
from qgis.core import (NULL, QgsCoordinateReferenceSystem, QgsDataSourceUri, QgsFeatureSink, QgsMapLayer,
                       QgsProcessingAlgorithm, QgsProcessingException, QgsProcessingOutputLayerDefinition,
                       QgsProcessingParameterDefinition, QgsProcessingParameterFileDestination, QgsProcessingUtils,
                       QgsProcessingLayerPostProcessorInterface, QgsProcessingParameterEnum,
                       QgsProcessingParameterFile, QgsProcessingParameterFolderDestination,
                       QgsProperty, QgsProviderRegistry)
from qgis.PyQt.QtGui import QIcon

from ..core.errors import PushbroomError
from ..core.files import atomic_output
from ..core.files import check_outputs as check_files
from . import parameters as vocabulary
from .parameters import CAMERA, DEM, DEM_DATUM, HEIGHT, SCENE, enum_refusal, enum_value, tr

RESOURCES = Path(__file__).resolve().parents[1] / "resources"
STYLES = RESOURCES / "styles"


# --- algorithm base ------------------------------------------------------------------------
class PushbroomAlgorithm(QgsProcessingAlgorithm):
    """Base of the plugin's algorithms: id, name, group and help from class attributes.

    shortHelpString() is HELP followed by every parameter's name and help text (setHelp), so
    the toolbox, qgis_process help and the README say the same. NAME, GROUP and HELP are
    English and shown through tr(); GROUP_ID never changes with the language.
    Enumeration values are checked before a run (checkParameterValues): an unknown name or an
    option number is refused with the parameter's value names.
    """
    ID = ""
    NAME = ""
    GROUP, GROUP_ID = "Sensor model", "sensormodel"
    HELP = ""

    def name(self):
        return self.ID

    def displayName(self):  # noqa: N802 (QGIS API names)
        return tr(self.NAME)

    def group(self):
        return tr(self.GROUP)

    def groupId(self):  # noqa: N802
        return self.GROUP_ID

    def icon(self):
        return QIcon(str(RESOURCES / "icon.svg"))

    def createInstance(self):  # noqa: N802
        return type(self)()

    def add_parameter(self, parameter, help_text: str | None = None, advanced: bool = False) -> None:
        """Add a parameter with its help text (shown in the toolbox and qgis_process help); None keeps
        the help a shared definition of ui.parameters brings."""
        if help_text is not None:
            parameter.setHelp(help_text)
        if advanced:
            parameter.setFlags(parameter.flags() | QgsProcessingParameterDefinition.FlagAdvanced)
        self.addParameter(parameter)

    def output_path(self, parameters, context, name: str, temporary_name: str) -> str:
        """Where output parameter ``name`` goes: '' for an optional output nobody asked for, a new
        temporary file ``temporary_name`` for an empty required one (a graphical model passes
        that for outputs nobody asked for, which later steps may still need)."""
        definition = self.parameterDefinition(name)
        if isinstance(definition, QgsProcessingParameterFileDestination):
            path = self.parameterAsFileOutput(parameters, name, context)
        else:
            path = self.parameterAsOutputLayer(parameters, name, context)
        if not path and definition.flags() & QgsProcessingParameterDefinition.FlagOptional:
            return ""
        return path or QgsProcessingUtils.generateTempFilename(temporary_name)

    def shortHelpString(self):  # noqa: N802
        rows = "".join(f"<li><b>{p.name()}</b>: {p.help() or p.description()}</li>"
                       for p in self.parameterDefinitions())
        outs = "".join(f"<li><b>{o.name()}</b>: {o.description()}</li>" for o in self.outputDefinitions())
        return (f"<p>{tr(self.HELP)}</p><p>{tr('Parameters')}:</p><ul>{rows}</ul>"
                f"<p>{tr('Outputs')}:</p><ul>{outs}</ul>")

    def checkParameterValues(self, parameters, context):  # noqa: N802
        """Enumerations take value names only (see ui.parameters.enum_refusal); an empty text is
        'not given', as the toolbox's '[Not selected]' is. The rest is QGIS's own check."""
        given = dict(parameters)
        for definition in self.parameterDefinitions():
            if isinstance(definition, QgsProcessingParameterEnum):
                refusal = enum_refusal(definition, given.get(definition.name()))
                if refusal:
                    return False, refusal
                if given.get(definition.name()) == "":
                    given[definition.name()] = None
        return super().checkParameterValues(given, context)


# --- errors -------------------------------------------------------------------------------
@contextmanager
def processing_errors(prefix: str = ""):
    """Turn core.errors.PushbroomError raised inside the block into QgsProcessingException,
    with ``prefix`` (e.g. the parameter name) put before the core's message."""
    try:
        yield
    except PushbroomError as exc:
        raise QgsProcessingException(f"{prefix}{exc}") from None


def core_call(func: Callable, *args, **kw):
    """Call a core function; its PushbroomError becomes a QgsProcessingException."""
    with processing_errors():
        return func(*args, **kw)


def load_scene_for(parameter_name: str, path: str, feedback=None):
    """Load any supported scene file (core.scene_io.load_scene) given by a parameter.

    The error message names the parameter, e.g. "SCENE: /x/y.xml: no such file". The reader's
    warnings (``scene.info["warnings"]``: what it assumed about the file) go to ``feedback``.
    """
    from ..core.formats.scene_json import load_scene
    if not path:
        raise QgsProcessingException(f"{parameter_name}: no scene file given")
    with processing_errors(f"{parameter_name}: "):
        scene = load_scene(path)
    if feedback is not None:
        for warning in scene.info.get("warnings", []):
            feedback.pushWarning(f"{parameter_name}: {warning}")
    return scene


def camera_for(parameter_name: str, scene, text: str | None) -> int:
    """Camera index of a scene from a parameter holding a camera name or index ('' = first)."""
    text = (text or "").strip()
    if not text:
        return 0
    with processing_errors(f"{parameter_name}: "):
        return scene.camera_index(int(text) if text.isdigit() else text)


def scene_camera_and_features(alg, parameters, context, input_name: str = "INPUT", feedback=None):
    """(scene, camera index, feature source, its features) from SCENE, CAMERA and a feature
    source parameter; errors name the parameter, the reader's warnings go to ``feedback``."""
    scene = load_scene_for(SCENE, alg.parameterAsFile(parameters, SCENE, context), feedback)
    camera = camera_for(CAMERA, scene, alg.parameterAsString(parameters, CAMERA, context))
    source = alg.parameterAsSource(parameters, input_name, context)
    if source is None:
        raise QgsProcessingException(alg.invalidSourceError(parameters, input_name))
    return scene, camera, source, list(source.getFeatures())


def add_scene_parameters(alg, with_camera: bool = True) -> None:
    """SCENE (any supported metadata or scene JSON) and, optionally, CAMERA."""
    alg.addParameter(vocabulary.scene())
    if with_camera:
        alg.addParameter(vocabulary.camera())


def lonlat_of(parameter_name: str, crs, x, y) -> tuple[np.ndarray, np.ndarray]:
    """WGS84 (lon, lat) degrees of coordinates (x, y) in a layer's QgsCoordinateReferenceSystem."""
    if not crs.isValid():
        raise QgsProcessingException(f"{parameter_name}: the layer has no valid CRS; assign one first")
    try:
        source = CRS.from_wkt(crs.toWkt(QgsCoordinateReferenceSystem.WKT_PREFERRED))
    except CRSError as exc:
        raise QgsProcessingException(f"{parameter_name}: unknown CRS {crs.authid() or crs.description()} ({exc})") \
            from None
    lon, lat = Transformer.from_crs(source, CRS.from_epsg(4326), always_xy=True).transform(x, y)
    lon, lat = np.asarray(lon, dtype=float), np.asarray(lat, dtype=float)
    bad = ~(np.isfinite(lon) & np.isfinite(lat))
    if bad.any():
        raise QgsProcessingException(f"{parameter_name}: {bad.sum()} points cannot be converted from "
                                     f"{crs.authid()} to WGS84 longitude/latitude")
    return lon, lat


def require_points(parameter_name: str, source) -> None:
    """Refuse a feature source whose geometries are not points (a line or polygon layer where
    points are meant: taking one vertex of each would be silently wrong)."""
    from qgis.core import QgsWkbTypes
    kind = QgsWkbTypes.geometryType(source.wkbType())
    if kind != QgsWkbTypes.PointGeometry:
        raise QgsProcessingException(f"{parameter_name}: the layer holds {QgsWkbTypes.displayString(source.wkbType())} "
                                     f"geometries; a point layer is needed")


def z_datum_of_crs(crs) -> str | None:
    """What the Z values of a layer in QgsCoordinateReferenceSystem ``crs`` are measured from, when
    the CRS says it: 'ellipsoid' for a 3D geographic CRS (EPSG:4979, the output of 'Image to
    ground'), 'geoid' for a compound CRS with EGM96 heights (EPSG:4326+5773); else None."""
    if not crs.isValid():
        return None
    try:
        pyproj_crs = CRS.from_wkt(crs.toWkt(QgsCoordinateReferenceSystem.WKT_PREFERRED))
    except CRSError:
        return None
    if pyproj_crs.is_geographic and len(pyproj_crs.axis_info) == 3:
        return "ellipsoid"
    if pyproj_crs.is_compound and any("EGM96" in (sub.name or "") for sub in pyproj_crs.sub_crs_list[1:]):
        return "geoid"
    return None


def nonfinite_message(parameter_name: str, what: str, ids, bad) -> str:
    """Message naming (some of) the features whose values are NaN, missing or infinite."""
    first = ", ".join(str(i) for i in np.asarray(ids)[bad][:5])
    return f"{parameter_name}: {int(np.sum(bad))} features have missing or non-finite {what} (feature ids {first}...)"


def field_values(alg, parameters, context, source, features) -> Callable[[str, bool], list | None]:
    """column(param, required): the values of ``features`` in the field of ``source`` that string
    parameter ``param`` names; None when the parameter is empty and not required. Errors name
    the parameter (and list the layer's fields)."""
    names = source.fields().names()

    def column(param: str, required: bool):
        name = alg.parameterAsString(parameters, param, context).strip()
        if not name:
            if required:
                raise QgsProcessingException(f"{param}: name the field of the layer that holds it")
            return None
        if name not in names:
            raise QgsProcessingException(f"{param}: the layer has no field {name!r} (fields: {', '.join(names)})")
        return [f[name] for f in features]

    return column


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


@contextmanager
def core_log_to(feedback, logger_name: str):
    """Show a core module's log messages (warnings about the input) in the Processing log."""
    class _ToFeedback(logging.Handler):
        def emit(self, record):
            (feedback.pushWarning if record.levelno >= logging.WARNING else feedback.pushInfo)(record.getMessage())

    logger = logging.getLogger(logger_name)
    handler = _ToFeedback(logging.INFO)
    logger.addHandler(handler)
    previous = logger.level
    logger.setLevel(logging.INFO)
    try:
        yield
    finally:
        logger.removeHandler(handler)
        logger.setLevel(previous)


# --- feedback -----------------------------------------------------------------------------
def feedback_callbacks(feedback) -> tuple[Callable[[float, str | None], None], Callable[[], bool]]:
    """(progress(fraction 0..1, message or None), is_cancelled()) for a QgsProcessingFeedback
    (or None, when an algorithm runs without one)."""
    def progress(fraction: float, message: str | None = None) -> None:
        if feedback is None:
            return
        feedback.setProgress(100.0 * min(max(float(fraction), 0.0), 1.0))
        if message:
            feedback.setProgressText(message)

    def is_cancelled() -> bool:
        return feedback is not None and feedback.isCanceled()

    return progress, is_cancelled


def check_cancelled(feedback) -> None:
    """Stop an algorithm between steps when the user cancelled it."""
    if feedback is not None and feedback.isCanceled():
        raise QgsProcessingException("cancelled by the user")


# --- DEM parameters -----------------------------------------------------------------------
def add_dem_parameters(alg) -> None:
    """Add the optional DEM raster, its height datum and the constant-height fallback."""
    for p in (vocabulary.dem(), vocabulary.dem_datum(), vocabulary.height()):
        alg.addParameter(p)


def dem_from_parameters(alg, parameters, context, scene=None, feedback=None):
    """core.dem.Dem of the DEM parameter, or core.dem.ConstantHeight(HEIGHT) without one.

    With an RPC ``scene`` (core.rpcscene.RpcScene), heights that do not meet the RPC's height
    range are refused and heights partly outside it are a warning to ``feedback``."""
    from ..core.dem import ConstantHeight, Dem
    from ..core.validation import check_terrain_height
    layer = alg.parameterAsRasterLayer(parameters, DEM, context)
    if layer is None:
        with processing_errors():
            surface = ConstantHeight(check_terrain_height(alg.parameterAsDouble(parameters, HEIGHT, context), HEIGHT))
        what = f"{HEIGHT} {surface.value:g} m"
    else:
        datum = enum_value(alg, parameters, DEM_DATUM, context)
        path = layer.source().split("|")[0]
        with processing_errors(f"{DEM}: "):
            surface = Dem(path, datum)
            surface.height_range  # reads the DEM's overview: implausible heights are refused before any output
        what = f"{DEM} {path}"
    if hasattr(scene, "check_surface"):
        with processing_errors():
            warning = scene.check_surface(surface.height_range, what)
        if warning and feedback is not None:
            feedback.pushWarning(warning)
    return surface


# --- raw images and matching settings -----------------------------------------------------------
def camera_images_for(alg, parameters, context, scene) -> dict[int, str]:
    """{camera index: file} of INPUTS, one raw image per camera of ``scene`` in its camera order;
    QgsProcessingException naming the cameras when the count differs or a layer is not a file."""
    layers = alg.parameterAsLayerList(parameters, vocabulary.INPUTS, context)
    names = [cam.name for cam in scene.cameras]
    if len(layers) != len(names):
        raise QgsProcessingException(f"{vocabulary.INPUTS}: {len(layers)} raw image(s) given, but the scene has "
                                     f"{len(names)} camera(s) ({', '.join(names)}): give one image per camera, "
                                     "in that order")
    images = {k: layer_file(layer) for k, layer in enumerate(layers)}
    missing = [names[k] for k, path in images.items() if not path]
    if missing:
        raise QgsProcessingException(f"{vocabulary.INPUTS}: the image(s) of camera(s) {', '.join(missing)} are not "
                                     "files (memory or service layers); save them as GeoTIFF first")
    return images


def matching_settings(alg, parameters, context, **fixed):
    """core.matching.MatchSettings of the matching parameters (ui.parameters.matching_parameters),
    checked; ``fixed``: other MatchSettings fields."""
    from ..core.measure.matching import MatchSettings
    with processing_errors():
        settings = MatchSettings(spacing=alg.parameterAsDouble(parameters, vocabulary.SPACING, context),
                                 count=alg.parameterAsInt(parameters, vocabulary.N_POINTS, context),
                                 window=alg.parameterAsInt(parameters, vocabulary.WINDOW, context),
                                 min_correlation=alg.parameterAsDouble(parameters, vocabulary.MIN_CORRELATION,
                                                                       context),
                                 search=alg.parameterAsDouble(parameters, vocabulary.SEARCH_RANGE, context), **fixed)
        settings.validate()
    return settings


# --- inputs and outputs: nothing lost, nothing partial ------------------------------------------
def layer_file(layer: QgsMapLayer | None) -> str:
    """The file behind a layer ('' for memory layers, databases and services)."""
    if layer is None:
        return ""
    return QgsProviderRegistry.instance().decodeUri(layer.providerType(), layer.source()).get("path") or ""


def destination_file(destination: str) -> str:
    """The file an output layer destination writes to: the path itself, the database of an
    'ogr:dbname=...' table; '' for memory layers and services."""
    if destination.startswith("ogr:"):
        return QgsDataSourceUri(destination[4:]).database()
    if destination.startswith(("memory:", "postgis:", "postgres:", "spatialite:", "mssql:", "oracle:")):
        return ""
    return destination.split("|")[0]


def input_files(alg, parameters, context) -> dict[str, list[str]]:
    """{parameter: files it reads} for the input parameters given: files, and the files behind
    layers (loaded in the project or given by path)."""
    files = {}
    for definition in alg.parameterDefinitions():
        name = definition.name()
        if definition.isDestination() or parameters.get(name) in (None, ""):
            continue
        if isinstance(definition, QgsProcessingParameterFile):
            files[name] = [alg.parameterAsFile(parameters, name, context)]
        elif definition.type() in ("raster", "vector", "source", "layer", "mesh", "pointcloud"):
            files[name] = [layer_file(alg.parameterAsLayer(parameters, name, context))]
        elif definition.type() == "multilayer":
            files[name] = [layer_file(layer) for layer in alg.parameterAsLayerList(parameters, name, context)]
    return files


def geopackage_output(alg, parameters, context, name: str, temporary_name: str, what: str) -> str:
    """The file of vector output ``name``, a GeoPackage (``what``: the layers' kind, for the
    message), checked against the inputs (:func:`check_outputs`) before any work."""
    dest = alg.output_path(parameters, context, name, temporary_name)
    if Path(dest).suffix.lower() != ".gpkg":
        raise QgsProcessingException(f"{name}: {what} layers are written as GeoPackage; choose a .gpkg file "
                                     f"(got {dest})")
    check_outputs(alg, parameters, context, {name: [dest]})
    return dest


def check_outputs(alg, parameters, context, outputs: dict | None = None) -> None:
    """Before any work: refuse outputs that would replace an input or each other (derived files
    included) and destinations that cannot be written, naming both parameters
    (:func:`core.files.check_outputs`). ``outputs``: {parameter: [its file, Output(derived file,
    label)...]} for outputs whose paths the algorithm resolved itself; every other destination
    parameter given is checked with the file its value names."""
    outputs = dict(outputs or {})
    for definition in alg.destinationParameterDefinitions():
        name = definition.name()
        if name in outputs or parameters.get(name) in (None, ""):
            continue
        if isinstance(definition, QgsProcessingParameterFolderDestination):
            continue  # the algorithm knows which files it writes there
        if isinstance(definition, QgsProcessingParameterFileDestination):
            outputs[name] = [alg.parameterAsFileOutput(parameters, name, context)]
        else:
            outputs[name] = [destination_file(alg.parameterAsOutputLayer(parameters, name, context))]
    with processing_errors():
        check_files(input_files(alg, parameters, context), outputs)


class CheckedSink:
    """A feature sink whose failures are errors: a feature the sink does not take (a full disk,
    a format that cannot hold it) stops the algorithm with a message naming the output."""

    def __init__(self, sink, parameter: str):
        self.sink, self.parameter, self.count = sink, parameter, 0

    def add(self, feature) -> None:
        if not self.sink.addFeature(feature, QgsFeatureSink.FastInsert):
            raise QgsProcessingException(f"{self.parameter}: the output did not take feature {self.count + 1} "
                                         f"({self.sink.lastError() or 'write error'}); nothing was written")
        self.count += 1


@contextmanager
def output_sink(alg, parameters, context, name: str, fields, wkb_type, crs):
    """(CheckedSink, destination) of feature sink parameter ``name``, written completely or not
    at all: a file destination is written under a temporary name in its folder
    (:func:`core.files.atomic_output`), checked to hold every feature once closed, and renamed
    over the destination when the block ends normally; nothing is left when it raises. Memory
    layers and tables added to a database are written in place."""
    final = alg.parameterAsOutputLayer(parameters, name, context)  # registers it for loading, if asked
    path = destination_file(final) if not final.startswith("ogr:") else ""
    if not path:
        sink, dest = alg.parameterAsSink(parameters, name, context, fields, wkb_type, crs)
        if sink is None:
            raise QgsProcessingException(alg.invalidSinkError(parameters, name))
        yield CheckedSink(sink, name), dest
        return
    with processing_errors(f"{name}: "), atomic_output(path) as tmp:
        given = parameters.get(name)
        staged = QgsProcessingOutputLayerDefinition(QgsProperty.fromValue(str(tmp)))  # not loaded: the final is
        if isinstance(given, QgsProcessingOutputLayerDefinition):
            staged.createOptions = given.createOptions
        sink, _ = alg.parameterAsSink({**parameters, name: staged}, name, context, fields, wkb_type, crs)
        if sink is None:
            raise QgsProcessingException(alg.invalidSinkError(parameters, name))
        checked = CheckedSink(sink, name)
        try:
            yield checked, final
        finally:
            checked.sink = sink = None  # closes the file (before it is renamed, or removed on errors)
        _check_written(name, tmp, checked.count)


def _check_written(name: str, path, expected: int) -> None:
    """QgsProcessingException unless the closed output file holds ``expected`` features (a full
    disk can lose them when the file is closed, where the sink reports nothing)."""
    from ..core.vector_io import feature_count
    found = feature_count(path)
    if found != expected:
        raise QgsProcessingException(f"{name}: the written file holds {found} of {expected} features (disk full?); "
                                     "nothing was written")


# --- output styling -----------------------------------------------------------------------
class _StyleOnLoad(QgsProcessingLayerPostProcessorInterface):
    """Applies a QML style to an output layer when Processing loads it into the project."""

    def __init__(self, qml_path: str):
        super().__init__()
        self.qml_path = qml_path

    def postProcessLayer(self, layer, context, feedback):  # noqa: N802 (QGIS API name)
        if layer is not None:
            layer.loadNamedStyle(self.qml_path)
            layer.triggerRepaint()


# QGIS holds post-processors by C++ pointer only: keep the Python objects alive here.
_post_processors: dict[str, _StyleOnLoad] = {}


def style_output_on_load(context, layer_id: str, qml_path: str | Path) -> None:
    """Style output ``layer_id`` with ``qml_path`` if Processing will load it on completion."""
    if not context.willLoadLayerOnCompletion(layer_id):
        return
    post = _StyleOnLoad(str(qml_path))
    _post_processors[layer_id] = post
    context.layerToLoadOnCompletionDetails(layer_id).setPostProcessor(post)
