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


def layer_parts(layer, crs: QgsCoordinateReferenceSystem, field: str = "") -> tuple[list[str], list[np.ndarray]]:
    """(the value of ``field`` ('' for none) of each part's feature, parts [(n, 3)]: x, y in ``crs``, z
    (NaN without Z)) of ``layer``'s features."""
    transform = QgsCoordinateTransform(layer.crs(), crs, QgsProject.instance())
    has_z = QgsWkbTypes.hasZ(layer.wkbType())
    ids, parts = [], []
    for feature in layer.getFeatures():
        geometry = QgsGeometry(feature.geometry())
        if geometry.isEmpty():
            continue
        geometry.transform(transform)
        for part in geometry.constParts():
            parts.append(np.array([(p.x(), p.y(), p.z() if has_z else np.nan) for p in part.vertices()], dtype=float))
            ids.append(str(feature[field]) if field else "")
    return ids, parts
