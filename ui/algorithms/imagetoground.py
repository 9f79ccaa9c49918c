"""pushbroom:imagetoground — ground points (lon, lat, ellipsoidal h) seen at image coordinates."""
import numpy as np
from qgis.core import (QgsCoordinateReferenceSystem, QgsFeature, QgsField, QgsFields, QgsGeometry,
                       QgsPoint, QgsProcessing, QgsProcessingException, QgsProcessingParameterFeatureSink,
                       QgsProcessingParameterFeatureSource, QgsProcessingUtils,
                       QgsWkbTypes)
from qgis.PyQt.QtCore import QVariant

from ...core.dem import ConstantHeight, no_height_words, surface_name
from ...core.products.footprint import rays_without_height
from ...core.geodesy import ecef_to_geodetic
from ..feedback import check_cancelled, core_call
from ..inputs import (add_dem_parameters, add_scene_parameters, dem_from_parameters, nonfinite_message,
                      scene_camera_and_features)
from ..outputs import STYLES, check_outputs, output_sink, style_output_on_load
from ..parameters import COL_FIELD, DEM, ROW_FIELD, image_field, tr
from .base import PushbroomAlgorithm


OUTPUT_CRS = "EPSG:4979"  # WGS84 longitude, latitude (deg) and ellipsoidal height (m)


class ImageToGroundAlgorithm(PushbroomAlgorithm):
    ID = "imagetoground"
    NAME = "Image to ground"
    HELP = ("Intersects the lines of sight of image points with the terrain (a DEM, or a constant height) "
            "using the scene's rigorous sensor model. Image coordinates follow GDAL: (0, 0) is the upper-left "
            "corner of the upper-left pixel, pixel centres at half-integers. The output points are in "
            "EPSG:4979 (WGS84 longitude/latitude with ellipsoidal Z) and carry the input attributes plus "
            "lon, lat, h_ellipsoid.")
    INPUT, COL_FIELD, ROW_FIELD, OUTPUT = "INPUT", COL_FIELD, ROW_FIELD, "OUTPUT"

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API name)
        add_scene_parameters(self)
        source = QgsProcessingParameterFeatureSource(self.INPUT, tr("Image points (table or layer)"),
                                                     [QgsProcessing.TypeVector])
        source.setHelp(tr("Any table or layer (CSV, GeoPackage, ...) with numeric column and row fields; its "
                          "geometry, if any, is ignored."))
        self.addParameter(source)
        for name in (self.COL_FIELD, self.ROW_FIELD):
            self.addParameter(image_field(name))
        add_dem_parameters(self)
        out = QgsProcessingParameterFeatureSink(self.OUTPUT, tr("Ground points"), QgsProcessing.TypeVectorPoint)
        out.setHelp(tr("Points in EPSG:4979 with the input attributes plus lon, lat (degrees) and h_ellipsoid "
                       "(m)."))
        self.addParameter(out)

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        check_outputs(self, parameters, context)
        scene, camera, source, features = scene_camera_and_features(self, parameters, context, self.INPUT, feedback)
        col, row = self._image_points(parameters, context, source, features)
        surface = dem_from_parameters(self, parameters, context, scene, feedback)
        check_cancelled(feedback)
        cam = scene.cameras[camera]
        outside = ~cam.in_image(col, row)
        if outside.any():
            feedback.pushWarning(f"{int(outside.sum())} points lie outside the image of camera {cam.name} "
                                 f"({cam.cols} x {cam.rows} px); their lines of sight are extrapolated")
        feedback.setProgressText(f"intersecting {len(features)} lines of sight with the terrain")
        if isinstance(surface, ConstantHeight):
            xyz = core_call(scene.image_to_ground, col, row, surface.value, camera)
        else:
            xyz = core_call(scene.image_to_ground_dem, col, row, surface, camera)
        missed = ~np.all(np.isfinite(xyz), axis=1)
        if missed.any():
            self._missed(scene, camera, col, row, surface, features, missed, feedback)
            features = [f for f, m in zip(features, missed) if not m]
        lon, lat, h = ecef_to_geodetic(xyz[~missed])
        dest = self._write(parameters, context, source, features, lon, lat, h)
        feedback.setProgress(100)
        return {self.OUTPUT: dest}

    @staticmethod
    def _missed(scene, camera: int, col, row, surface, features, missed, feedback) -> None:
        """Points whose lines of sight met no height: left out with a warning that counts them when
        they meet the DEM only on its nodata holes; else refused, naming the DEM and why."""
        lost = [str(f.id()) for f, m in zip(features, missed) if m]
        ids = ", ".join(lost[:5]) + (", ..." if len(lost) > 5 else "")
        if isinstance(surface, ConstantHeight):
            raise QgsProcessingException(f"{DEM}: the lines of sight of {int(missed.sum())} points miss the Earth; "
                                         f"feature ids {ids}")
        off, hole = core_call(rays_without_height, scene, camera, col[missed], row[missed], surface)
        words = no_height_words(int(missed.sum() - hole.sum()), int(hole.sum()), missed.size, "points")
        if not hole.all() or missed.all():
            raise QgsProcessingException(f"{DEM}: {surface_name(surface)} {words}: their lines of sight leave it (it "
                                         f"does not cover them); feature ids {ids}")
        feedback.pushWarning(f"{DEM}: {surface_name(surface)} {words}: their lines of sight meet it only there; "
                             f"those points are left out (feature ids {ids})")

    def _image_points(self, parameters, context, source, features):
        names = [self.parameterAsString(parameters, p, context) or default
                 for p, default in ((self.COL_FIELD, "col"), (self.ROW_FIELD, "row"))]
        idx = []
        for param, name in zip((self.COL_FIELD, self.ROW_FIELD), names):
            i = source.fields().lookupField(name)
            if i < 0:
                raise QgsProcessingException(f"{param}: the input has no field {name!r} "
                                             f"(fields: {', '.join(source.fields().names())})")
            idx.append(i)
        values = np.array([[_float(f.attribute(i)) for i in idx] for f in features])
        bad = ~np.all(np.isfinite(values), axis=1)
        if bad.any():
            ids = np.array([f.id() for f in features])
            raise QgsProcessingException(nonfinite_message(self.INPUT, f"{names[0]}/{names[1]} values", ids, bad))
        return values[:, 0], values[:, 1]

    def _write(self, parameters, context, source, features, lon, lat, h):
        new = QgsFields()
        for name in ("lon", "lat", "h_ellipsoid"):
            new.append(QgsField(name, QVariant.Double))
        fields = QgsProcessingUtils.combineFields(source.fields(), new)
        with output_sink(self, parameters, context, self.OUTPUT, fields, QgsWkbTypes.PointZ,
                         QgsCoordinateReferenceSystem(OUTPUT_CRS)) as (sink, dest):
            for f, x, y, z in zip(features, lon, lat, h):
                out = QgsFeature(fields)
                out.setGeometry(QgsGeometry(QgsPoint(float(x), float(y), float(z))))
                out.setAttributes(f.attributes() + [float(x), float(y), float(z)])
                sink.add(out)
        style_output_on_load(context, dest, STYLES / "ground_points.qml")
        return dest


def _float(value) -> float:
    """A numeric attribute as float; NaN for NULL or non-numeric values."""
    try:
        return float(value)
    except (TypeError, ValueError):
        return float("nan")
