"""pushbroom:exportrpc — RPC00B rational polynomials fitted to the rigorous model, written where
GDAL and QGIS read them, with the fit's check figures per CCD (:mod:`core.runs.exportrpc`)."""
from qgis.core import (QgsProcessingOutputFile, QgsProcessingOutputNumber, QgsProcessingOutputRasterLayer,
                       QgsProcessingParameterFileDestination, QgsProcessingParameterNumber)

from ...core.runs import exportrpc as use_case
from ..inputs import add_dem_parameters, add_scene_parameters, raster_file
from ..outputs import files_in_use
from ..parameters import CAMERA, DEM, SCENE, RasterInput, tr
from .base import PushbroomAlgorithm


class ExportRpcAlgorithm(PushbroomAlgorithm):
    ID = "exportrpc"
    NAME = "Export RPC"
    GROUP, GROUP_ID = "Products", "products"
    HEIGHT_SPAN, GRID, HEIGHT_LEVELS, REGULARISATION = "HEIGHT_SPAN", "GRID", "HEIGHT_LEVELS", "REGULARISATION"
    IMAGE, OUTPUT = "IMAGE", "OUTPUT"
    REPORT, IMAGE_WITH_RPC, RMS_PX, MAX_PX = use_case.REPORT, use_case.IMAGE_WITH_RPC, "RMS_PX", "MAX_PX"
    CORE_PARAMETERS = {"scene": SCENE, "camera": CAMERA, "dem": DEM, use_case.IMAGE: IMAGE,
                       use_case.OUTPUT: OUTPUT}

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API name)
        add_scene_parameters(self)
        add_dem_parameters(self)
        number = QgsProcessingParameterNumber
        self.addParameter(number(self.HEIGHT_SPAN, tr("Height span without a DEM (± m)"), number.Double, 500.0,
                                 minValue=1.0, maxValue=10000.0))
        self.add_parameter(number(self.GRID, tr("Fit grid nodes across and along the image"), number.Integer, 31,
                                  minValue=4, maxValue=201), advanced=True)
        self.add_parameter(number(self.HEIGHT_LEVELS, tr("Fit height levels"), number.Integer, 7, minValue=4,
                                  maxValue=51), advanced=True)
        self.add_parameter(number(self.REGULARISATION, tr("Regularisation (Tikhonov)"), number.Double, 1e-12,
                                  minValue=0.0, maxValue=1e-2), advanced=True)
        self.addParameter(RasterInput(self.IMAGE, tr("Image of this camera (optional)"), optional=True))
        self.addParameter(QgsProcessingParameterFileDestination(self.OUTPUT, tr("RPC file"),
                                                                "RPC text (*_RPC.TXT);;RPB (*.RPB)", defaultValue=None))
        self.addOutput(QgsProcessingOutputFile(self.REPORT, tr("Fit report (JSON): errors overall, per CCD, "
                                                               "at the height-range ends")))
        self.addOutput(QgsProcessingOutputRasterLayer(self.IMAGE_WITH_RPC, tr("Image with RPC (VRT), when "
                                                                              "IMAGE is given")))
        self.addOutput(QgsProcessingOutputNumber(self.RMS_PX, tr("Check RMS error (px)")))
        self.addOutput(QgsProcessingOutputNumber(self.MAX_PX, tr("Check maximum error (px)")))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        request = use_case.RpcRequest(
            self.parameterAsFile(parameters, SCENE, context),
            self.output_path(parameters, context, self.OUTPUT, "image_RPC.TXT"), self.terrain(parameters, context),
            camera=self.parameterAsString(parameters, CAMERA, context),
            height_span=self.parameterAsDouble(parameters, self.HEIGHT_SPAN, context),
            grid=self.parameterAsInt(parameters, self.GRID, context),
            levels=self.parameterAsInt(parameters, self.HEIGHT_LEVELS, context),
            regularisation=self.parameterAsDouble(parameters, self.REGULARISATION, context),
            image=raster_file(self, parameters, self.IMAGE, context), files=files_in_use(self, parameters, context))
        result = self.run_core(use_case.run, request, feedback)
        return {**result.files, self.RMS_PX: result.figures["rms_px"], self.MAX_PX: result.figures["max_px"]}
