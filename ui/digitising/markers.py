"""What the docks draw: labelled point markers, line bands, their legend, the GCPs on the main map. Markers
keep their screen size and are hollow: at whole-image zoom a prediction does not hide the measurement."""
from __future__ import annotations

from contextlib import suppress
from dataclasses import dataclass, replace

from qgis.core import QgsCoordinateTransform, QgsGeometry, QgsPointXY, QgsProject, QgsWkbTypes
from qgis.gui import QgsMapCanvas, QgsMapCanvasItem, QgsRubberBand
from qgis.PyQt import sip
from qgis.PyQt.QtCore import QPointF, QRectF, Qt
from qgis.PyQt.QtGui import QColor, QFont, QFontMetricsF, QPainter, QPainterPath, QPen, QPixmap, QPolygonF
from qgis.PyQt.QtWidgets import QHBoxLayout, QLabel, QWidget

from ..parameters import tr
from .form import wgs84


@dataclass(frozen=True)
class MarkerStyle:
    """Colour (r, g, b), shape (circle, square, diamond), size and pen width (screen px), a dot at the spot?"""
    colour: tuple[int, int, int]
    shape: str
    size: float
    width: float
    dot: bool
    legend: str


STYLES = {
    "selected": MarkerStyle((230, 20, 20), "circle", 16, 2.0, True, "selected point"),
    "measured": MarkerStyle((0, 150, 255), "circle", 12, 1.5, True, "measured"),
    "ground": MarkerStyle((255, 140, 0), "square", 14, 1.5, False, "predicted from its ground"),
    "scene": MarkerStyle((200, 0, 200), "diamond", 18, 1.5, False, "predicted from another scene"),
}
LINE_STYLES = {  # (colour, alpha, width px, dashed): thin and half transparent, the road stays visible under them
    "line": ((0, 170, 255), 170, 1, False),
    "selected": ((255, 40, 40), 150, 1, False),
    "drawing": ((255, 200, 0), 220, 1, False),
    "predicted": ((200, 0, 200), 170, 1, True),
}


def paint_marker(painter: QPainter, style: MarkerStyle, label: str = "", font: QFont | None = None) -> None:
    """Draw a marker of ``style`` at the painter's origin, ``label`` beside it (white halo)."""
    painter.setRenderHint(QPainter.Antialiasing)
    r, colour, outline = style.size / 2, QColor(*style.colour), QPainterPath()
    if style.shape == "square":
        outline.addRect(QRectF(-r * 0.8, -r * 0.8, 1.6 * r, 1.6 * r))
    elif style.shape == "diamond":
        outline.addPolygon(QPolygonF([QPointF(0, -r), QPointF(r, 0), QPointF(0, r), QPointF(-r, 0), QPointF(0, -r)]))
    else:
        outline.addEllipse(QPointF(0, 0), r, r)
    painter.setBrush(Qt.NoBrush)
    for pen in (QPen(QColor(255, 255, 255, 160), style.width + 2), QPen(colour, style.width)):
        painter.setPen(pen)
        painter.drawPath(outline)
    if style.dot:
        painter.setBrush(colour)
        painter.drawEllipse(QPointF(0, 0), 1.2, 1.2)
    if label:
        text = QPainterPath()
        text.addText(QPointF(style.size / 2 + 2, -style.size / 2), font, label)
        for pen, brush in ((QPen(QColor(255, 255, 255, 220), 3), Qt.NoBrush), (Qt.NoPen, colour)):
            painter.setPen(pen)
            painter.setBrush(brush)
            painter.drawPath(text)


class PointMarker(QgsMapCanvasItem):
    """A marker of ``style`` at ``point`` (map coordinates of ``canvas``), labelled ``label``."""

    def __init__(self, canvas: QgsMapCanvas, point: QgsPointXY, style: MarkerStyle, label: str = ""):
        super().__init__(canvas)
        self.point, self.style, self.label, self.font = point, style, label, QFont()
        self.font.setPointSizeF(8.5)
        self.font.setBold(True)
        width = QFontMetricsF(self.font).horizontalAdvance(label) if label else 0.0
        r = style.size / 2 + style.width + 2
        self.bounds = QRectF(-r, -r - 14, 2 * r + width + 6, 2 * r + 16)
        self.setZValue(20 if style.dot else 10)  # measurements above predictions
        self.updatePosition()

    def paint(self, painter, option=None, widget=None):
        paint_marker(painter, self.style, self.label, self.font)

    def boundingRect(self):  # noqa: N802 (Qt API name)
        return self.bounds

    def updatePosition(self):  # noqa: N802 (QGIS API name)
        self.setPos(self.toCanvasCoordinates(self.point))


