"""pushbroom:simulateblock — a block of several independent scenes over one ground (tri-stereo,
a stereo pair, two dates, neighbouring strips, an RPC product of another date) or a region of RPC
products (rendered, or without images), with known truth."""
from qgis.core import (QgsProcessingOutputFile, QgsProcessingOutputMultipleLayers,
                       QgsProcessingOutputRasterLayer)

from ...simulation import runs as use_case
from ...simulation.layouts import LAYOUT_MEANINGS
from ...simulation.region import RegionLayout
from ..parameters import CHECK_FRACTION, PRESET, check_fraction, enum_parameter, enum_value, preset, tr
from ..simparameters import (FORWARD_OVERLAP, IMAGE_NOISE, IMAGE_SIZE, N_GCPS, N_TIE_POINTS, PRODUCTS_PER_STRIP,
                             RENDER, SEED, SIDE_LAP, STRIPS, TIES_PER_PRODUCT, image_noise, image_size, n_gcps,
                             n_tie_points, output_folder, region_parameters, render, seed)
from .base import PushbroomAlgorithm


class SimulateBlockAlgorithm(PushbroomAlgorithm):
    ID = "simulateblock"
    NAME = "Simulate a block of scenes"
    GROUP, GROUP_ID = "Simulation", "simulation"
    LAYOUT, SEED, N_GCPS, N_TIE_POINTS, IMAGE_NOISE, RENDER, IMAGE_SIZE = \
        "LAYOUT", SEED, N_GCPS, N_TIE_POINTS, IMAGE_NOISE, RENDER, IMAGE_SIZE
    OUTPUT_FOLDER = "OUTPUT_FOLDER"
    CORE_PARAMETERS = {use_case.IMAGE_SIZE: IMAGE_SIZE, use_case.N_TIE_POINTS: N_TIE_POINTS, use_case.RENDER: RENDER,
                       "strips": STRIPS, "products_per_strip": PRODUCTS_PER_STRIP, "side_lap": SIDE_LAP,
                       "forward_overlap": FORWARD_OVERLAP, "ties_per_product": TIES_PER_PRODUCT,
                       "image_noise": IMAGE_NOISE, "check_fraction": CHECK_FRACTION}
    SCENES, TRUE_SCENES, IMAGES, GCPS, TIE_POINTS, DEM, REFERENCE, MANIFEST = \
        "SCENES", "TRUE_SCENES", "IMAGES", "GCPS", "TIE_POINTS", "DEM", "REFERENCE", "MANIFEST"

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API name)
        self.addParameter(preset())
        self.addParameter(enum_parameter(self.LAYOUT, tr("Block"), LAYOUT_MEANINGS, "tristereo"))
        for parameter in (seed(), n_gcps(), n_tie_points(), image_noise(), render(), image_size()):
            self.addParameter(parameter)
        self.add_parameter(check_fraction(), advanced=True)
        for parameter in region_parameters():
            self.add_parameter(parameter, advanced=True)
        folder = output_folder()
        self.addParameter(folder)
        self.addOutput(QgsProcessingOutputMultipleLayers(self.SCENES, tr("Onboard scene of each scene (scene JSON; "
                                                                         "the RPC file of an RPC product)")))
        self.addOutput(QgsProcessingOutputMultipleLayers(self.TRUE_SCENES, tr("True scene of each scene")))
        self.addOutput(QgsProcessingOutputMultipleLayers(self.IMAGES, tr("Raw image of each scene, when rendered")))
        self.addOutput(QgsProcessingOutputFile(self.GCPS, tr("Ground control points (CSV with a scene column)")))
        self.addOutput(QgsProcessingOutputFile(self.TIE_POINTS, tr("Tie points (CSV with a scene column)")))
        self.addOutput(QgsProcessingOutputRasterLayer(self.DEM, tr("DEM (GeoTIFF, EGM96 geoid heights)")))
        self.addOutput(QgsProcessingOutputRasterLayer(self.REFERENCE, tr("Reference orthoimage, when rendered")))
        self.addOutput(QgsProcessingOutputFile(self.MANIFEST, tr("Block settings and drawn errors (JSON)")))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        return self.run_core(use_case.run_block, use_case.SimulateBlockRequest(
            self.parameterAsFileOutput(parameters, self.OUTPUT_FOLDER, context),
            enum_value(self, parameters, PRESET, context), enum_value(self, parameters, self.LAYOUT, context),
            self.parameterAsInt(parameters, self.SEED, context), self.parameterAsInt(parameters, self.N_GCPS, context),
            self.parameterAsInt(parameters, self.N_TIE_POINTS, context),
            self.parameterAsDouble(parameters, self.IMAGE_NOISE, context),
            self.parameterAsBool(parameters, self.RENDER, context),
            self.parameterAsDouble(parameters, CHECK_FRACTION, context),
            self.parameterAsInt(parameters, self.IMAGE_SIZE, context),
            RegionLayout(self.parameterAsInt(parameters, STRIPS, context),
                         self.parameterAsInt(parameters, PRODUCTS_PER_STRIP, context),
                         self.parameterAsDouble(parameters, SIDE_LAP, context),
                         self.parameterAsDouble(parameters, FORWARD_OVERLAP, context)),
            self.parameterAsInt(parameters, TIES_PER_PRODUCT, context)), feedback).files
