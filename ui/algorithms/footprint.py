"""pushbroom:footprint — ground outline of each camera's image, or of every product of a block or
region (SCENES: files, folders, list files), as polygons."""
from qgis.core import (QgsCoordinateReferenceSystem, QgsFeature, QgsGeometry, QgsLineString, QgsPolygon,
                       QgsProcessing, QgsProcessingParameterFeatureSink, QgsProcessingParameterNumber, QgsWkbTypes)
from qgis.PyQt.QtCore import QVariant

from ...core.runs import footprint as use_case
from ..inputs import SCENE_PARAMETERS, add_dem_parameters, add_scene_parameters, scene_or_block
from ..outputs import STYLES, files_in_use, output_fields, output_sink, style_output_on_load
from ..parameters import tr
from .base import PushbroomAlgorithm


class FootprintAlgorithm(PushbroomAlgorithm):
    ID = "footprint"
    NAME = "Scene footprint"
    GROUP, GROUP_ID = "Products", "products"
    SAMPLES, OUTPUT = "SAMPLES", "OUTPUT"
    CORE_PARAMETERS = SCENE_PARAMETERS
    SCENE_OR_SCENES = ("outline each camera of one scene", "outline every product of a block or region")

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API name)
        add_scene_parameters(self, with_camera=False, or_scenes=True)
        add_dem_parameters(self)
        self.addParameter(QgsProcessingParameterNumber(self.SAMPLES, tr("Points per image edge"),
                                                       QgsProcessingParameterNumber.Integer, 256, minValue=4,
                                                       maxValue=100000))
        self.addParameter(QgsProcessingParameterFeatureSink(self.OUTPUT, tr("Footprints"),
                                                            QgsProcessing.TypeVectorPolygon))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        scene, scenes = scene_or_block(self, parameters, context, feedback)
        result = self.run_core(use_case.run, use_case.FootprintRequest(
            scene, self.terrain(parameters, context), self.parameterAsInt(parameters, self.SAMPLES, context),
            files_in_use(self, parameters, context), scenes), feedback)
        if scenes:
            fields = {"scene": QVariant.String, "file": QVariant.String, "cameras": QVariant.String,
                      "area_km2": QVariant.Double, "overlaps": QVariant.Int, "overlapping": QVariant.String}
            rows = [(p, [p.name, p.file, ",".join(p.cameras), float(p.area_km2), len(p.overlaps), ",".join(p.overlaps)])
                    for p in result.figures["products"]]
            return self._write(parameters, context, fields, rows, "product_footprint.qml")
        fields = {"camera": QVariant.String, "cols": QVariant.Int, "rows": QVariant.Int, "area_km2": QVariant.Double}
        rows = [(fp, [fp.camera, fp.cols, fp.rows, float(fp.area_km2)]) for fp in result.figures["footprints"]]
        return self._write(parameters, context, fields, rows, "footprint.qml")

    def _write(self, parameters, context, types: dict, rows: list, style: str) -> dict:
        """One polygon per (outline with .lon/.lat, attributes) of ``rows``, styled with ``style``."""
        fields = output_fields(types)
        with output_sink(self, parameters, context, self.OUTPUT, fields, QgsWkbTypes.Polygon,
                         QgsCoordinateReferenceSystem("EPSG:4326")) as (sink, dest):
            for outline, attributes in rows:
                out = QgsFeature(fields)
                out.setGeometry(QgsGeometry(QgsPolygon(QgsLineString(outline.lon.tolist(), outline.lat.tolist()))))
                out.setAttributes(attributes)
                sink.add(out)
        style_output_on_load(context, dest, STYLES / style)
        return {self.OUTPUT: dest}
