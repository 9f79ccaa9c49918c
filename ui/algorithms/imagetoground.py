"""pushbroom:imagetoground — ground points (lon, lat, ellipsoidal h) seen at image coordinates
(:mod:`core.runs.imagetoground`)."""
import numpy as np
from qgis.core import (QgsCoordinateReferenceSystem, QgsFeature, QgsGeometry, QgsPoint, QgsProcessing,
                       QgsProcessingException, QgsProcessingParameterFeatureSink, QgsProcessingParameterFeatureSource,
                       QgsWkbTypes)
from qgis.PyQt.QtCore import QVariant

from ...core.runs import imagetoground as use_case
from ..inputs import add_dem_parameters, add_scene_parameters, attribute_floats, source_and_features
from ..outputs import STYLES, files_in_use, output_fields, output_sink, style_output_on_load
from ..parameters import CAMERA, COL_FIELD, DEM, ROW_FIELD, SCENE, image_field, tr
from .base import PushbroomAlgorithm


OUTPUT_CRS = "EPSG:4979"  # WGS84 longitude, latitude (deg) and ellipsoidal height (m)


class ImageToGroundAlgorithm(PushbroomAlgorithm):
    ID = "imagetoground"
    NAME = "Image to ground"
    INPUT, COL_FIELD, ROW_FIELD, OUTPUT = "INPUT", COL_FIELD, ROW_FIELD, "OUTPUT"
    CORE_PARAMETERS = {"scene": SCENE, "camera": CAMERA, "dem": DEM, use_case.POINTS: INPUT}

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API name)
        add_scene_parameters(self)
        self.addParameter(QgsProcessingParameterFeatureSource(self.INPUT, tr("Image points (table or layer)"),
                                                              [QgsProcessing.TypeVector]))
        for name in (self.COL_FIELD, self.ROW_FIELD):
            self.addParameter(image_field(name))
        add_dem_parameters(self)
        self.addParameter(QgsProcessingParameterFeatureSink(self.OUTPUT, tr("Ground points"),
                                                            QgsProcessing.TypeVectorPoint))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        source, features = source_and_features(self, parameters, context, self.INPUT)
        names, col, row = self._image_points(parameters, context, source, features)
        result = self.run_core(use_case.run, use_case.ImageToGroundRequest(
            self.parameterAsFile(parameters, SCENE, context), col, row, np.array([f.id() for f in features]), names,
            self.terrain(parameters, context), self.parameterAsString(parameters, CAMERA, context),
            files_in_use(self, parameters, context)), feedback)
        kept = [f for f, k in zip(features, result.figures["kept"]) if k]
        f = result.figures
        return {self.OUTPUT: self._write(parameters, context, source, kept, f["lon"], f["lat"], f["h"])}

    def _image_points(self, parameters, context, source, features) -> tuple:
        """(names of the col and row fields, col, row (n,) of the features: NaN for NULL or non-numeric)."""
        names = [self.parameterAsString(parameters, p, context) or default
                 for p, default in ((self.COL_FIELD, "col"), (self.ROW_FIELD, "row"))]
        idx = []
        for param, name in zip((self.COL_FIELD, self.ROW_FIELD), names):
            i = source.fields().lookupField(name)
            if i < 0:
                raise QgsProcessingException(f"{param}: the input has no field {name!r} "
                                             f"(fields: {', '.join(source.fields().names())})")
            idx.append(i)
        col, row = (attribute_floats([f.attribute(i) for f in features]) for i in idx)
        return tuple(names), col, row

    def _write(self, parameters, context, source, features, lon, lat, h):
        fields = output_fields(dict.fromkeys(("lon", "lat", "h_ellipsoid"), QVariant.Double), source.fields())
        with output_sink(self, parameters, context, self.OUTPUT, fields, QgsWkbTypes.PointZ,
                         QgsCoordinateReferenceSystem(OUTPUT_CRS)) as (sink, dest):
            for f, x, y, z in zip(features, lon, lat, h):
                out = QgsFeature(fields)
                out.setGeometry(QgsGeometry(QgsPoint(float(x), float(y), float(z))))
                out.setAttributes(f.attributes() + [float(x), float(y), float(z)])
                sink.add(out)
        style_output_on_load(context, dest, STYLES / "ground_points.qml")
        return dest
