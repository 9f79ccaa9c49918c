"""pushbroom:preparedigitising — display copy of a raw image and an empty image-line layer."""
from qgis.core import QgsProcessingContext, QgsProcessingParameterFileDestination

from ...core.measure.display import check_image_size, write_display_vrt, write_empty_lines
from ...core.files import atomic_outputs
from ...core.observations.lines import IMAGE_LAYER
from ..feedback import processing_errors
from ..inputs import add_scene_parameters, camera_for, load_scene_for, raster_file
from ..outputs import check_outputs
from ..parameters import CAMERA, SCENE, RasterInput, tr
from .base import PushbroomAlgorithm


class PrepareDigitisingAlgorithm(PushbroomAlgorithm):
    ID = "preparedigitising"
    NAME = "Prepare digitising control lines"
    GROUP, GROUP_ID = "Control", "control"
    HELP = ("Makes a raw image ready for digitising control lines on it. QGIS warps a raw image that carries RPC "
            "or GCP metadata to the ground on display, and draws one without any in an unnamed frame; the "
            "display copy (a small VRT referencing the raw image, nothing copied) shows it in the pixel frame "
            "'Pushbroom image pixels': x = column, y = -row. Digitise there with the dock 'Digitise control "
            "lines on the raw image' (Plugins menu, Pushbroom Adjust), or with QGIS's own editing tools in the "
            "empty image-line layer. The input image is only read.")
    INPUT, OUTPUT, OUTPUT_LINES = "INPUT", "OUTPUT", "OUTPUT_LINES"

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API name)
        self.add_parameter(RasterInput(self.INPUT, tr("Raw image")),
                           tr("The raw (unrectified) image of the scene's camera CAMERA, with the camera's number "
                              "of columns and rows."))
        add_scene_parameters(self)
        self.add_parameter(QgsProcessingParameterFileDestination(self.OUTPUT, tr("Display copy"),
                                                                 fileFilter="Virtual raster (*.vrt)"),
                           tr("VRT (.vrt) showing the raw image in the pixel frame, without its RPC and GCPs; it "
                              "names SCENE and CAMERA for the digitising dock."))
        self.add_parameter(QgsProcessingParameterFileDestination(self.OUTPUT_LINES, tr("Empty image-line layer"),
                                                                 fileFilter="GeoPackage (*.gpkg)", optional=True),
                           tr("GeoPackage with an empty layer 'image_lines' (LineString M, x = column, y = -row, "
                              "M = a vertex's sigma in px; fields line_id (the ground line's id), camera, "
                              "sigma_px), to digitise in with QGIS's own tools. Optional."))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        check_outputs(self, parameters, context)
        scene = load_scene_for(SCENE, self.parameterAsFile(parameters, SCENE, context), feedback)
        camera = scene.cameras[camera_for(CAMERA, scene, self.parameterAsString(parameters, CAMERA, context))]
        image = raster_file(self, parameters, self.INPUT, context)
        output = self.parameterAsFileOutput(parameters, self.OUTPUT, context)
        lines = self.parameterAsFileOutput(parameters, self.OUTPUT_LINES, context)
        with processing_errors(f"{self.INPUT}: "):
            check_image_size(image, camera.cols, camera.rows, camera.name)
        with processing_errors(), atomic_outputs() as files:
            write_display_vrt(image, output, self.parameterAsFile(parameters, SCENE, context), camera.name, files)
            if lines:
                write_empty_lines(lines, files)
        details = QgsProcessingContext.LayerDetails(tr("Display copy ({camera})").format(camera=camera.name),
                                                    context.project(), self.OUTPUT)
        context.addLayerToLoadOnCompletion(output, details)
        if lines:
            context.addLayerToLoadOnCompletion(f"{lines}|layername={IMAGE_LAYER}", QgsProcessingContext.LayerDetails(
                tr("Image lines ({camera})").format(camera=camera.name), context.project(), self.OUTPUT_LINES))
        return {self.OUTPUT: output, self.OUTPUT_LINES: lines or None}
