"""pushbroom:snaplines — image lines digitised on a raw image refined to the road's centre or an
edge with sub-pixel profiles across them (core.snapping)."""
from qgis.core import QgsProcessing, QgsProcessingParameterNumber

from ...core.measure.snapping import SnapSettings
from ...core.runs import snaplines as use_case
from ..inputs import ogr_source, raster_file
from ..outputs import files_in_use
from ..parameters import RasterInput, enum_parameter, enum_value, file_layer, image_lines, tr
from .base import PushbroomAlgorithm

DEFAULTS = SnapSettings()


class SnapLinesAlgorithm(PushbroomAlgorithm):
    ID = "snaplines"
    NAME = "Snap image lines to the image"
    GROUP, GROUP_ID = "Control", "control"
    INPUT, IMAGE_LINES, OUTPUT, MODE, POLARITY = "INPUT", "IMAGE_LINES", "OUTPUT", "MODE", "POLARITY"
    WIDTH, SEARCH, REACH, MAX_SIGMA = "WIDTH", "SEARCH", "REACH", "MAX_SIGMA"
    CORE_PARAMETERS = {use_case.IMAGE: INPUT, use_case.IMAGE_LINES: IMAGE_LINES,
                       use_case.SETTINGS: f"{WIDTH}, {SEARCH}, {REACH}, {MAX_SIGMA}"}

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API name)
        self.addParameter(RasterInput(self.INPUT, tr("Raw image")))
        self.addParameter(image_lines())
        self.addParameter(enum_parameter(
            self.MODE, tr("Feature"),
            {"centre": tr("the centre line of a band WIDTH px wide (a road, a canal)"),
             "edge": tr("the strongest edge (a field boundary, a shore)")}, "centre"))
        self.addParameter(enum_parameter(
            self.POLARITY, tr("Band polarity"),
            {"bright": tr("brighter than its surroundings (a road)"), "dark": tr("darker (a canal, a hedge)")},
            "bright"))
        for name, label, default, lo, hi, advanced in (
                (self.WIDTH, tr("Band width (px)"), DEFAULTS.width, 0.5, 100.0, False),
                (self.SEARCH, tr("Search distance (px)"), DEFAULTS.search, 1.0, 200.0, False),
                (self.REACH, tr("Profiles along the line (px)"), DEFAULTS.reach, 0.0, 100.0, True),
                (self.MAX_SIGMA, tr("Largest accepted sigma (px)"), DEFAULTS.max_sigma, 0.11, 100.0, True)):
            self.add_parameter(QgsProcessingParameterNumber(name, label, QgsProcessingParameterNumber.Double,
                                                            default, minValue=lo, maxValue=hi), advanced=advanced)
        self.addParameter(file_layer(self.OUTPUT, tr("Snapped image lines"), QgsProcessing.TypeVectorLine))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        lines = ogr_source(self.IMAGE_LINES, self.parameterAsVectorLayer(parameters, self.IMAGE_LINES, context),
                           "image line layer")
        settings = SnapSettings(mode=enum_value(self, parameters, self.MODE, context),
                                polarity=1 if enum_value(self, parameters, self.POLARITY, context) == "bright" else -1,
                                width=self.parameterAsDouble(parameters, self.WIDTH, context),
                                search=self.parameterAsDouble(parameters, self.SEARCH, context),
                                reach=self.parameterAsDouble(parameters, self.REACH, context),
                                max_sigma=self.parameterAsDouble(parameters, self.MAX_SIGMA, context))
        return self.run_core(use_case.run, use_case.SnapRequest(
            self.output_path(parameters, context, self.OUTPUT, "snapped_lines.gpkg"),
            raster_file(self, parameters, self.INPUT, context), lines, settings,
            files_in_use(self, parameters, context)), feedback).files
