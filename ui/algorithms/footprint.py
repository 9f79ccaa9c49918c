"""pushbroom:footprint — ground outline of each camera's image, as polygons."""
from qgis.core import (QgsCoordinateReferenceSystem, QgsFeature, QgsGeometry, QgsLineString, QgsPolygon,
                       QgsProcessing, QgsProcessingParameterFeatureSink, QgsProcessingParameterNumber, QgsWkbTypes)
from qgis.PyQt.QtCore import QVariant

from ...core.runs import footprint as use_case
from ..inputs import add_dem_parameters, add_scene_parameters
from ..outputs import STYLES, files_in_use, output_fields, output_sink, style_output_on_load
from ..parameters import DEM, SCENE, tr
from .base import PushbroomAlgorithm


class FootprintAlgorithm(PushbroomAlgorithm):
    ID = "footprint"
    NAME = "Scene footprint"
    GROUP, GROUP_ID = "Products", "products"
    SAMPLES, OUTPUT = "SAMPLES", "OUTPUT"
    CORE_PARAMETERS = {"scene": SCENE, "dem": DEM}

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API name)
        add_scene_parameters(self, with_camera=False)
        add_dem_parameters(self)
        self.addParameter(QgsProcessingParameterNumber(self.SAMPLES, tr("Points per image edge"),
                                                       QgsProcessingParameterNumber.Integer, 256, minValue=4,
                                                       maxValue=100000))
        self.addParameter(QgsProcessingParameterFeatureSink(self.OUTPUT, tr("Footprints"),
                                                            QgsProcessing.TypeVectorPolygon))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        result = self.run_core(use_case.run, use_case.FootprintRequest(
            self.parameterAsFile(parameters, SCENE, context), self.terrain(parameters, context),
            self.parameterAsInt(parameters, self.SAMPLES, context), files_in_use(self, parameters, context)), feedback)
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
