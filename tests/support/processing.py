"""For running the plugin's algorithms through processing.run: a feedback that keeps what they
push, the memory layers they take as input and the values of the layers they write."""
import numpy as np
from qgis.core import (QgsCoordinateReferenceSystem, QgsFeature, QgsGeometry, QgsPoint, QgsProcessingFeedback,
                       QgsVectorLayer)


class RecordingFeedback(QgsProcessingFeedback):
    """Keeps what an algorithm pushes: ``lines`` (information and warnings, in order), ``infos``,
    ``warnings`` and ``errors`` (reportError)."""

    def __init__(self):
        super().__init__()
        self.lines, self.infos, self.warnings, self.errors = [], [], [], []

    def pushInfo(self, info):  # noqa: N802 (QGIS API name)
        self.lines.append(info)
        self.infos.append(info)
        super().pushInfo(info)

    def pushWarning(self, warning):  # noqa: N802 (QGIS API name)
        self.lines.append(warning)
        self.warnings.append(warning)
        super().pushWarning(warning)

    def reportError(self, error, fatalError=False):  # noqa: N802 (QGIS API names)
        self.errors.append(error)
        super().reportError(error, fatalError)


def image_table(col, row, extra_null=False) -> QgsVectorLayer:
    """A geometry-less memory table with fields id, col, row (the second row's row NULL with
    ``extra_null``)."""
    layer = QgsVectorLayer("None?field=id:integer&field=col:double&field=row:double", "image points", "memory")
    feats = []
    for i, (c, r) in enumerate(zip(col, row)):
        f = QgsFeature(layer.fields())
        f.setAttributes([i, float(c), None if extra_null and i == 1 else float(r)])
        feats.append(f)
    layer.dataProvider().addFeatures(feats)
    return layer


def point_layer(x, y, z=None, crs="EPSG:4326") -> QgsVectorLayer:
    """A memory point layer (with Z when z is given) with a 'name' field (p0, p1, ...); no CRS
    when ``crs`` is None."""
    kind = "Point" if z is None else "PointZ"
    layer = QgsVectorLayer(f"{kind}?field=name:string", "ground points", "memory")
    layer.setCrs(QgsCoordinateReferenceSystem(crs) if crs else QgsCoordinateReferenceSystem())
    feats = []
    for i in range(len(x)):
        f = QgsFeature(layer.fields())
        p = QgsPoint(float(x[i]), float(y[i])) if z is None else QgsPoint(float(x[i]), float(y[i]), float(z[i]))
        f.setGeometry(QgsGeometry(p))
        f.setAttributes([f"p{i}"])
        feats.append(f)
    layer.dataProvider().addFeatures(feats)
    return layer


def field_values(layer, *names) -> np.ndarray:
    """(features, len(names)) float array of the fields ``names`` of every feature of ``layer``."""
    return np.array([[f[n] for n in names] for f in layer.getFeatures()], dtype=float)
