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
            return self._write_products(parameters, context, result.figures["products"])
        fields = output_fields({"camera": QVariant.String, "cols": QVariant.Int, "rows": QVariant.Int,
                                "area_km2": QVariant.Double})
        with output_sink(self, parameters, context, self.OUTPUT, fields, QgsWkbTypes.Polygon,
                         QgsCoordinateReferenceSystem("EPSG:4326")) as (sink, dest):
            for fp in result.figures["footprints"]:
                out = QgsFeature(fields)
                out.setGeometry(QgsGeometry(QgsPolygon(QgsLineString(fp.lon.tolist(), fp.lat.tolist()))))
                out.setAttributes([fp.camera, fp.cols, fp.rows, float(fp.area_km2)])
                sink.add(out)
        style_output_on_load(context, dest, STYLES / "footprint.qml")
        return {self.OUTPUT: dest}

    def _write_products(self, parameters, context, products) -> dict:
        """One polygon per product of a block: its name, file, cameras, area and the products it overlaps."""
        fields = output_fields({"scene": QVariant.String, "file": QVariant.String, "cameras": QVariant.String,
                                "area_km2": QVariant.Double, "overlaps": QVariant.Int,
                                "overlapping": QVariant.String})
        with output_sink(self, parameters, context, self.OUTPUT, fields, QgsWkbTypes.Polygon,
                         QgsCoordinateReferenceSystem("EPSG:4326")) as (sink, dest):
            for p in products:
                out = QgsFeature(fields)
                out.setGeometry(QgsGeometry(QgsPolygon(QgsLineString(p.lon.tolist(), p.lat.tolist()))))
                out.setAttributes([p.name, p.file, ",".join(p.cameras), float(p.area_km2), len(p.overlaps),
                                   ",".join(p.overlaps)])
                sink.add(out)
        style_output_on_load(context, dest, STYLES / "product_footprint.qml")
        return {self.OUTPUT: dest}