class CanvasDrawing:
    """The markers and bands a dock keeps on one canvas, replaced together."""

    def __init__(self, canvas: QgsMapCanvas):
        self.canvas, self.items = canvas, []

    def clear(self) -> None:
        """Take every item off the scene that holds it and delete it (unless gone with its canvas)."""
        for item in (i for i in self.items if not sip.isdeleted(i)):
            if item.scene() is not None:
                item.scene().removeItem(item)
            sip.delete(item)
        self.items = []

    def marker(self, point: QgsPointXY, kind: str, label: str = "") -> PointMarker:
        """A marker of STYLES[kind] at ``point`` (map coordinates)."""
        item = PointMarker(self.canvas, point, STYLES[kind], label)
        self.items.append(item)
        return item

    def polyline(self, points: list[QgsPointXY], kind: str) -> None:
        """A band through ``points`` (map coordinates) in LINE_STYLES[kind]."""
        colour, alpha, width, dashed = LINE_STYLES[kind]
        band = QgsRubberBand(self.canvas, QgsWkbTypes.LineGeometry)
        band.setColor(QColor(*colour, alpha))
        band.setWidth(width)
        if dashed:
            band.setLineStyle(Qt.DashLine)
        band.setToGeometry(QgsGeometry.fromPolylineXY(points), None)
        self.items.append(band)


def legend(kinds, lines: tuple[str, ...] = ()) -> QWidget:
    """A row of swatches and texts: of STYLES' ``kinds``, of LINE_STYLES' (kind, text) ``lines``."""
    widget = QWidget()
    row = QHBoxLayout(widget)
    row.setContentsMargins(2, 0, 2, 0)
    for kind, text in [(k, "") for k in kinds] + list(lines):
        pixmap = QPixmap(22, 22)
        pixmap.fill(Qt.transparent)
        painter = QPainter(pixmap)
        if text:
            colour, _, _, dashed = LINE_STYLES[kind]
            painter.setPen(QPen(QColor(*colour), 2, Qt.DashLine if dashed else Qt.SolidLine))
            painter.drawLine(2, 16, 20, 6)
        else:
            painter.translate(11, 11)
            paint_marker(painter, replace(STYLES[kind], size=min(STYLES[kind].size, 16)))
            text = tr(STYLES[kind].legend)
        painter.end()
        swatch = QWidget()
        pair = QHBoxLayout(swatch)
        pair.setContentsMargins(0, 0, 6, 0)
        pair.setSpacing(2)
        pair.addWidget(QLabel(pixmap=pixmap))
        pair.addWidget(QLabel(text))
        row.addWidget(swatch)
    row.addStretch(1)
    return widget


class MainMapMarkers:
    """The GCPs' markers on the main map, redrawn when its CRS changes; ``selected``: the selected one's."""

    def __init__(self, canvas):
        self.canvas, self.drawing, self.shown, self.selected = canvas, CanvasDrawing(canvas), [], None
        canvas.destinationCrsChanged.connect(self.show)

    def show(self, marks: list[tuple[str, float, float, bool]] | None = None) -> None:
        """Mark (id, lon, lat deg, selected) ``marks`` (GcpSession.ground_marks; None: the last ones)."""
        self.shown = self.shown if marks is None else marks
        self.hide()
        to_canvas = QgsCoordinateTransform(wgs84(), self.canvas.mapSettings().destinationCrs(), QgsProject.instance())
        for point_id, lon, lat, selected in self.shown:
            item = self.drawing.marker(to_canvas.transform(QgsPointXY(lon, lat)), "selected" if selected else
                                       "measured", point_id)
            self.selected = item if selected else self.selected

    def hide(self) -> None:
        """Take the markers off the map until the next :meth:`show` (the dock closed)."""
        self.drawing.clear()
        self.selected = None

    def dispose(self) -> None:
        self.shown = []
        self.hide()
        with suppress(TypeError):  # disconnected already
            self.canvas.destinationCrsChanged.disconnect(self.show)
