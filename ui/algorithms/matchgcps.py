"""pushbroom:matchgcps — ground control points matched automatically between the raw image and
a reference orthoimage through the scene model, written as the GCP layer the adjustment reads."""
from qgis.core import QgsProcessing

from ...core.runs import matchgcps as use_case
from ..inputs import SCENE_PARAMETERS, add_dem_parameters, add_scene_parameters, matching_settings, raster_file
from ..outputs import STYLES, files_in_use, style_output_on_load
from ..parameters import CAMERA, CHECK_FRACTION, SCENE, RasterInput, check_fraction, file_layer, matching_parameters, tr
from .base import PushbroomAlgorithm


class MatchGcpsAlgorithm(PushbroomAlgorithm):
    ID = "matchgcps"
    NAME = "Match ground control points"
    GROUP, GROUP_ID = "Control", "control"
    INPUT, REFERENCE, OUTPUT = "INPUT", "REFERENCE", "OUTPUT"
    CORE_PARAMETERS = {**SCENE_PARAMETERS, use_case.IMAGE: INPUT, use_case.REFERENCE: REFERENCE}

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API name)
        self.addParameter(RasterInput(self.INPUT, tr("Raw image")))
        add_scene_parameters(self)
        self.addParameter(RasterInput(self.REFERENCE, tr("Reference orthoimage")))
        add_dem_parameters(self)
        for parameter in matching_parameters():
            self.addParameter(parameter)
        self.addParameter(check_fraction())
        self.addParameter(file_layer(self.OUTPUT, tr("Matched ground control points"), QgsProcessing.TypeVectorPoint))
        self.show_only("INPUT", "SCENE", "CAMERA", "REFERENCE", "DEM", "HEIGHT", "SEARCH_RANGE", "CHECK_FRACTION")

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        result = self.run_core(use_case.run, use_case.MatchGcpsRequest(
            self.output_path(parameters, context, self.OUTPUT, "matched_gcps.gpkg"),
            self.parameterAsFile(parameters, SCENE, context), raster_file(self, parameters, self.INPUT, context),
            raster_file(self, parameters, self.REFERENCE, context), self.terrain(parameters, context),
            self.parameterAsString(parameters, CAMERA, context), matching_settings(self, parameters, context),
            self.parameterAsDouble(parameters, CHECK_FRACTION, context), files_in_use(self, parameters, context)),
            feedback)
        style_output_on_load(context, result.files[self.OUTPUT], STYLES / "gcps.qml")
        return result.files
