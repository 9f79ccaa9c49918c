"""pushbroom:matchtiepoints — tie points between the cameras of a three-line scene (or strip), or
on the overlap graph of a block (SCENES; on this machine's cores or a Dask SCHEDULER), matched in a
common ground geometry, written as the tie-point layer the adjustment reads."""
from qgis.core import QgsProcessing

from ...core.runs import matchtiepoints as use_case
from ..inputs import (SCENE_PARAMETERS, add_dem_parameters, add_scene_parameters, matching_settings, raster_files,
                      scene_or_block)
from ..outputs import STYLES, files_in_use, style_output_on_load
from ..parameters import INPUTS, SCENES, SCHEDULER, camera_images, file_layer, matching_parameters, scheduler, tr
from .base import PushbroomAlgorithm


class MatchTiePointsAlgorithm(PushbroomAlgorithm):
    ID = "matchtiepoints"
    NAME = "Match tie points"
    GROUP, GROUP_ID = "Control", "control"
    OUTPUT = "OUTPUT"
    CORE_PARAMETERS = {**SCENE_PARAMETERS, use_case.IMAGES: INPUTS, "base": SCENES}
    SCENE_OR_SCENES = ("match tie points between the cameras of one scene",
                       "match tie points between the images of several scenes")
    IMAGE_FOLDERS = True

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API name)
        add_scene_parameters(self, with_camera=False, or_scenes=True)
        self.addParameter(camera_images())
        add_dem_parameters(self)
        for parameter in matching_parameters():
            self.addParameter(parameter)
        self.add_parameter(scheduler(), advanced=True)
        self.addParameter(file_layer(self.OUTPUT, tr("Matched tie points"), QgsProcessing.TypeVectorPoint))
        self.show_only("SCENE", "SCENES", "INPUTS", "DEM", "HEIGHT", "SPACING", "SEARCH_RANGE")

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        scene, scenes = scene_or_block(self, parameters, context, feedback)
        result = self.run_core(use_case.run, use_case.MatchTiesRequest(
            self.output_path(parameters, context, self.OUTPUT, "matched_tie_points.gpkg"),
            tuple(raster_files(self, parameters, INPUTS, context)), scene, scenes, self.terrain(parameters, context),
            matching_settings(self, parameters, context), files_in_use(self, parameters, context),
            self.parameterAsString(parameters, SCHEDULER, context).strip()), feedback)
        style_output_on_load(context, result.files[self.OUTPUT], STYLES / "tie_points.qml")
        return result.files
