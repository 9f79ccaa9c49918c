"""pushbroom:importlines — control lines: ground lines from any line layer paired by id with the
image lines digitised on the raw image, checked against a scene and written as the one
GeoPackage the adjustment reads (bundleadjust LINES)."""
from pathlib import Path

import numpy as np
from qgis.core import (QgsProcessing, QgsProcessingException, QgsProcessingParameterNumber,
                       QgsProcessingParameterString, QgsProcessingParameterVectorDestination,
                       QgsProcessingParameterVectorLayer)

from ...core.adjust.linepoints import ControlLines, check_against_scene
from ...core.observations import lines as core_lines
from ..feedback import check_cancelled, processing_errors
from ..inputs import add_dem_parameters, add_scene_parameters, heights_from_parameters, load_scene_for, ogr_source
from ..outputs import STYLES, geopackage_output, style_output_on_load
from ..parameters import SCENE, height_source, image_lines, tr, z_datum
from .base import PushbroomAlgorithm


class ImportLinesAlgorithm(PushbroomAlgorithm):
    ID = "importlines"
    NAME = "Import control lines"
    GROUP, GROUP_ID = "Control", "control"
    INPUT, IMAGE_LINES, OUTPUT = "INPUT", "IMAGE_LINES", "OUTPUT"
    ID_FIELD, IMAGE_ID_FIELD = "LINE_ID_FIELD", "IMAGE_ID_FIELD"
    SIGMA_ACROSS, SIGMA_H = "SIGMA_ACROSS", "SIGMA_H"
    HEIGHT_SOURCE, Z_DATUM = "HEIGHT_SOURCE", "Z_DATUM"

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API name)
        add_scene_parameters(self, with_camera=False)
        self.add_parameter(QgsProcessingParameterVectorLayer(self.INPUT, tr("Ground lines"),
                                                             [QgsProcessing.TypeVectorLine]),
                           tr("Any line layer (LineString or MultiLineString, 2D or 3D) in any CRS: roads, canals, "
                              "field boundaries. Heights as HEIGHT_SOURCE says."))
        self.add_parameter(QgsProcessingParameterString(self.ID_FIELD, tr("Ground line id field"), optional=True,
                                                        defaultValue="line_id"),
                           tr("Field with each ground line's id (what image lines pair to). Empty: feature ids."))
        self.addParameter(image_lines())
        self.add_parameter(QgsProcessingParameterString(self.IMAGE_ID_FIELD, tr("Image line id field"),
                                                        defaultValue="line_id"),
                           tr("Field of the image lines naming the ground line each shows."))
        self.addParameter(height_source())
        self.addParameter(z_datum())
        add_dem_parameters(self)
        for name, label, default in ((self.SIGMA_ACROSS, tr("Sigma across the line (m)"), 2.0),
                                     (self.SIGMA_H, tr("Sigma in height (m)"), 3.0)):
            self.add_parameter(QgsProcessingParameterNumber(name, label, QgsProcessingParameterNumber.Double,
                                                            default, minValue=1e-6, maxValue=1e4),
                               tr("Used where the layer has no sigma_across / sigma_h field value."))
        out = QgsProcessingParameterVectorDestination(self.OUTPUT, tr("Control lines"), QgsProcessing.TypeVectorLine)
        out.setSupportsNonFileBasedOutput(False)
        self.add_parameter(out, tr("GeoPackage (.gpkg) with the layers ground_lines and image_lines."))
        self.show_only("SCENE", "INPUT", "IMAGE_LINES", "HEIGHT_SOURCE", "DEM", "HEIGHT", "SIGMA_ACROSS", "SIGMA_H")

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        dest = geopackage_output(self, parameters, context, self.OUTPUT, "control_lines.gpkg", "control lines")
        scene_path = self.parameterAsFile(parameters, SCENE, context)
        scene = load_scene_for(SCENE, scene_path, feedback)
        lines = self._read(parameters, context)
        check_cancelled(feedback)
        feedback.setProgress(40)
        with processing_errors():
            points, table, outside = check_against_scene(scene, lines)
        ids = table["line_id"].tolist()
        ground = lines.ground
        extra_ground = {"outside": [int(i in set(outside.tolist())) for i in ground.id],
                        "apriori_rms_m": [float(table["rms_across_m"][ids.index(i)]) if i in ids else None
                                          for i in ground.id],
                        "apriori_max_m": [float(table["max_across_m"][ids.index(i)]) if i in ids else None
                                          for i in ground.id]}
        per_part = _per_image_line(lines.image, points["across_m"])
        with processing_errors(f"{self.OUTPUT}: "):
            core_lines.write_gpkg(dest, ground, lines.image, extra_ground=extra_ground,
                                  extra_image={"apriori_rms_m": per_part})
        feedback.pushInfo(f"{len(ground)} ground line part(s), {len(lines.image)} image line(s) with "
                          f"{len(points['line_id'])} points; a-priori across-line offsets (onboard model): "
                          + ", ".join(f"{i} {r:.1f} m" for i, r in list(zip(ids, table["rms_across_m"]))[:20]))
        if outside.size:
            feedback.pushWarning(f"{outside.size} ground line(s) outside the scene (no image line pairs them; kept, "
                                 f"outside = 1): {', '.join(outside[:20].tolist())}")
        style_output_on_load(context, dest, STYLES / "control_lines.qml")
        feedback.setProgress(100)
        return {self.OUTPUT: dest}

    def _read(self, parameters, context) -> ControlLines:
        ground_layer = self.parameterAsVectorLayer(parameters, self.INPUT, context)
        path, name = ogr_source(self.INPUT, ground_layer, "ground line layer")
        image_path, image_name = ogr_source(self.IMAGE_LINES, self.parameterAsVectorLayer(
            parameters, self.IMAGE_LINES, context), "image line layer")
        if Path(path).resolve() == Path(image_path).resolve() and name == image_name:
            raise QgsProcessingException(f"{self.IMAGE_LINES}: the same layer as {self.INPUT}; give the image lines "
                                         "digitised on the raw image")
        heights = heights_from_parameters(self, parameters, context, ground_layer.crs())
        id_field = self.parameterAsString(parameters, self.ID_FIELD, context).strip() or None
        sigma_a = self.parameterAsDouble(parameters, self.SIGMA_ACROSS, context)
        sigma_h = self.parameterAsDouble(parameters, self.SIGMA_H, context)
        with processing_errors(f"{self.INPUT}: "):
            ground = core_lines.read_ground_lines(path, name, id_field, heights, sigma_a, sigma_h)
        with processing_errors(f"{self.IMAGE_LINES}: "):
            image = core_lines.read_image_lines(image_path, image_name,
                                                self.parameterAsString(parameters, self.IMAGE_ID_FIELD, context))
        return ControlLines(ground, image)


def _per_image_line(image: core_lines.ImageLines, across):
    """RMS (m) of the a-priori across-line offsets per image line part."""
    part = image.vertex_part()
    n = np.bincount(part, minlength=len(image))
    return (np.sqrt(np.bincount(part, weights=across ** 2, minlength=len(image)) / np.maximum(n, 1))).tolist()
