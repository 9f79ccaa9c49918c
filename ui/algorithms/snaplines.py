"""pushbroom:snaplines — image lines digitised on a raw image refined to the road's centre or an
edge with sub-pixel profiles across them (core.snapping)."""
from qgis.core import QgsProcessing, QgsProcessingParameterNumber, QgsProcessingParameterVectorDestination

from ...core.measure.snapping import SnapSettings
from ...core.runs import snaplines as use_case
from ..inputs import ogr_source, raster_file
from ..outputs import files_in_use
from ..parameters import RasterInput, enum_parameter, enum_value, image_lines, tr
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
        self.add_parameter(RasterInput(self.INPUT, tr("Raw image")),
                           tr("The raw image the lines were digitised on (or its display copy from 'Prepare "
                              "digitising'); band 1 is used."))
        self.addParameter(image_lines())
        self.addParameter(enum_parameter(
            self.MODE, tr("Feature"),
            {"centre": tr("the centre line of a band WIDTH px wide (a road, a canal)"),
             "edge": tr("the strongest edge (a field boundary, a shore)")}, "centre",
            tr("What the lines are snapped to.")))
        self.addParameter(enum_parameter(
            self.POLARITY, tr("Band polarity"),
            {"bright": tr("brighter than its surroundings (a road)"), "dark": tr("darker (a canal, a hedge)")},
            "bright", tr("In MODE=centre, whether the band is bright or dark.")))
        for name, label, default, lo, hi, help_text, advanced in (
                (self.WIDTH, tr("Band width (px)"), DEFAULTS.width, 0.5, 100.0,
                 tr("Width of the band in MODE=centre, in pixels (a 7 m road on a 2.4 m image: 3 px)."), False),
                (self.SEARCH, tr("Search distance (px)"), DEFAULTS.search, 1.0, 200.0,
                 tr("How far across the line (each side) the feature is looked for: more than the clicks' "
                    "error, less than the distance to the next similar feature."), False),
                (self.REACH, tr("Profiles along the line (px)"), DEFAULTS.reach, 0.0, 100.0,
                 tr("Profiles are taken every pixel within this distance of a vertex along the line."), True),
                (self.MAX_SIGMA, tr("Largest accepted sigma (px)"), DEFAULTS.max_sigma, 0.11, 100.0,
                 tr("A vertex whose refined position is less certain than this keeps its position."), True)):
            self.add_parameter(QgsProcessingParameterNumber(name, label, QgsProcessingParameterNumber.Double,
                                                            default, minValue=lo, maxValue=hi),
                               help_text, advanced=advanced)
        out = QgsProcessingParameterVectorDestination(self.OUTPUT, tr("Snapped image lines"),
                                                      QgsProcessing.TypeVectorLine)
        out.setSupportsNonFileBasedOutput(False)
        self.add_parameter(out, tr("GeoPackage (.gpkg) with the layer image_lines as IMAGE_LINES (x = column, "
                                   "y = -row, M = each vertex's sigma in px) and per line the number of vertices "
                                   "refined (field refined); 'Import control lines' reads it as IMAGE_LINES."))

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
