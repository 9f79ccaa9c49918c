"""The GCP dock on QGIS's main map canvas: the points with a ground marked there (the selected one
highlighted) and the reference layer's points. Ground positions are WGS84 lon, lat (deg); the canvas
may be in any CRS."""
from __future__ import annotations

import numpy as np
from qgis.core import (QgsCoordinateReferenceSystem, QgsCoordinateTransform, QgsGeometry, QgsPointXY, QgsProject,
                       QgsWkbTypes)

from .markers import CanvasDrawing


def wgs84() -> QgsCoordinateReferenceSystem:
    """EPSG:4326, made when needed (not at import, before QGIS has its CRS database)."""
    return QgsCoordinateReferenceSystem("EPSG:4326")


def canvas_to_wgs84(canvas, point: QgsPointXY) -> QgsPointXY:
    """A point of ``canvas`` (its CRS) as lon, lat (deg)."""
    crs = canvas.mapSettings().destinationCrs()
    return QgsCoordinateTransform(crs, wgs84(), QgsProject.instance()).transform(point)


class MainMapMarkers:
    """The points' markers on the main map canvas, redrawn when its CRS changes."""

    def __init__(self, canvas):
        self.canvas = canvas
        self.drawing = CanvasDrawing(canvas)
        self.shown: list = []
        self.selected = None  # the selected point's marker
        canvas.destinationCrsChanged.connect(self._crs_changed)

    def show(self, points, selected: int | None) -> None:
        """Mark ``points`` (those with a ground), point ``selected`` (an index) highlighted."""
        self.shown = [(p.id, p.ground.lon, p.ground.lat, i == selected) for i, p in enumerate(points)
                      if p.ground is not None]
        self._draw()

    def _draw(self) -> None:
        self.drawing.clear()
        self.selected = None
        to_canvas = QgsCoordinateTransform(wgs84(), self.canvas.mapSettings().destinationCrs(), QgsProject.instance())
        for point_id, lon, lat, selected in sorted(self.shown, key=lambda s: s[3]):  # the selected one on top
            at = to_canvas.transform(QgsPointXY(lon, lat))
            item = self.drawing.marker(at, "selected" if selected else "measured", point_id)
            self.selected = item if selected else self.selected

    def _crs_changed(self) -> None:
        if self.shown:
            self._draw()

    def hide(self) -> None:
        """Take the markers off the map until the next :meth:`show` (the dock closed)."""
        self.drawing.clear()
        self.selected = None

    def dispose(self) -> None:
        self.shown, self.selected = [], None
        self.drawing.clear()
        try:
            self.canvas.destinationCrsChanged.disconnect(self._crs_changed)
        except TypeError:  # disconnected already
            pass


def reference_points(layer, crs: QgsCoordinateReferenceSystem) -> tuple[np.ndarray, np.ndarray]:
    """((n, 2) x, y in ``crs``, the main canvas's; (n, 3) lon, lat deg, Z or NaN) of ``layer``'s points."""
    to_canvas = QgsCoordinateTransform(layer.crs(), crs, QgsProject.instance())
    to_wgs84 = QgsCoordinateTransform(layer.crs(), wgs84(), QgsProject.instance())
    has_z = QgsWkbTypes.hasZ(layer.wkbType())
    xy, lonlatz = [], []
    for feature in layer.getFeatures():
        geometry = QgsGeometry(feature.geometry())
        if not geometry.isEmpty():
            vertex = geometry.vertexAt(0)
            there, lonlat = (t.transform(QgsPointXY(vertex.x(), vertex.y())) for t in (to_canvas, to_wgs84))
            xy.append((there.x(), there.y()))
            lonlatz.append((lonlat.x(), lonlat.y(), vertex.z() if has_z else np.nan))
    return np.reshape(xy, (-1, 2)), np.reshape(lonlatz, (-1, 3))
