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
    HELP = ("Finds ground control points without a click, as Zheng et al. 2015 did for CBERS-02B: a grid of points "
            "over the raw image is matched against a reference orthoimage (a national orthophoto, a Sentinel-2 "
            "scene, an earlier adjusted product; any projected or geographic CRS and GSD) through the scene's model "
            "and the DEM. "
            "For each point the reference is resampled into the raw image's geometry (the onboard model maps each "
            "pixel of the window to the DEM). The onboard offset is found coarse to fine over an image pyramid: the "
            "whole image first, over the whole SEARCH_RANGE (a range beyond the image is clipped to it, and the log "
            "says so), then local chips at finer levels; each window is then searched within FINE_RADIUS "
            "(normalised cross-correlation by FFT), refined by least-squares matching with gain and offset (Gruen "
            "1985) and checked backward. Weak matches are rejected and counted by reason (low texture, low "
            "correlation: clouds, water, changed land cover; ambiguous peaks; fits that fail; backward matches "
            "that disagree; windows leaving the image or the reference or straddling a CCD seam; offsets that "
            "disagree with the neighbours'; points where the DEM has no height); what passes may still hold a few "
            "gross errors, which the adjustment's robust estimation removes. Each GCP is the ground point the "
            "onboard model sees at a grid point (lon, lat and the DEM's ellipsoidal height) at the matched image "
            "position, with fields quality (the correlation peak), peak_ratio (second peak / first) and sigma_px "
            "(from the least-squares fit, at least 0.07 px). The output is the GeoPackage layer pushbroom:importgcps "
            "writes, read directly by pushbroom:bundleadjust (use robust estimation).")
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
