"""PushbroomAlgorithm, the base of the provider's algorithms and their adapter around the core."""
from __future__ import annotations

from pathlib import Path

from qgis.core import (QgsProcessingAlgorithm, QgsProcessingParameterDefinition, QgsProcessingParameterEnum,
                       QgsProcessingParameterFileDestination, QgsProcessingUtils)
from qgis.PyQt.QtGui import QIcon

from ...core.runs.base import Terrain
from .. import RESOURCES
from ..feedback import feedback_callbacks, processing_errors, push_lines
from ..help import documented_help, help_page, shared_help, short_help
from ..inputs import is_raster_input, raster_file, raster_refusal
from ..parameters import DEM, DEM_DATUM, HEIGHT, enum_refusal, enum_value, tr


class PushbroomAlgorithm(QgsProcessingAlgorithm):
    """Id, name and group from class attributes (NAME and GROUP English, shown through tr()), help from
    docs/algorithms/<ID>.md (ui.help)."""
    ID = ""
    NAME = ""
    GROUP, GROUP_ID = "Sensor model", "sensormodel"
    # The inputs the core's errors and log lines name (InputError.parameter: 'gcps', 'settings.alpha'...) ->
    # this algorithm's parameters, which then start the message.
    CORE_PARAMETERS: dict[str, str] = {}
    SCENE_OR_SCENES = ("work on one scene", "work on a block of scenes")  # for refusing both (ui.inputs.scene_or_block)
    IMAGE_FOLDERS = False  # whether INPUTS may be one folder or list file of raw images (ui.inputs.raster_refusal)

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

    def add_parameter(self, parameter, advanced: bool = False) -> None:
        """Add a parameter (its help from the docs: :meth:`addParameter`), flagged advanced if asked."""
        if advanced:
            parameter.setFlags(parameter.flags() | QgsProcessingParameterDefinition.FlagAdvanced)
        self.addParameter(parameter)

    def addParameter(self, definition, createOutput=True):  # noqa: N802 (QGIS API names)
        """QGIS's addParameter, with the help of the parameter's entry on the algorithm's page, else in
        docs/parameters.md."""
        name = definition.name()
        definition.setHelp(documented_help(self.ID, name, tr) or shared_help(name, tr))
        return super().addParameter(definition, createOutput)

    def show_only(self, *names: str) -> None:
        """Flag every input parameter but ``names`` advanced: the dialog shows ``names`` and the outputs,
        the rest under QGIS's 'Advanced parameters' (at most 8 inputs shown, tests/qgis/test_provider.py)."""
        for definition in self.parameterDefinitions():
            if not definition.isDestination() and definition.name() not in names:
                definition.setFlags(definition.flags() | QgsProcessingParameterDefinition.FlagAdvanced)

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

    def user_destination(self, parameters, context, name: str) -> str:
        """The file output ``name`` was given by the user; '' when not given or temporary (the
        dialog's '[Save to temporary file]', a graphical model's file for an output nobody takes)."""
        if parameters.get(name) in (None, ""):
            return ""
        path = self.parameterAsFileOutput(parameters, name, context) if self.parameterDefinition(name).type() == \
            "fileDestination" else self.parameterAsOutputLayer(parameters, name, context)
        temporary = Path(QgsProcessingUtils.tempFolder()).resolve()
        return "" if not path or temporary in Path(path).resolve().parents else path

    def shortHelpString(self):  # noqa: N802
        inputs = [d for d in self.parameterDefinitions() if not d.isDestination()]
        advanced = QgsProcessingParameterDefinition.FlagAdvanced
        shown = [(d.description(), d.name()) for d in inputs if not d.flags() & advanced]
        outputs = [(d.description(), d.name()) for d in self.parameterDefinitions() if d.isDestination()]
        return short_help(self.ID, tr, shown, len(inputs) - len(shown), outputs)

    def helpUrl(self):  # noqa: N802
        return help_page(self.ID).as_uri()

    def checkParameterValues(self, parameters, context):  # noqa: N802
        """Enumerations take value names only ('' is not given, as '[Not selected]' is); rasters are checked
        by GDAL (ui.parameters.CheckedByGdal); the rest by QGIS."""
        given = dict(parameters)
        for definition in self.parameterDefinitions():
            if isinstance(definition, QgsProcessingParameterEnum):
                refusal = enum_refusal(definition, given.get(definition.name()))
                if given.get(definition.name()) == "":
                    given[definition.name()] = None
            else:
                refusal = raster_refusal(self, parameters, definition, context) if is_raster_input(definition) else ""
            if refusal:
                return False, refusal
        return super().checkParameterValues(given, context)

    def validateInputCrs(self, parameters, context):  # noqa: N802
        """Always true: the inputs lie in different frames by nature (raw images in pixels, the DEM and
        reference in their own CRSs), and QGIS's check would load every input raster as a layer."""
        return True

    # --- the adapter around core calls ---------------------------------------------------------
    def core_errors(self, default: str = ""):
        """Context manager: a core error raised inside becomes a QgsProcessingException that starts with the
        parameter CORE_PARAMETERS gives for its input, else with ``default`` (a parameter name, or '')."""
        return processing_errors(f"{default}: " if default else "", self.CORE_PARAMETERS)

    def push_core_lines(self, feedback, lines) -> None:
        """The core's log lines to the Processing log, named by CORE_PARAMETERS (ui.feedback.push_lines)."""
        push_lines(feedback, lines, self.CORE_PARAMETERS)

    def run_core(self, run, request, feedback):
        """The one core call of an algorithm: ``run(request, progress, is_cancelled)`` of a use case
        (:mod:`core.runs`), its errors named by CORE_PARAMETERS, its log lines pushed in order; returns
        its :class:`core.runs.base.RunResult`."""
        progress, is_cancelled = feedback_callbacks(feedback)
        with self.core_errors():
            result = run(request, progress, is_cancelled)
        self.push_core_lines(feedback, result.lines)
        return result

    def terrain(self, parameters, context) -> Terrain:
        """The terrain of the DEM parameters (ui.inputs.add_dem_parameters): DEM with DEM_DATUM, else HEIGHT."""
        dem = raster_file(self, parameters, DEM, context)
        datum = enum_value(self, parameters, DEM_DATUM, context) if dem else "geoid"
        return Terrain(dem, datum, self.parameterAsDouble(parameters, HEIGHT, context), HEIGHT, DEM)
