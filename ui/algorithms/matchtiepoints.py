"""pushbroom:matchtiepoints — tie points between the cameras of a three-line scene (or strip),
or between the images of several scenes of a block (SCENES, ui.blockmatch), matched
automatically in a common ground geometry, written as the tie-point layer the adjustment reads."""
from qgis.core import QgsProcessing, QgsProcessingException, QgsProcessingParameterVectorDestination

from ...core import measure
from ...core.observations import tiepoints
from ...core.measure.tiematching import match_tiepoints
from ...core.products.ortho import check_images
from ..blockmatch import block_given, match_block, one_scene_file
from ..feedback import check_cancelled, core_call, core_log_to, feedback_callbacks, processing_errors
from ..inputs import (add_dem_parameters, add_scene_parameters, camera_images_for, dem_from_parameters, load_scene_for,
                      matching_settings)
from ..outputs import geopackage_output, write_tie_layer
from ..parameters import INPUTS, SCENE, camera_images, matching_parameters, tr
from .base import PushbroomAlgorithm


class MatchTiePointsAlgorithm(PushbroomAlgorithm):
    ID = "matchtiepoints"
    NAME = "Match tie points"
    GROUP, GROUP_ID = "Control", "control"
    OUTPUT = "OUTPUT"
    SCENE_OR_SCENES = ("match tie points between the cameras of one scene",
                       "match tie points between the images of several scenes")

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API name)
        add_scene_parameters(self, with_camera=False, or_scenes=True)
        self.addParameter(camera_images())
        add_dem_parameters(self)
        for parameter in matching_parameters():
            self.addParameter(parameter)
        out = QgsProcessingParameterVectorDestination(self.OUTPUT, tr("Matched tie points"),
                                                      QgsProcessing.TypeVectorPoint)
        out.setSupportsNonFileBasedOutput(False)
        self.add_parameter(out, tr("GeoPackage (.gpkg) point layer 'tie_points' in EPSG:4979, one feature per "
                                   "observation, with the fields of pushbroom:importtiepoints, styled by the "
                                   "number of cameras seeing each point."))
        self.show_only("SCENE", "SCENES", "INPUTS", "DEM", "HEIGHT", "SPACING", "SEARCH_RANGE")

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        dest = geopackage_output(self, parameters, context, self.OUTPUT, "matched_tie_points.gpkg", "tie-point layers")
        if block_given(self, parameters, context):
            table = match_block(self, parameters, context, feedback)
            return write_tie_layer(table, self.OUTPUT, dest, context, feedback, by_scene=True)
        scene_path = one_scene_file(self, parameters, context)
        scene = load_scene_for(SCENE, scene_path, feedback)
        if len(scene.cameras) < 2:
            raise QgsProcessingException(f"{SCENE}: {scene_path} has one camera ({scene.cameras[0].name}); tie points "
                                         "are matched between the cameras of a scene with two or more (a three-line "
                                         "camera such as TH-1 or ZY-3)")
        images = camera_images_for(self, parameters, context, scene)
        with processing_errors(f"{INPUTS}: "):
            check_images(scene, images)
        for k, image in images.items():
            feedback.pushInfo(f"camera {scene.cameras[k].name}: {image}")
        surface = dem_from_parameters(self, parameters, context, scene, feedback)
        settings = matching_settings(self, parameters, context)
        progress, is_cancelled = feedback_callbacks(feedback)
        with core_log_to(feedback, measure.__name__):
            table, rejected = core_call(match_tiepoints, scene, images, surface, settings, 0,
                                        lambda f, m=None: progress(0.85 * f, m), is_cancelled)
        check_cancelled(feedback)
        self._report_matching(scene, table, rejected, feedback)
        feedback.setProgressText(f"checking and intersecting {len(table)} observations")
        with core_log_to(feedback, tiepoints.__name__):
            table = core_call(tiepoints.check_against_scene, table, scene, scene_path, "matched tie points")
        check_cancelled(feedback)
        return write_tie_layer(table, self.OUTPUT, dest, context, feedback)

    @staticmethod
    def _report_matching(scene, table, rejected: dict, feedback) -> None:
        """Per camera matched against the first: grid points matched, rejections by reason."""
        base = scene.cameras[0].name
        for name, counts in rejected.items():
            matched = int((table.camera == name).sum())
            total = matched + sum(counts.values())
            reasons = ", ".join(f"{v} {k}" for k, v in counts.items() if v) or "none"
            feedback.pushInfo(f"{base}-{name}: matched {matched} of {total} grid points; rejected: {reasons}")
        pairs = tiepoints.summary(table)["pairs"]
        feedback.pushInfo("tie points per camera pair: " + ", ".join(f"{k} {v}" for k, v in pairs.items()))
