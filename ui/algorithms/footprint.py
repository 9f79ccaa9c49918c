"""pushbroom:footprint — ground outline of each camera's image, as polygons."""
from qgis.core import (QgsCoordinateReferenceSystem, QgsFeature, QgsField, QgsFields, QgsGeometry, QgsLineString,
                       QgsPolygon, QgsProcessing, QgsProcessingParameterFeatureSink, QgsProcessingParameterNumber,
                       QgsWkbTypes)
from qgis.PyQt.QtCore import QVariant

from ...core.products.footprint import footprints
from ..feedback import check_cancelled, core_call
from ..inputs import add_dem_parameters, add_scene_parameters, dem_from_parameters, load_scene_for
from ..outputs import STYLES, check_outputs, output_sink, style_output_on_load
from ..parameters import DEM, SCENE, tr
from .base import PushbroomAlgorithm


class FootprintAlgorithm(PushbroomAlgorithm):
    ID = "footprint"
    NAME = "Scene footprint"
    GROUP, GROUP_ID = "Products", "products"
    HELP = ("Traces the border of each camera's image on the terrain (a DEM, or a constant height) with the "
            "scene's rigorous sensor model: one polygon per camera in WGS84 (EPSG:4326), densely sampled "
            "along every edge and on both sides of each CCD boundary, so that the outline stays correct "
            "for long strips, curved edges and staggered CCDs.")
    SAMPLES, OUTPUT = "SAMPLES", "OUTPUT"

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API name)
        add_scene_parameters(self, with_camera=False)
        add_dem_parameters(self)
        samples = QgsProcessingParameterNumber(self.SAMPLES, tr("Points per image edge"),
                                               QgsProcessingParameterNumber.Integer, 256, minValue=4,
                                               maxValue=100000)
        samples.setHelp(tr("How many intervals each edge of the image is divided into; 256 keeps the outline "
                           "within centimetres of the true border for usual scenes."))
        self.addParameter(samples)
        out = QgsProcessingParameterFeatureSink(self.OUTPUT, tr("Footprints"), QgsProcessing.TypeVectorPolygon)
        out.setHelp(tr("Polygons (EPSG:4326), one per camera, with fields camera, cols, rows and area_km2 "
                       "(geodesic area on the WGS84 ellipsoid)."))
        self.addParameter(out)

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        check_outputs(self, parameters, context)
        scene = load_scene_for(SCENE, self.parameterAsFile(parameters, SCENE, context), feedback)
        surface = dem_from_parameters(self, parameters, context, scene, feedback)
        samples = self.parameterAsInt(parameters, self.SAMPLES, context)
        fields = QgsFields()
        fields.append(QgsField("camera", QVariant.String))
        fields.append(QgsField("cols", QVariant.Int))
        fields.append(QgsField("rows", QVariant.Int))
        fields.append(QgsField("area_km2", QVariant.Double))
        with output_sink(self, parameters, context, self.OUTPUT, fields, QgsWkbTypes.Polygon,
                         QgsCoordinateReferenceSystem("EPSG:4326")) as (sink, dest):
            n = len(scene.cameras)
            for k in range(n):
                check_cancelled(feedback)
                feedback.setProgressText(f"camera {scene.cameras[k].name}")
                (fp,) = core_call(footprints, scene, surface, cameras=[k], samples_per_edge=samples)
                if fp.note:
                    feedback.pushWarning(f"{DEM}: {fp.note}")
                out = QgsFeature(fields)
                ring = QgsLineString(fp.lon.tolist(), fp.lat.tolist())
                out.setGeometry(QgsGeometry(QgsPolygon(ring)))
                out.setAttributes([fp.camera, fp.cols, fp.rows, float(fp.area_km2)])
                sink.add(out)
                feedback.setProgress(100.0 * (k + 1) / n)
        style_output_on_load(context, dest, STYLES / "footprint.qml")
        return {self.OUTPUT: dest}
