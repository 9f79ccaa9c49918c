"""pushbroom:importlines — control lines: ground lines from any line layer paired by id with the
image lines digitised on the raw image, checked against a scene and written as the one
GeoPackage the adjustment reads (bundleadjust LINES)."""
from qgis.core import (QgsProcessing, QgsProcessingParameterNumber, QgsProcessingParameterString,
                       QgsProcessingParameterVectorLayer)

from ...core.runs import importlines as use_case
from ..inputs import SCENE_PARAMETERS, add_dem_parameters, add_scene_parameters, crs_text, ogr_source, point_heights
from ..outputs import STYLES, files_in_use, style_output_on_load
from ..parameters import SCENE, file_layer, height_source, image_lines, tr, z_datum
from .base import PushbroomAlgorithm


class ImportLinesAlgorithm(PushbroomAlgorithm):
    ID = "importlines"
    NAME = "Import control lines"
    GROUP, GROUP_ID = "Control", "control"
    INPUT, IMAGE_LINES, OUTPUT = "INPUT", "IMAGE_LINES", "OUTPUT"
    ID_FIELD, IMAGE_ID_FIELD = "LINE_ID_FIELD", "IMAGE_ID_FIELD"
    SIGMA_ACROSS, SIGMA_H = "SIGMA_ACROSS", "SIGMA_H"
    HEIGHT_SOURCE, Z_DATUM = "HEIGHT_SOURCE", "Z_DATUM"
    CORE_PARAMETERS = {**SCENE_PARAMETERS, use_case.GROUND_LINES: INPUT, use_case.IMAGE_LINES: IMAGE_LINES}

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API name)
        add_scene_parameters(self, with_camera=False)
        self.addParameter(QgsProcessingParameterVectorLayer(self.INPUT, tr("Ground lines"),
                                                            [QgsProcessing.TypeVectorLine]))
        self.addParameter(QgsProcessingParameterString(self.ID_FIELD, tr("Ground line id field"), optional=True,
                                                       defaultValue="line_id"))
        self.addParameter(image_lines())
        self.addParameter(QgsProcessingParameterString(self.IMAGE_ID_FIELD, tr("Image line id field"),
                                                       defaultValue="line_id"))
        self.addParameter(height_source())
        self.addParameter(z_datum())
        add_dem_parameters(self)
        for name, label, default in ((self.SIGMA_ACROSS, tr("Sigma across the line (m)"), 2.0),
                                     (self.SIGMA_H, tr("Sigma in height (m)"), 3.0)):
            self.addParameter(QgsProcessingParameterNumber(name, label, QgsProcessingParameterNumber.Double,
                                                           default, minValue=1e-6, maxValue=1e4))
        self.addParameter(file_layer(self.OUTPUT, tr("Control lines"), QgsProcessing.TypeVectorLine))
        self.show_only("SCENE", "INPUT", "IMAGE_LINES", "HEIGHT_SOURCE", "DEM", "HEIGHT", "SIGMA_ACROSS", "SIGMA_H")

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        ground_layer = self.parameterAsVectorLayer(parameters, self.INPUT, context)
        ground = ogr_source(self.INPUT, ground_layer, "ground line layer")
        image = ogr_source(self.IMAGE_LINES, self.parameterAsVectorLayer(parameters, self.IMAGE_LINES, context),
                           "image line layer")
        result = self.run_core(use_case.run, use_case.ImportLinesRequest(
            self.output_path(parameters, context, self.OUTPUT, "control_lines.gpkg"),
            self.parameterAsFile(parameters, SCENE, context), ground, image, crs_text(ground_layer.crs()),
            ground_layer.crs().authid(), self.parameterAsString(parameters, self.ID_FIELD, context).strip() or None,
            self.parameterAsString(parameters, self.IMAGE_ID_FIELD, context), point_heights(self, parameters, context),
            self.parameterAsDouble(parameters, self.SIGMA_ACROSS, context),
            self.parameterAsDouble(parameters, self.SIGMA_H, context), files_in_use(self, parameters, context)),
            feedback)
        style_output_on_load(context, result.files[self.OUTPUT], STYLES / "control_lines.qml")
        return result.files
