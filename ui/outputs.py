"""Destinations, sinks and styles of outputs: nothing lost, nothing partial. Outputs are checked
before any work (none replaces an input or another output), written completely or not at all,
checked to hold what was written, and styled when Processing loads them."""
from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path
from typing import Callable

from qgis.core import (QgsContrastEnhancement, QgsDataSourceUri, QgsFeatureSink, QgsField, QgsFields, QgsProcessing,
                       QgsProcessingContext, QgsProcessingException, QgsProcessingLayerPostProcessorInterface,
                       QgsProcessingOutputLayerDefinition, QgsProcessingParameterFile,
                       QgsProcessingParameterFileDestination, QgsProcessingParameterFolderDestination,
                       QgsProcessingUtils, QgsProperty, QgsRasterMinMaxOrigin)

from ..core.files import atomic_output, write_failure
from ..core.runs.base import FilesInUse
from ..core.vector_io import feature_count
from . import RESOURCES
from .feedback import processing_errors
from .inputs import is_raster_input, layer_file, raster_files

STYLES = RESOURCES / "styles"  # QML styles of the output layers


# --- destinations, checked before any work -----------------------------------------------------
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
        elif is_raster_input(definition):
            files[name] = raster_files(alg, parameters, name, context)  # not loaded as layers: see ui.inputs
        elif definition.type() in ("vector", "source", "layer", "mesh", "pointcloud"):
            files[name] = [layer_file(alg.parameterAsLayer(parameters, name, context))]
        elif definition.type() == "multilayer" and definition.layerType() == QgsProcessing.TypeFile:
            files[name] = [f for f in alg.parameterAsFileList(parameters, name, context) if f]  # files (SCENES)
        elif definition.type() == "multilayer":
            files[name] = [layer_file(layer) for layer in alg.parameterAsLayerList(parameters, name, context)]
    return files


def files_in_use(alg, parameters, context) -> FilesInUse:
    """The files around a run (:class:`core.runs.base.FilesInUse`): those the inputs given read
    (:func:`input_files`), and every destination parameter given with the file its value names
    (folders apart: the algorithm knows which files it writes there)."""
    writes = {}
    for definition in alg.destinationParameterDefinitions():
        name = definition.name()
        if parameters.get(name) in (None, "") or isinstance(definition, QgsProcessingParameterFolderDestination):
            continue
        if isinstance(definition, QgsProcessingParameterFileDestination):
            writes[name] = [alg.parameterAsFileOutput(parameters, name, context)]
        else:
            writes[name] = [destination_file(alg.parameterAsOutputLayer(parameters, name, context))]
    return FilesInUse(input_files(alg, parameters, context), writes)


def check_outputs(alg, parameters, context, outputs: dict | None = None) -> None:
    """Before any work: refuse outputs that would replace an input or each other, or cannot be
    written, naming both parameters (:meth:`core.runs.base.FilesInUse.check`); ``outputs``:
    {parameter: [its file, Output...]} the algorithm resolved itself, besides the destinations given."""
    with processing_errors():
        files_in_use(alg, parameters, context).check(dict(outputs or {}))


# --- feature sinks: every feature or nothing ---------------------------------------------------
def output_fields(kinds: dict, before=None) -> QgsFields:
    """The fields of an output: ``kinds`` ({name: QVariant type}) after the input's fields ``before``."""
    fields = QgsFields()
    for name, kind in kinds.items():
        fields.append(QgsField(name, kind))
    return fields if before is None else QgsProcessingUtils.combineFields(before, fields)


class CheckedSink:
    """A feature sink whose failures are errors: a feature the sink does not take (a full disk,
    a format that cannot hold it) stops the algorithm with a message naming the output."""

    def __init__(self, sink, parameter: str, path: str = ""):
        self.sink, self.parameter, self.path, self.count = sink, parameter, path, 0

    def add(self, feature) -> None:
        if not self.sink.addFeature(feature, QgsFeatureSink.FastInsert):
            error = self.sink.lastError() or "write error"
            error = write_failure(self.path, error) if self.path else error
            raise QgsProcessingException(f"{self.parameter}: the output did not take feature {self.count + 1} "
                                         f"({error}); nothing was written")
        self.count += 1


@contextmanager
def output_sink(alg, parameters, context, name: str, fields, wkb_type, crs):
    """(CheckedSink, destination) of feature sink parameter ``name``, all or nothing: a file is written under
    a temporary name (core.files.atomic_output), checked and renamed at the block's normal end (memory
    layers and database tables: in place)."""
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
        checked = CheckedSink(sink, name, path)  # failures named by the destination, not the temporary file
        try:
            yield checked, final
        finally:
            checked.sink = sink = None  # closes the file (before it is renamed, or removed on errors)
        _check_written(name, tmp, checked.count, path)


def _check_written(name: str, path, expected: int, shown) -> None:
    """QgsProcessingException unless the closed output file ``path`` holds ``expected`` features (a
    full disk can lose them when the file is closed, where the sink reports nothing); the message
    names ``shown`` (the destination the file was to become)."""
    found = feature_count(path)
    if found != expected:
        written = ("the written file cannot be read back" if found is None else
                   f"the written file holds {found} of {expected} features")
        raise QgsProcessingException(f"{name}: {write_failure(shown, written)}; nothing was written")


# --- styles on load ----------------------------------------------------------------------------
class _StyleOnLoad(QgsProcessingLayerPostProcessorInterface):
    """Styles an output layer when Processing loads it into the project: ``style(layer)``."""

    def __init__(self, style: Callable):
        super().__init__()
        self.style = style

    def postProcessLayer(self, layer, context, feedback):  # noqa: N802 (QGIS API name)
        if layer is not None:
            self.style(layer)
            layer.triggerRepaint()


# QGIS holds post-processors by C++ pointer only: keep the Python objects alive here.
_post_processors: dict[str, _StyleOnLoad] = {}


def _style_on_load(context, layer_id: str, style: Callable) -> None:
    """Style output ``layer_id`` with ``style(layer)`` if Processing will load it on completion."""
    if not context.willLoadLayerOnCompletion(layer_id):
        return
    post = _StyleOnLoad(style)
    _post_processors[layer_id] = post
    context.layerToLoadOnCompletionDetails(layer_id).setPostProcessor(post)


def style_output_on_load(context, layer_id: str, qml_path: str | Path) -> None:
    """Style output ``layer_id`` with ``qml_path`` if Processing will load it on completion."""
    _style_on_load(context, layer_id, lambda layer, qml=str(qml_path): layer.loadNamedStyle(qml))


def load_raster_stretched(context, path: str, name: str, output: str) -> None:
    """Load the raster ``path`` (output ``output``) as layer ``name`` when the run completes, its
    contrast stretched between the 2 % and 98 % cumulative counts of each band."""
    context.addLayerToLoadOnCompletion(path, QgsProcessingContext.LayerDetails(name, context.project(), output))
    _style_on_load(context, path, lambda layer: layer.setContrastEnhancement(
        QgsContrastEnhancement.StretchToMinimumMaximum, QgsRasterMinMaxOrigin.CumulativeCut))
