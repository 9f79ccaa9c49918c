"""pushbroom:preparedigitising — display copy of a raw image and an empty image-line layer."""
from qgis.core import QgsProcessingContext, QgsProcessingParameterFileDestination

from ...core.observations.lines import IMAGE_LAYER
from ...core.runs import preparedigitising as use_case
from ..inputs import SCENE_PARAMETERS, add_scene_parameters, raster_file
from ..outputs import files_in_use
from ..parameters import CAMERA, SCENE, RasterInput, tr
from .base import PushbroomAlgorithm


class PrepareDigitisingAlgorithm(PushbroomAlgorithm):
    ID = "preparedigitising"
    NAME = "Prepare digitising control lines"
    GROUP, GROUP_ID = "Control", "control"
    INPUT, OUTPUT, OUTPUT_LINES = "INPUT", "OUTPUT", "OUTPUT_LINES"
    CORE_PARAMETERS = {**SCENE_PARAMETERS, use_case.IMAGE: INPUT}

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API name)
        self.addParameter(RasterInput(self.INPUT, tr("Raw image")))
        add_scene_parameters(self)
        self.addParameter(QgsProcessingParameterFileDestination(self.OUTPUT, tr("Display copy"),
                                                                fileFilter="Virtual raster (*.vrt)"))
        self.addParameter(QgsProcessingParameterFileDestination(self.OUTPUT_LINES, tr("Empty image-line layer"),
                                                                fileFilter="GeoPackage (*.gpkg)", optional=True))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        result = self.run_core(use_case.run, use_case.PrepareRequest(
            self.parameterAsFile(parameters, SCENE, context), raster_file(self, parameters, self.INPUT, context),
            self.parameterAsFileOutput(parameters, self.OUTPUT, context),
            self.parameterAsFileOutput(parameters, self.OUTPUT_LINES, context),
            self.parameterAsString(parameters, CAMERA, context), files_in_use(self, parameters, context)), feedback)
        output, lines, camera = result.files[self.OUTPUT], result.files[self.OUTPUT_LINES], result.figures["camera"]
        details = QgsProcessingContext.LayerDetails(tr("Display copy ({camera})").format(camera=camera),
                                                    context.project(), self.OUTPUT)
        context.addLayerToLoadOnCompletion(output, details)
        if lines:
            context.addLayerToLoadOnCompletion(f"{lines}|layername={IMAGE_LAYER}", QgsProcessingContext.LayerDetails(
                tr("Image lines ({camera})").format(camera=camera), context.project(), self.OUTPUT_LINES))
        return {self.OUTPUT: output, self.OUTPUT_LINES: lines or None}
