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
        self.add_parameter(
            QgsProcessingParameterNumber(self.HEIGHT_SPAN, tr("Height span without a DEM (± m)"),
                                         QgsProcessingParameterNumber.Double, 500.0, minValue=1.0,
                                         maxValue=10000.0),
            tr("Without a DEM the RPC is fitted from HEIGHT - HEIGHT_SPAN to HEIGHT + HEIGHT_SPAN (metres, "
               "ellipsoidal); outside that range it extrapolates. With a DEM, the range is the DEM's heights over "
               "the image plus a margin (10 % of their span, at least 50 m)."))
        self.add_parameter(
            QgsProcessingParameterNumber(self.GRID, tr("Fit grid nodes across and along the image"),
                                         QgsProcessingParameterNumber.Integer, 31, minValue=4, maxValue=201),
            tr("The rigorous model is sampled on this many image columns and rows (image edges included) at "
               "each height level; 31 is plenty for a cubic RPC."), advanced=True)
        self.add_parameter(
            QgsProcessingParameterNumber(self.HEIGHT_LEVELS, tr("Fit height levels"),
                                         QgsProcessingParameterNumber.Integer, 7, minValue=4, maxValue=51),
            tr("Number of heights, from the bottom to the top of the height range, at which the grid is "
               "sampled (a cubic in height needs at least 4)."), advanced=True)
        self.add_parameter(
            QgsProcessingParameterNumber(self.REGULARISATION, tr("Regularisation (Tikhonov)"),
                                         QgsProcessingParameterNumber.Double, 1e-12, minValue=0.0, maxValue=1e-2),
            tr("Ridge weight, relative to the normalised normal equations, that keeps the denominators tame. "
               "It is raised 100-fold at a time (up to 1e-4; the value used is reported) while the denominator "
               "vanishes at a fit node or the independent check's largest error exceeds twice the fit's."),
            advanced=True)
        self.add_parameter(
            RasterInput(self.IMAGE, tr("Image of this camera (optional)"), optional=True),
            tr("The raw image of the scene's camera (same size). When given, a VRT named after OUTPUT (e.g. "
               "scene_RPC.TXT -> scene.vrt) is written beside OUTPUT: the image unchanged with the RPC in its "
               "metadata, for GDAL and QGIS. The image file is never modified."))
        self.add_parameter(
            QgsProcessingParameterFileDestination(self.OUTPUT, tr("RPC file"), "RPC text (*_RPC.TXT);;RPB (*.RPB)",
                                                  defaultValue=None),
            tr("Where to write the RPC: a name ending in _RPC.TXT writes GDAL's RPC text (the DigitalGlobe "
               "'KEY: value' layout), .RPB the RPB layout. GDAL uses it for an image called <name>.<ext> in the "
               "same folder. The fit report is written beside it as <OUTPUT>.json."))
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
