"""pushbroom:simulatescene — a simulated scene with known truth: onboard and true sensor models,
GCPs, tie points, a DEM and optionally rendered raw images, from a preset sensor."""
from qgis.core import (QgsProcessingOutputFile, QgsProcessingOutputMultipleLayers,
                       QgsProcessingOutputRasterLayer,
                       QgsProcessingParameterNumber)

from ...simulation import runs as use_case
from ...simulation.measurements import GcpSettings
from ...simulation.roads import RoadSettings
from ..parameters import CHECK_FRACTION, PRESET, check_fraction, enum_value, preset, tr
from ..simparameters import (IMAGE_NOISE, IMAGE_SIZE, N_GCPS, N_TIE_POINTS, RENDER, SEED, image_noise, image_size,
                             n_gcps, n_tie_points, output_folder, render, seed)
from .base import PushbroomAlgorithm

MICRO = 1e-6

# Error magnitudes the user may override: (parameter, simulation.presets.ErrorSettings field,
# label, factor from the parameter's unit to the core's SI unit). Each is at most ERROR_LIMITS
# in the parameter's unit: far beyond any onboard error (100 km of position, 0.1 rad of attitude),
# so that a typing error is refused instead of simulating a scene whose rays miss the Earth.
ERROR_PARAMETERS = (
    ("POSITION_BIAS", "position_bias", "Position bias (m)", 1.0),
    ("POSITION_DRIFT", "position_drift", "Position drift (m/s)", 1.0),
    ("POSITION_QUADRATIC", "position_quadratic", "Position 2nd-order term (m/s²)", 1.0),
    ("ATTITUDE_BIAS", "attitude_bias", "Attitude bias (µrad)", MICRO),
    ("ATTITUDE_DRIFT", "attitude_drift", "Attitude drift (µrad/s)", MICRO),
    ("ATTITUDE_QUADRATIC", "attitude_quadratic", "Attitude 2nd-order term (µrad/s²)", MICRO),
    ("CCD_SHIFT", "ccd_shift", "CCD shift (px)", 1.0),
    ("CCD_ROTATION", "ccd_rotation", "CCD rotation (µrad)", MICRO),
    ("FOCAL_ERROR", "focal", "Focal length error at the array end (px)", 1.0),
    ("DISTORTION", "radial_k1", "Radial distortion k1 at the array end (px)", 1.0),
    ("PRINCIPAL_POINT_X_ERROR", "principal_point_x", "Principal point error along track (px)", 1.0),
    ("PRINCIPAL_POINT_Y_ERROR", "principal_point_y", "Principal point error across track (px)", 1.0),
    ("RADIAL_K2_ERROR", "radial_k2", "Radial distortion k2 at the array end (px)", 1.0),
    ("DECENTRING_P1_ERROR", "decentring_p1", "Decentring distortion p1 at the array end (px)", 1.0),
    ("DECENTRING_P2_ERROR", "decentring_p2", "Decentring distortion p2 at the array end (px)", 1.0),
    ("AFFINITY_B1_ERROR", "affinity_b1", "Affinity b1 (px at the array half-length)", 1.0),
    ("AFFINITY_B2_ERROR", "affinity_b2", "Affinity b2 at the array end (px)", 1.0),
    ("AFFINITY_B3_ERROR", "affinity_b3", "Affinity b3 at the array end (px)", 1.0),
    ("INSTALLATION", "installation", "Installation angle error (µrad)", MICRO),
)

ERROR_LIMITS = {"POSITION_BIAS": 1e5, "POSITION_DRIFT": 1e3, "POSITION_QUADRATIC": 1e2, "ATTITUDE_BIAS": 1e5,
                "ATTITUDE_DRIFT": 1e4, "ATTITUDE_QUADRATIC": 1e4, "CCD_SHIFT": 1e3, "CCD_ROTATION": 1e5,
                "INSTALLATION": 1e5}
LENS_LIMIT = 1e3  # px at the array end: every lens and focal-plane term

# Measurement settings: (parameter, simulation.measurements.GcpSettings field, label, default, min, max), all
# real numbers; CHECK_FRACTION (field check_fraction) is the shared definition of ui.parameters.
MEASUREMENT_PARAMETERS = (
    ("GROUND_NOISE_XY", "ground_noise_xy", "Ground planimetric noise (m)", 0.0, 0.0, 1000.0),
    ("GROUND_NOISE_Z", "ground_noise_z", "Ground height noise (m)", 0.0, 0.0, 1000.0),
    ("GROSS_FRACTION", "gross_fraction", "Share of gross errors", 0.0, 0.0, 1.0),
    ("GROSS_MIN", "gross_min", "Smallest gross error (px)", 5.0, 0.0, 1e5),
    ("GROSS_MAX", "gross_max", "Largest gross error (px)", 100.0, 0.0, 1e5),
)


