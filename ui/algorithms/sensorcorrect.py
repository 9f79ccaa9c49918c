"""pushbroom:sensorcorrect — a raw multi-CCD image resampled onto one straight, distortion-free
virtual detector line: a seamless image with its own scene model and an RPC exact to hundredths
of a pixel (:mod:`core.runs.sensorcorrect`)."""
from __future__ import annotations

from qgis.core import (QgsProcessingOutputFile, QgsProcessingOutputNumber, QgsProcessingOutputRasterLayer,
                       QgsProcessingParameterRasterDestination)

from ...core.runs import sensorcorrect as use_case
from ..inputs import add_dem_parameters, add_scene_parameters, raster_file
from ..outputs import files_in_use
from ..parameters import (CAMERA, DEM, OUTPUT_SCENE, RESAMPLING, SCENE, RasterInput, enum_value, output_scene,
                          resampling, tr)
from .base import PushbroomAlgorithm


class SensorCorrectAlgorithm(PushbroomAlgorithm):
    ID = "sensorcorrect"
    NAME = "Sensor-corrected image (virtual linear array)"
    GROUP, GROUP_ID = "Products", "products"
    INPUT, OUTPUT = "INPUT", "OUTPUT"
    RPC, REPORT, IMAGE_WITH_RPC = use_case.RPC, use_case.REPORT, use_case.IMAGE_WITH_RPC
    RMS_PX, MAX_PX = "RMS_PX", "MAX_PX"
    CORE_PARAMETERS = {"scene": SCENE, "camera": CAMERA, "dem": DEM, use_case.IMAGE: INPUT, use_case.OUTPUT: OUTPUT}

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API name)
        self.addParameter(RasterInput(self.INPUT, tr("Raw image (one camera)")))
        add_scene_parameters(self)
        add_dem_parameters(self)
        self.addParameter(resampling())
        self.addParameter(QgsProcessingParameterRasterDestination(self.OUTPUT, tr("Sensor-corrected image")))
        self.addParameter(output_scene())
        self.addOutput(QgsProcessingOutputFile(self.RPC, tr("RPC of the sensor-corrected image (_RPC.TXT)")))
        self.addOutput(QgsProcessingOutputFile(self.REPORT, tr("RPC fit report (JSON)")))
        self.addOutput(QgsProcessingOutputRasterLayer(self.IMAGE_WITH_RPC, tr("Sensor-corrected image with RPC "
                                                                              "(VRT)")))
        self.addOutput(QgsProcessingOutputNumber(self.RMS_PX, tr("RPC check RMS error (px)")))
        self.addOutput(QgsProcessingOutputNumber(self.MAX_PX, tr("RPC check maximum error (px)")))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        request = use_case.SensorCorrectRequest(
            self.parameterAsFile(parameters, SCENE, context), raster_file(self, parameters, self.INPUT, context),
            self.output_path(parameters, context, self.OUTPUT, "sensor_corrected.tif"),
            self.output_path(parameters, context, OUTPUT_SCENE, "sensor_corrected_scene.json"),
            self.terrain(parameters, context), self.parameterAsString(parameters, CAMERA, context),
            enum_value(self, parameters, RESAMPLING, context), files_in_use(self, parameters, context))
        result = self.run_core(use_case.run, request, feedback)
        return {**result.files, self.RMS_PX: result.figures["rpc_check_rms_px"],
                self.MAX_PX: result.figures["rpc_check_max_px"]}
