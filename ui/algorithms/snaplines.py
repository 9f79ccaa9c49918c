"""pushbroom:snaplines — image lines digitised on a raw image refined to the road's centre or an
edge with sub-pixel profiles across them (core.snapping)."""
import numpy as np
from qgis.core import QgsProcessing, QgsProcessingParameterNumber, QgsProcessingParameterVectorDestination

from ...core.observations import lines as core_lines
from ...core.measure.snapping import SnapSettings, kept_reasons, snap_lines
from ..feedback import processing_errors
from ..inputs import ogr_source, raster_file
from ..outputs import geopackage_output
from ..parameters import RasterInput, enum_parameter, enum_value, image_lines, tr
from .base import PushbroomAlgorithm

DEFAULTS = SnapSettings()


class SnapLinesAlgorithm(PushbroomAlgorithm):
    ID = "snaplines"
    NAME = "Snap image lines to the image"
    GROUP, GROUP_ID = "Control", "control"
    HELP = ("Refines image lines digitised on the raw image (clicks a few pixels off) to the image feature they "
            "show: the centre of a road-like band or an edge. For every vertex, profiles across the line within "
            "REACH px of it are sampled over ±SEARCH px; the feature's sub-pixel position on each and a straight "
            "line through them give the vertex's refined position across the line and its own sigma (M value of "
            "the output; never below 0.1 px). A vertex where too few profiles find the feature, or where they "
            "disagree by more than MAX_SIGMA px (a junction, a CCD seam, texture), keeps its position and sigma; "
            "the log counts both and why. Vertices only move across the line: the along-line position of a line "
            "point is free in the adjustment anyway. The inputs are only read.")
    INPUT, IMAGE_LINES, OUTPUT, MODE, POLARITY = "INPUT", "IMAGE_LINES", "OUTPUT", "MODE", "POLARITY"
    WIDTH, SEARCH, REACH, MAX_SIGMA = "WIDTH", "SEARCH", "REACH", "MAX_SIGMA"

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
        dest = geopackage_output(self, parameters, context, self.OUTPUT, "snapped_lines.gpkg", "snapped lines")
        image = raster_file(self, parameters, self.INPUT, context)
        path, name = ogr_source(self.IMAGE_LINES, self.parameterAsVectorLayer(parameters, self.IMAGE_LINES, context),
                                "image line layer")
        settings = SnapSettings(mode=enum_value(self, parameters, self.MODE, context),
                                polarity=1 if enum_value(self, parameters, self.POLARITY, context) == "bright" else -1,
                                width=self.parameterAsDouble(parameters, self.WIDTH, context),
                                search=self.parameterAsDouble(parameters, self.SEARCH, context),
                                reach=self.parameterAsDouble(parameters, self.REACH, context),
                                max_sigma=self.parameterAsDouble(parameters, self.MAX_SIGMA, context))
        with processing_errors(f"{self.WIDTH}, {self.SEARCH}, {self.REACH}, {self.MAX_SIGMA}: "):
            settings.validate()
        with processing_errors(f"{self.IMAGE_LINES}: "):
            lines = core_lines.read_image_lines(path, name)
        with processing_errors(f"{self.INPUT}: "):
            result = snap_lines(image, lines, settings)
        part = lines.vertex_part()
        refined = np.bincount(part, weights=result.refined, minlength=len(lines)).astype(int).tolist()
        with processing_errors(f"{self.OUTPUT}: "):
            core_lines.write_gpkg(dest, image=result.lines, extra_image={"refined": refined})
        n, moved = int(result.refined.sum()), result.moved[result.refined]
        feedback.pushInfo(f"{n} of {result.refined.size} vertices refined ({settings.mode}; median move "
                          f"{np.median(moved) if n else 0:.2f} px, median sigma "
                          f"{np.median(result.lines.sigma_px[result.refined]) if n else 0:.2f} px)")
        for reason, count in kept_reasons(result, settings).items():
            feedback.pushWarning(f"{count} vertices kept their position: {reason}")
        return {self.OUTPUT: dest}
