"""pushbroom:matchgcps — ground control points matched automatically between the raw image and
a reference orthoimage through the scene model, written as the GCP layer the adjustment reads."""
import numpy as np
from qgis.core import QgsProcessing, QgsProcessingException, QgsProcessingParameterVectorDestination

from ...core import measure
from ...core.observations import gcps
from ...core.measure.matching import match_gcps
from ..feedback import core_call, core_log_to, feedback_callbacks, processing_errors
from ..inputs import (add_dem_parameters, add_scene_parameters, camera_for, dem_from_parameters, load_scene_for,
                      matching_settings, raster_file)
from ..outputs import STYLES, geopackage_output, style_output_on_load
from ..parameters import CAMERA, CHECK_FRACTION, SCENE, RasterInput, check_fraction, matching_parameters, tr
from .base import PushbroomAlgorithm


class MatchGcpsAlgorithm(PushbroomAlgorithm):
    ID = "matchgcps"
    NAME = "Match ground control points"
    GROUP, GROUP_ID = "Control", "control"
    INPUT, REFERENCE, OUTPUT = "INPUT", "REFERENCE", "OUTPUT"

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API name)
        self.add_parameter(RasterInput(self.INPUT, tr("Raw image")),
                           tr("The scene's raw image (first band matched), of the size the scene's camera images."))
        add_scene_parameters(self)
        self.add_parameter(RasterInput(self.REFERENCE, tr("Reference orthoimage")),
                           tr("A north-up orthoimage of the scene's ground in a projected or geographic CRS, any GSD "
                              "(first band matched; its nodata value is honoured). It must overlap the scene."))
        add_dem_parameters(self)
        for parameter in matching_parameters():
            self.addParameter(parameter)
        self.addParameter(check_fraction())
        out = QgsProcessingParameterVectorDestination(self.OUTPUT, tr("Matched ground control points"),
                                                      QgsProcessing.TypeVectorPoint)
        out.setSupportsNonFileBasedOutput(False)
        self.add_parameter(out, tr("GeoPackage (.gpkg) point layer of the matched GCPs in EPSG:4979 with the fields "
                                   "of pushbroom:importgcps plus quality and peak_ratio."))
        self.show_only("INPUT", "SCENE", "CAMERA", "REFERENCE", "DEM", "HEIGHT", "SEARCH_RANGE", "CHECK_FRACTION")

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        dest = geopackage_output(self, parameters, context, self.OUTPUT, "matched_gcps.gpkg", "GCP layers")
        image, reference = (self._raster(parameters, context, name) for name in (self.INPUT, self.REFERENCE))
        scene_path = self.parameterAsFile(parameters, SCENE, context)
        scene = load_scene_for(SCENE, scene_path, feedback)
        camera = camera_for(CAMERA, scene, self.parameterAsString(parameters, CAMERA, context))
        surface = dem_from_parameters(self, parameters, context, scene, feedback)
        settings = matching_settings(self, parameters, context)
        progress, is_cancelled = feedback_callbacks(feedback)
        with core_log_to(feedback, measure.__name__):
            result = core_call(match_gcps, scene, camera, image, reference, surface, settings, progress, is_cancelled)
        table = core_call(gcps.check_against_scene, result.table, scene, scene_path, None,
                          self.parameterAsDouble(parameters, CHECK_FRACTION, context))
        with processing_errors(f"{self.OUTPUT}: "):
            gcps.write_gpkg(table, dest, extra={"quality": result.quality, "peak_ratio": result.peak_ratio})
        self._report(result, feedback)
        style_output_on_load(context, dest, STYLES / "gcps.qml")
        feedback.setProgress(100)
        return {self.OUTPUT: dest}

    def _raster(self, parameters, context, name: str) -> str:
        path = raster_file(self, parameters, name, context)
        if not path:
            raise QgsProcessingException(f"{name}: no raster given")
        return path

    @staticmethod
    def _report(result, feedback) -> None:
        n = len(result.table)
        feedback.pushInfo(f"matched {n} of {result.grid_points} grid points in {result.seconds:.1f} s "
                          f"({n / max(result.seconds, 1e-9):.0f} points/s)")
        rejected = ", ".join(f"{v} {k}" for k, v in result.rejected.items() if v)
        feedback.pushInfo(f"rejected: {rejected or 'none'}")
        c = result.coarse
        feedback.pushInfo(f"onboard offset of the whole image (found at 1:{c['factor']}): {c['offset_px'][0]:.1f} px "
                          f"across, {c['offset_px'][1]:.1f} px along track; searched +-{c['search_m']:.0f} m"
                          f"{' (SEARCH_RANGE clipped to the image)' if c['clipped'] else ''}")
        feedback.pushInfo(f"quality (correlation) median {np.median(result.quality):.3f}; sigma_px median "
                          f"{np.median(result.table.sigma_px):.2f} px")
