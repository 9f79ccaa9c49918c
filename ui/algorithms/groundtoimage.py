"""pushbroom:groundtoimage — image coordinates (col, row) of ground points in a scene
(:mod:`core.runs.groundtoimage`)."""
import numpy as np
from qgis.core import (QgsFeature, QgsProcessing, QgsProcessingException, QgsProcessingParameterBoolean,
                       QgsProcessingParameterFeatureSink, QgsProcessingParameterFeatureSource)
from qgis.PyQt.QtCore import QVariant

from ...core.runs import groundtoimage as use_case
from ..inputs import (add_dem_parameters, add_scene_parameters, layer_crs, point_xyz, require_points,
                      source_and_features)
from ..outputs import STYLES, files_in_use, output_fields, output_sink, style_output_on_load
from ..parameters import CAMERA, DEM, SCENE, Z_DATUM, enum_value, tr, z_datum
from .base import PushbroomAlgorithm


class GroundToImageAlgorithm(PushbroomAlgorithm):
    ID = "groundtoimage"
    NAME = "Ground to image"
    INPUT, USE_Z, Z_DATUM, OUTPUT = "INPUT", "USE_Z", Z_DATUM, "OUTPUT"
    CORE_PARAMETERS = {"scene": SCENE, "camera": CAMERA, "dem": DEM, use_case.POINTS: INPUT, use_case.Z_DATUM: Z_DATUM}

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API name)
        add_scene_parameters(self)
        self.addParameter(QgsProcessingParameterFeatureSource(self.INPUT, tr("Ground points"),
                                                              [QgsProcessing.TypeVectorPoint]))
        self.addParameter(QgsProcessingParameterBoolean(self.USE_Z, tr("Use the points' Z values as heights"),
                                                        defaultValue=True))
        self.addParameter(z_datum())
        add_dem_parameters(self)
        self.addParameter(QgsProcessingParameterFeatureSink(self.OUTPUT, tr("Image points"),
                                                            QgsProcessing.TypeVectorPoint))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        source, features = source_and_features(self, parameters, context, self.INPUT)
        require_points(self.INPUT, source)
        crs = source.sourceCrs()
        x, y, z = self._coordinates(features)
        result = self.run_core(use_case.run, use_case.GroundToImageRequest(
            self.parameterAsFile(parameters, SCENE, context), x, y, z, np.array([f.id() for f in features], np.int64),
            layer_crs(self.INPUT, crs), crs.authid(), self.parameterAsBool(parameters, self.USE_Z, context),
            enum_value(self, parameters, self.Z_DATUM, context), self.terrain(parameters, context),
            self.parameterAsString(parameters, CAMERA, context), files_in_use(self, parameters, context)), feedback)
        col, row, inside = (result.figures[k] for k in ("col", "row", "inside"))
        fields = output_fields({"col": QVariant.Double, "row": QVariant.Double, "in_image": QVariant.Int},
                               source.fields())
        with output_sink(self, parameters, context, self.OUTPUT, fields, source.wkbType(), crs) as (sink, dest):
            for i, f in enumerate(features):
                out = QgsFeature(fields)
                out.setGeometry(f.geometry())
                out.setAttributes(f.attributes() + [_number(col[i]), _number(row[i]), int(inside[i])])
                sink.add(out)
        style_output_on_load(context, dest, STYLES / "image_points.qml")
        return {self.OUTPUT: dest}

    def _coordinates(self, features) -> tuple:
        """x, y, z (n,) of the features' points (ui.inputs.point_xyz); a feature of several points is refused."""
        for f in features:
            g = f.geometry()
            if not g.isEmpty() and g.isMultipart() and g.constGet().numGeometries() != 1:
                raise QgsProcessingException(f"{self.INPUT}: feature {f.id()} holds several points; split it with "
                                             f"'Multipart to singleparts' first")
        return tuple(point_xyz(features).T)

def _number(v: float):
    """A float attribute, or NULL for NaN."""
    return float(v) if np.isfinite(v) else None