class SimulateSceneAlgorithm(PushbroomAlgorithm):
    ID = "simulatescene"
    NAME = "Simulate a scene"
    GROUP, GROUP_ID = "Simulation", "simulation"
    PRESET, SEED, N_SCENES, N_GCPS, IMAGE_NOISE, RENDER = PRESET, SEED, "N_SCENES", N_GCPS, IMAGE_NOISE, RENDER
    N_LINES, WRONG_LINE_FRACTION, LINES = "N_LINES", "WRONG_LINE_FRACTION", "LINES"
    IMAGE_SIZE, IMAGES = IMAGE_SIZE, "IMAGES"
    OUTPUT_FOLDER = "OUTPUT_FOLDER"
    CORE_PARAMETERS = {use_case.IMAGE_SIZE: IMAGE_SIZE, use_case.FOLDER: OUTPUT_FOLDER}
    ONBOARD_SCENE, TRUE_SCENE, GCPS, DEM = "ONBOARD_SCENE", "TRUE_SCENE", "GCPS", "DEM"
    TIE_POINTS, MANIFEST, IMAGE, REFERENCE = "TIE_POINTS", "MANIFEST", "IMAGE", "REFERENCE"

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API name)
        n_scenes = QgsProcessingParameterNumber(self.N_SCENES, tr("Number of scenes along the strip"),
                                                QgsProcessingParameterNumber.Integer, 1, minValue=1, maxValue=200)
        n_lines = QgsProcessingParameterNumber(self.N_LINES, tr("Number of roads (control lines)"),
                                               QgsProcessingParameterNumber.Integer, 0, minValue=0, maxValue=10000)
        folder = output_folder()
        for p in (preset(), seed(), n_scenes, n_gcps(), image_noise(), render(), n_lines):
            self.addParameter(p)
        self.add_parameter(check_fraction(), advanced=True)
        self.add_parameter(QgsProcessingParameterNumber(self.WRONG_LINE_FRACTION, tr("Share of wrong map lines"),
                                                        QgsProcessingParameterNumber.Double, 0.0, minValue=0.0,
                                                        maxValue=1.0), advanced=True)
        self.addParameter(image_size())
        self.add_parameter(n_tie_points(), advanced=True)
        for name, _, label, default, lo, hi in MEASUREMENT_PARAMETERS:
            self.add_parameter(QgsProcessingParameterNumber(name, tr(label), QgsProcessingParameterNumber.Double,
                                                            default, minValue=lo, maxValue=hi), advanced=True)
        for name, _, label, _ in ERROR_PARAMETERS:
            self.add_parameter(QgsProcessingParameterNumber(name, tr(label), QgsProcessingParameterNumber.Double,
                                                            optional=True, minValue=0.0,
                                                            maxValue=ERROR_LIMITS.get(name, LENS_LIMIT)),
                               advanced=True)
        self.addParameter(folder)
        self.addOutput(QgsProcessingOutputFile(self.ONBOARD_SCENE, tr("Onboard scene model (scene JSON)")))
        self.addOutput(QgsProcessingOutputFile(self.TRUE_SCENE, tr("True scene model (scene JSON)")))
        self.addOutput(QgsProcessingOutputFile(self.GCPS, tr("Ground control points (CSV: id, role, camera, col, "
                                                             "row, lon, lat, h ellipsoidal, sigmas, true values, "
                                                             "gross)")))
        self.addOutput(QgsProcessingOutputFile(self.TIE_POINTS, tr("Tie points (CSV), when requested")))
        self.addOutput(QgsProcessingOutputRasterLayer(self.DEM, tr("DEM (GeoTIFF, EGM96 geoid heights)")))
        self.addOutput(QgsProcessingOutputFile(self.LINES, tr("Control lines (GeoPackage: ground_lines, image_lines, "
                                                              "image_clicks), when requested")))
        self.addOutput(QgsProcessingOutputFile(self.MANIFEST, tr("Simulation settings and drawn errors (JSON)")))
        self.addOutput(QgsProcessingOutputRasterLayer(self.IMAGE, tr("Raw image of the first camera, when rendered")))
        self.addOutput(QgsProcessingOutputMultipleLayers(self.IMAGES, tr("Raw images of every camera, in the "
                                                                         "scene's camera order, when rendered")))
        self.addOutput(QgsProcessingOutputRasterLayer(self.REFERENCE, tr("Reference orthoimage, when rendered")))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        errors = {field: self.parameterAsDouble(parameters, name, context) * factor
                  for name, field, _, factor in ERROR_PARAMETERS if parameters.get(name) not in (None, "")}
        measurements = {field: self.parameterAsDouble(parameters, name, context)
                        for name, field, *_ in MEASUREMENT_PARAMETERS}
        settings = GcpSettings(n_gcps=self.parameterAsInt(parameters, self.N_GCPS, context),
                               image_noise=self.parameterAsDouble(parameters, self.IMAGE_NOISE, context),
                               n_tie_points=self.parameterAsInt(parameters, N_TIE_POINTS, context),
                               check_fraction=self.parameterAsDouble(parameters, CHECK_FRACTION, context),
                               **measurements)
        roads = RoadSettings(n_lines=self.parameterAsInt(parameters, self.N_LINES, context),
                             wrong_fraction=self.parameterAsDouble(parameters, self.WRONG_LINE_FRACTION, context))
        return self.run_core(use_case.run_scene, use_case.SimulateSceneRequest(
            self.parameterAsFileOutput(parameters, self.OUTPUT_FOLDER, context),
            enum_value(self, parameters, self.PRESET, context), self.parameterAsInt(parameters, self.SEED, context),
            self.parameterAsInt(parameters, self.N_SCENES, context),
            self.parameterAsBool(parameters, self.RENDER, context), errors, settings, roads,
            self.parameterAsInt(parameters, self.IMAGE_SIZE, context)), feedback).files
