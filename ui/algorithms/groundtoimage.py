"""pushbroom:groundtoimage — image coordinates (col, row) of ground points in a scene."""
import numpy as np
from qgis.core import (QgsFeature, QgsField, QgsFields, QgsProcessing, QgsProcessingException,
                       QgsProcessingParameterBoolean, QgsProcessingParameterFeatureSink,
                       QgsProcessingParameterFeatureSource, QgsProcessingUtils)
from qgis.PyQt.QtCore import QVariant

from ...core.geodesy import geodetic_to_ecef
from ...core.observations.tables import point_heights
from ..feedback import check_cancelled, core_call
from ..inputs import (add_dem_parameters, add_scene_parameters, dem_from_parameters, lonlat_of, nonfinite_message,
                      require_points, scene_camera_and_features, z_datum_of_crs)
from ..outputs import STYLES, check_outputs, output_sink, style_output_on_load
from ..parameters import Z_DATUM, enum_value, tr, z_datum
from .base import PushbroomAlgorithm


class GroundToImageAlgorithm(PushbroomAlgorithm):
    ID = "groundtoimage"
    NAME = "Ground to image"
    HELP = ("Projects ground points into a scene with its rigorous sensor model and adds their image "
            "coordinates: fields <b>col</b>, <b>row</b> (GDAL convention: (0, 0) is the upper-left corner "
            "of the upper-left pixel, pixel centres at half-integers) and <b>in_image</b> (1 when the point "
            "falls inside the image). Points outside the image are kept, flagged and counted in a warning. "
            "When the input already has fields named col/row, the new ones are named col_2/row_2.")
    INPUT, USE_Z, Z_DATUM, OUTPUT = "INPUT", "USE_Z", Z_DATUM, "OUTPUT"

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API name)
        add_scene_parameters(self)
        source = QgsProcessingParameterFeatureSource(self.INPUT, tr("Ground points"), [QgsProcessing.TypeVectorPoint])
        source.setHelp(tr("Point layer in any CRS. Heights come from the points' Z values (see USE_Z), "
                          "else from the DEM, else from the constant HEIGHT."))
        self.addParameter(source)
        use_z = QgsProcessingParameterBoolean(self.USE_Z, tr("Use the points' Z values as heights"),
                                              defaultValue=True)
        use_z.setHelp(tr("When checked, points that have a Z value use it as their height (in Z_DATUM, which must "
                         "then be given); points without Z fall back to the DEM or HEIGHT."))
        self.addParameter(use_z)
        self.addParameter(z_datum())
        add_dem_parameters(self)
        out = QgsProcessingParameterFeatureSink(self.OUTPUT, tr("Image points"), QgsProcessing.TypeVectorPoint)
        out.setHelp(tr("The input features with all their attributes plus col, row (float pixels) and in_image."))
        self.addParameter(out)

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        check_outputs(self, parameters, context)
        scene, camera, source, features = scene_camera_and_features(self, parameters, context, self.INPUT, feedback)
        require_points(self.INPUT, source)
        lon, lat, h = self._ground(parameters, context, source, features, scene, feedback)
        check_cancelled(feedback)
        feedback.setProgressText(f"projecting {len(features)} points into camera {scene.cameras[camera].name}")
        col, row = core_call(scene.ground_to_image, geodetic_to_ecef(lon, lat, h), camera)
        cam = scene.cameras[camera]
        inside = cam.in_image(col, row)

        new = QgsFields()
        for name in ("col", "row"):
            new.append(QgsField(name, QVariant.Double))
        new.append(QgsField("in_image", QVariant.Int))
        fields = QgsProcessingUtils.combineFields(source.fields(), new)
        with output_sink(self, parameters, context, self.OUTPUT, fields, source.wkbType(),
                         source.sourceCrs()) as (sink, dest):
            for i, f in enumerate(features):
                out = QgsFeature(fields)
                out.setGeometry(f.geometry())
                out.setAttributes(f.attributes() + [_number(col[i]), _number(row[i]), int(inside[i])])
                sink.add(out)
        if (~inside).any():
            feedback.pushWarning(f"{int((~inside).sum())} of {len(features)} points fall outside the image of "
                                 f"camera {cam.name} ({cam.cols} x {cam.rows} px); they are kept with in_image = 0")
        feedback.setProgress(100)
        style_output_on_load(context, dest, STYLES / "image_points.qml")
        return {self.OUTPUT: dest}

    def _ground(self, parameters, context, source, features, scene, feedback):
        """(lon, lat, ellipsoidal height) of the features' points, checked for NaN and coverage."""
        n = len(features)
        ids = np.array([f.id() for f in features], dtype=np.int64)
        xyz = np.full((n, 3), np.nan)
        for i, f in enumerate(features):
            g = f.geometry()
            if g.isNull() or g.isEmpty():
                continue
            if g.isMultipart() and g.constGet().numGeometries() != 1:
                raise QgsProcessingException(f"{self.INPUT}: feature {f.id()} holds several points; split it with "
                                             f"'Multipart to singleparts' first")
            p = g.vertexAt(0)
            xyz[i] = p.x(), p.y(), p.z()
        bad = ~np.all(np.isfinite(xyz[:, :2]), axis=1)
        if bad.any():
            raise QgsProcessingException(nonfinite_message(self.INPUT, "point coordinates", ids, bad))
        lon, lat = lonlat_of(self.INPUT, source.sourceCrs(), xyz[:, 0], xyz[:, 1])
        use_z = self.parameterAsBool(parameters, self.USE_Z, context) & np.isfinite(xyz[:, 2])
        datum = None
        if use_z.any():
            datum = enum_value(self, parameters, self.Z_DATUM, context) or z_datum_of_crs(source.sourceCrs())
            if datum is None:
                raise QgsProcessingException(f"{self.Z_DATUM}: {int(use_z.sum())} points have Z values and the "
                                             f"layer's CRS ({source.sourceCrs().authid()}) does not say what they "
                                             "are measured from: give Z_DATUM=geoid or Z_DATUM=ellipsoid (or "
                                             "USE_Z=false to take heights from the DEM or HEIGHT)")
        h = core_call(point_heights, lon, lat, np.where(use_z, xyz[:, 2], np.nan), datum,
                      lambda: dem_from_parameters(self, parameters, context, scene, feedback), ids, self.INPUT,
                      f"uncheck {self.USE_Z} to take heights from the DEM or HEIGHT")
        return lon, lat, h


def _number(v: float):
    """A float attribute, or NULL for NaN."""
    return float(v) if np.isfinite(v) else None
