"""The docks' canvas in the pixel frame x = col, y = -row, and its tools. It and its layers have no CRS:
QGIS asks for a transform from the pixel frame, which cannot exist, wherever a canvas has one (a red
bar); without one every transform is the identity."""
from __future__ import annotations

from contextlib import suppress

from qgis.core import QgsApplication, QgsCoordinateReferenceSystem, QgsPointXY, QgsProject, QgsRasterLayer, QgsRectangle
from qgis.gui import QgsMapCanvas, QgsMapTool, QgsMapToolPan, QgsMapToolZoom
from qgis.PyQt.QtCore import Qt
from qgis.PyQt.QtWidgets import QActionGroup, QLabel, QToolBar

from ..parameters import tr

ZOOM_TO_POINT_PX = 40.0  # half the width (image px) the view shows around a point zoomed to


def pixel_of(point: QgsPointXY) -> tuple[float, float]:
    """(col, row) px of a point of the pixel frame (x = col, y = -row)."""
    return point.x(), -point.y()


def point_of(col: float, row: float) -> QgsPointXY:
    """The point of the pixel frame at (col, row) px."""
    return QgsPointXY(col, -row)


def theme_icon(name: str):
    """A QGIS theme icon ('/mActionPan.svg')."""
    return QgsApplication.getThemeIcon(name)


class PixelTool(QgsMapTool):
    """The measuring tool: a release of the left or right button calls ``on_click(col, row, button)``."""

    def __init__(self, canvas: QgsMapCanvas, on_click):
        super().__init__(canvas)
        self.on_click = on_click
        self.setCursor(Qt.CrossCursor)

    def canvasReleaseEvent(self, event):  # noqa: N802
        if event.button() in (Qt.LeftButton, Qt.RightButton):
            self.on_click(*pixel_of(event.mapPoint()), event.button())


class PixelCanvas(QgsMapCanvas):
    """One raster, no CRS (a project read gives every canvas one: taken back), ``hint`` while empty."""

    def __init__(self, hint: str):
        super().__init__()
        self.setCanvasColor(Qt.white)
        self.layer: QgsRasterLayer | None = None
        self.hint = QLabel(hint, self, alignment=Qt.AlignCenter, wordWrap=True,
                           styleSheet="color: #444; font-size: 15px; background: transparent")
        QgsProject.instance().readProject.connect(self._restore)

    def show_raster(self, path: str, name: str) -> bool:
        """Show the raster at ``path`` alone, whole; False when QGIS cannot read it."""
        layer = QgsRasterLayer(path, name)
        if not layer.isValid():
            return False
        layer.setCrs(QgsCoordinateReferenceSystem())
        self.layer = layer
        self.setLayers([layer])
        self.hint.hide()
        self.zoom_to_image()
        return True

    def zoom_to_image(self) -> None:
        if self.layer is not None:
            self.setExtent(self.layer.extent())
            self.refresh()

    def zoom_to_pixel(self, col: float, row: float, half: float = ZOOM_TO_POINT_PX) -> None:
        """Centre the view on (col, row) px, ``half`` px either side (or the current scale when closer)."""
        half = min(half, max(self.extent().width(), 1.0) / 2)
        self.setExtent(QgsRectangle(col - half, -row - half, col + half, -row + half))
        self.refresh()

    def _restore(self, *args) -> None:
        self.setDestinationCrs(QgsCoordinateReferenceSystem())
        self.zoom_to_image()

    def resizeEvent(self, event):  # noqa: N802 (Qt API name)
        super().resizeEvent(event)
        self.hint.setGeometry(10, 10, max(self.width() - 20, 1), max(self.height() - 20, 1))

    def dispose(self) -> None:
        """Let go of the layer (its raster pipe must not outlive QGIS) and stop following the project."""
        self.stopRendering()
        self.setLayers([])
        self.layer = None
        self.hint.show()
        with suppress(TypeError):  # disconnected already (disposed twice)
            QgsProject.instance().readProject.disconnect(self._restore)


class CanvasTools(QToolBar):
    """The dock's ``tool`` (checked first), pan, zoom in, out (one active, as in QGIS), to all, to selected."""

    def __init__(self, canvas: PixelCanvas, tool: QgsMapTool, measure_text: str, measure_icon: str, zoom_selected):
        super().__init__()
        self.setIconSize(self.iconSize() * 0.8)
        group = QActionGroup(self)
        for icon, text, map_tool in (
                (measure_icon, measure_text, tool),
                ("/mActionPan.svg", tr("Pan (or drag with the middle button)"), QgsMapToolPan(canvas)),
                ("/mActionZoomIn.svg", tr("Zoom in (or the mouse wheel)"), QgsMapToolZoom(canvas, False)),
                ("/mActionZoomOut.svg", tr("Zoom out"), QgsMapToolZoom(canvas, True))):
            action = self.addAction(theme_icon(icon), text, lambda _=False, t=map_tool: canvas.setMapTool(t))
            action.setCheckable(True)
            group.addAction(action)
            map_tool.setAction(action)
        group.actions()[0].setChecked(True)
        canvas.setMapTool(tool)
        self.addSeparator()
        self.zoom_image = self.addAction(theme_icon("/mActionZoomFullExtent.svg"), tr("Zoom to the image"),
                                         canvas.zoom_to_image)
        self.zoom_selected = self.addAction(theme_icon("/mActionZoomToSelected.svg"), tr("Zoom to the selected one"),
                                            zoom_selected)
