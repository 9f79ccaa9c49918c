"""pushbroom:sensorcorrect — a raw multi-CCD image resampled onto one straight, distortion-free
virtual detector line: a seamless image with its own scene model and an RPC exact to hundredths
of a pixel."""
from __future__ import annotations

from pathlib import Path

from qgis.core import (QgsProcessingException, QgsProcessingOutputFile, QgsProcessingOutputNumber,
                       QgsProcessingOutputRasterLayer, QgsProcessingParameterRasterDestination)

from ...core.files import Output
from ...core.model.sensor import SceneModel
from ...core.products import rpcfit
from ...core.products.sensorcorrect import output_files, sensor_correct
from ..feedback import core_call, core_log_to, feedback_callbacks
from ..inputs import (add_dem_parameters, add_scene_parameters, camera_for, dem_from_parameters, load_scene_for,
                      raster_file)
from ..outputs import check_outputs
from ..parameters import (CAMERA, DEM, OUTPUT_SCENE, RESAMPLING, SCENE, RasterInput, enum_value, output_scene,
                          resampling, tr)
from .base import PushbroomAlgorithm


class SensorCorrectAlgorithm(PushbroomAlgorithm):
    ID = "sensorcorrect"
    NAME = "Sensor-corrected image (virtual linear array)"
    GROUP, GROUP_ID = "Products", "products"
    HELP = ("Resamples the raw image of one camera, through the scene's rigorous model (onboard or adjusted) and "
            "the terrain (DEM or constant height), onto a virtual camera: one straight, distortion-free "
            "detector line with as many detectors as the image has columns, fitted through the real detectors "
            "(so it sees the same ground), with the camera's focal length, the principal point on the optical "
            "axis and a constant line period over the same time span. The staggered, separately aligned CCD "
            "chips of a camera such as CBERS-02B HRC or ZY-3 (Zheng et al. 2015; Zhang et al. 2024) become one "
            "seamless image whose RPC is exact to hundredths of a pixel, where an RPC of the raw image is about "
            "1 px RMS (2-3 px at the seams): use it with any program that reads an image and its RPC (QGIS's "
            "warper, gdalwarp -rpc, stereo tools). Ground seen by neither chip next to a seam (misaligned "
            "chips leave gaps of a pixel or two) is interpolated between the two chips' edge pixels. "
            "Written, all or none: OUTPUT (tiled, compressed GeoTIFF with overviews, raw image geometry), "
            "its RPC <name>_RPC.TXT beside it (GDAL finds it by itself) with the fit report <name>_RPC.TXT.json, "
            "<name>.vrt (the image with the RPC in its metadata) and OUTPUT_SCENE, the virtual camera's scene "
            "JSON (info.sensor_corrected says how it was made), which every algorithm reads as SCENE. "
            "Works in tiles on all cores; image positions are computed exactly on a node grid and densified "
            "within 0.01 px, pixels along the seams exactly. Pixels whose ground the raw image does not see "
            "are 0 (nodata).")
    INPUT, OUTPUT = "INPUT", "OUTPUT"
    RPC, REPORT, IMAGE_WITH_RPC, RMS_PX, MAX_PX = "RPC", "REPORT", "IMAGE_WITH_RPC", "RMS_PX", "MAX_PX"

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API name)
        self.add_parameter(RasterInput(self.INPUT, tr("Raw image (one camera)")),
                           tr("The raw image of the camera CAMERA of SCENE (any GDAL format, any bands and data "
                              "type), of the size that camera images."))
        add_scene_parameters(self)
        add_dem_parameters(self)
        self.addParameter(resampling())
        self.add_parameter(QgsProcessingParameterRasterDestination(self.OUTPUT, tr("Sensor-corrected image")),
                           tr("GeoTIFF (.tif) of the sensor-corrected image; <name>_RPC.TXT, its report "
                              "<name>_RPC.TXT.json and <name>.vrt are written beside it."))
        self.addParameter(output_scene())
        self.addOutput(QgsProcessingOutputFile(self.RPC, tr("RPC of the sensor-corrected image (_RPC.TXT)")))
        self.addOutput(QgsProcessingOutputFile(self.REPORT, tr("RPC fit report (JSON)")))
        self.addOutput(QgsProcessingOutputRasterLayer(self.IMAGE_WITH_RPC, tr("Sensor-corrected image with RPC "
                                                                              "(VRT)")))
        self.addOutput(QgsProcessingOutputNumber(self.RMS_PX, tr("RPC check RMS error (px)")))
        self.addOutput(QgsProcessingOutputNumber(self.MAX_PX, tr("RPC check maximum error (px)")))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        output = Path(self.output_path(parameters, context, self.OUTPUT, "sensor_corrected.tif"))
        if output.suffix.lower() not in (".tif", ".tiff"):
            raise QgsProcessingException(f"{self.OUTPUT}: the sensor-corrected image is written as GeoTIFF; use a "
                                         f".tif file (got {output})")
        scene_out = Path(self.output_path(parameters, context, OUTPUT_SCENE, "sensor_corrected_scene.json"))
        derived = output_files(output)
        check_outputs(self, parameters, context, {
            self.OUTPUT: [output, Output(derived["rpc"], "its RPC"), Output(derived["report"], "its RPC report"),
                          Output(derived["vrt"], "its VRT with the RPC")],
            OUTPUT_SCENE: [scene_out]})
        image = raster_file(self, parameters, self.INPUT, context)
        if not image:
            raise QgsProcessingException(f"{self.INPUT}: no raw image given")
        scene_path = self.parameterAsFile(parameters, SCENE, context)
        scene = load_scene_for(SCENE, scene_path, feedback)
        if not isinstance(scene, SceneModel):
            raise QgsProcessingException(f"{SCENE}: {scene_path} is an RPC scene: it has no physical camera whose "
                                         "chips could be resampled onto a straight line, and its image already has "
                                         "one smooth RPC. Sensor correction needs a rigorous model (scene JSON of a "
                                         "rigorous scene, DIMAP or Maxar metadata)")
        camera = camera_for(CAMERA, scene, self.parameterAsString(parameters, CAMERA, context))
        surface = dem_from_parameters(self, parameters, context)
        progress, is_cancelled = feedback_callbacks(feedback)
        with core_log_to(feedback, rpcfit.__name__):
            figures = core_call(sensor_correct, scene, camera, image, surface, output, scene_out,
                                enum_value(self, parameters, RESAMPLING, context),
                                info={"source_scene": str(scene_path), "source_image": image},
                                progress=progress, is_cancelled=is_cancelled)
        feedback.pushInfo(f"sensor-corrected image {figures['cols']} x {figures['rows']} px written in "
                          f"{figures['seconds']:.1f} s; {figures['mapping']}")
        if figures.get("holes"):
            feedback.pushWarning(f"{DEM}: {figures['holes']}")
        feedback.pushInfo(f"RPC fitted to the virtual camera over heights {figures['height_range'][0]:.0f} to "
                          f"{figures['height_range'][1]:.0f} m: independent check RMS {figures['rpc_check_rms_px']:.4f}"
                          f" px, max {figures['rpc_check_max_px']:.4f} px")
        return {self.OUTPUT: str(output), OUTPUT_SCENE: str(scene_out), self.RPC: figures["rpc"],
                self.REPORT: figures["report"], self.IMAGE_WITH_RPC: figures["vrt"],
                self.RMS_PX: figures["rpc_check_rms_px"], self.MAX_PX: figures["rpc_check_max_px"]}
