"""What the docks that measure on raw images share: a map canvas of their own showing a display
copy (pushbroom:preparedigitising) in the pixel frame x = col, y = -row, a map tool that turns
clicks on it into pixel positions, one-shot picking on the main map canvas, the heights form
(Z, DEM or constant), rubber bands, a status line, and releasing the canvas before QGIS exits.
"""
from __future__ import annotations

from qgis.core import QgsGeometry, QgsMapLayerProxyModel, QgsPointXY, QgsRasterLayer, QgsWkbTypes
from qgis.gui import QgsMapCanvas, QgsMapLayerComboBox, QgsMapTool, QgsMapToolEmitPoint, QgsRubberBand
from qgis.PyQt.QtCore import Qt
from qgis.PyQt.QtGui import QColor
from qgis.PyQt.QtWidgets import (QComboBox, QDockWidget, QDoubleSpinBox, QFormLayout, QHBoxLayout, QLabel,
                                 QListWidget, QPushButton, QVBoxLayout, QWidget)

from ...core.observations.tables import Heights
from ..parameters import DATUMS, HEIGHT_SOURCES, tr


def pixel_of(point: QgsPointXY) -> tuple[float, float]:
    """(col, row) px of a point of the pixel frame (x = col, y = -row)."""
    return point.x(), -point.y()


def point_of(col: float, row: float) -> QgsPointXY:
    return QgsPointXY(col, -row)


class PixelTool(QgsMapTool):
    """On a dock's canvas: a release of the left or right button calls the dock's
    ``image_clicked(col, row, button)``; moving shows the pixel under the cursor."""

    def __init__(self, dock: "PixelCanvasDock"):
        super().__init__(dock.canvas)
        self.dock = dock

    def canvasMoveEvent(self, event):  # noqa: N802 (QGIS API name)
        self.dock.show_pixel(*pixel_of(event.mapPoint()))

    def canvasReleaseEvent(self, event):  # noqa: N802
        if event.button() in (Qt.LeftButton, Qt.RightButton):
            self.dock.image_clicked(*pixel_of(event.mapPoint()), event.button())


class PixelCanvasDock(QDockWidget):
    """The shared dock. Subclasses build their widgets into ``self.body_layout`` and ``self.form``
    (between them and the canvas), then call :meth:`finish_layout`; they implement
    ``image_clicked(col, row, button)`` and ``main_clicked(point)`` (a pick on the main canvas,
    in its CRS)."""

    def __init__(self, title: str, name: str, iface, parent=None):
        super().__init__(title, parent)
        self.setObjectName(name)
        self.iface = iface
        self.layer: QgsRasterLayer | None = None
        self.bands: list[QgsRubberBand] = []
        self.previous_main_tool = None
        self.canvas = QgsMapCanvas()
        self.canvas.setMinimumHeight(250)
        self.pixel_label, self.message_label = QLabel(), QLabel()
        self.message_label.setWordWrap(True)
        self.tool = PixelTool(self)
        self.canvas.setMapTool(self.tool)
        self.pick_tool = QgsMapToolEmitPoint(iface.mapCanvas())
        self.pick_tool.canvasClicked.connect(self._picked)
        self.body_layout = QVBoxLayout()
        self.form = QFormLayout()
        self.body_layout.addLayout(self.form)

    def add_buttons(self, *rows) -> None:
        """Rows of push buttons under the form, each a sequence of (attribute, text, slot); every
        button kept as ``self.<attribute>``."""
        for row in rows:
            buttons = QHBoxLayout()
            for attr, text, slot in row:
                button = QPushButton(text)
                button.clicked.connect(slot)
                setattr(self, attr, button)
                buttons.addWidget(button)
            self.body_layout.addLayout(buttons)

    def finish_with_list(self, on_select) -> QListWidget:
        """:meth:`finish_layout` with a list under the canvas (its row changes go to ``on_select``)."""
        listed = QListWidget()
        listed.setMaximumHeight(110)
        listed.currentRowChanged.connect(on_select)
        self.finish_layout([listed])
        return listed

    def finish_layout(self, below_canvas=()) -> None:
        """Put the canvas, the widgets ``below_canvas`` and the status lines under the form."""
        self.body_layout.addWidget(self.canvas, 1)
        for widget in below_canvas:
            self.body_layout.addWidget(widget)
        self.body_layout.addWidget(self.pixel_label)
        self.body_layout.addWidget(self.message_label)
        body = QWidget()
        body.setLayout(self.body_layout)
        self.setWidget(body)

    def add_height_rows(self, tooltip: str) -> None:
        """Rows 'Heights from' (z / dem / constant), 'DEM', 'Height datum', 'Constant height' in the form."""
        self.height_combo = QComboBox()
        self.height_combo.addItems(HEIGHT_SOURCES)
        self.height_combo.setToolTip(tooltip)
        self.dem_combo = QgsMapLayerComboBox()
        self.dem_combo.setFilters(QgsMapLayerProxyModel.RasterLayer)
        self.dem_combo.setAllowEmptyLayer(True)
        self.datum_combo = QComboBox()
        self.datum_combo.addItems(DATUMS)
        self.height_spin = QDoubleSpinBox()
        self.height_spin.setRange(-500.0, 9000.0)
        self.form.addRow(tr("Heights from"), self.height_combo)
        self.form.addRow(tr("DEM"), self.dem_combo)
        self.form.addRow(tr("Height datum"), self.datum_combo)
        self.form.addRow(tr("Constant height (m)"), self.height_spin)

    def heights(self) -> Heights:
        dem = self.dem_combo.currentLayer()
        return Heights(self.height_combo.currentText(), self.datum_combo.currentText(),
                       dem.source().split("|")[0] if dem is not None else None, self.height_spin.value())

    def tell(self, text: str) -> None:
        self.message_label.setText(text)

    def show_pixel(self, col: float, row: float) -> None:
        """Pixel coordinates under the cursor, in the dock's status line."""
        self.pixel_label.setText(tr("col {col:.1f}, row {row:.1f} px").format(col=col, row=row))

    def show_raster(self, path: str, name: str) -> bool:
        """Show the raster at ``path`` (a display copy) alone on the dock's canvas, whole; False
        (with a message) when QGIS cannot show it."""
        layer = QgsRasterLayer(path, name)
        if not layer.isValid():
            self.tell(tr("{path}: QGIS cannot show this raster").format(path=path))
            return False
        self.canvas.setDestinationCrs(layer.crs())
        self.canvas.setLayers([layer])
        self.layer = layer
        self.canvas.setExtent(layer.extent())
        self.canvas.refresh()
        return True

    # --- picking on the main map canvas ---------------------------------------------------------
    def start_picking(self, message: str) -> None:
        """The next click on the main map canvas goes to ``main_clicked``."""
        main = self.iface.mapCanvas()
        self.previous_main_tool = main.mapTool()
        main.setMapTool(self.pick_tool)
        self.tell(message)

    def _picked(self, point: QgsPointXY, button=None) -> None:
        if self.previous_main_tool is not None:
            self.iface.mapCanvas().setMapTool(self.previous_main_tool)
        self.main_clicked(point)

    # --- drawing ------------------------------------------------------------------------------
    def clear_bands(self) -> None:
        for band in self.bands:
            self.canvas.scene().removeItem(band)
        self.bands = []

    def add_band(self, geometry: QgsGeometry, kind, colour: QColor, width: int, dashed: bool = False,
                 icon=None) -> QgsRubberBand:
        """A rubber band of ``geometry`` (pixel frame) on the dock's canvas, kept until cleared."""
        band = QgsRubberBand(self.canvas, kind)
        band.setColor(colour)
        band.setWidth(width)
        if dashed:
            band.setLineStyle(Qt.DashLine)
        if icon is not None:
            band.setIcon(icon)
            band.setIconSize(12)
        band.setToGeometry(geometry, None)
        self.bands.append(band)
        return band

    def add_polyline(self, vertices, colour: QColor, width: int, dashed: bool = False) -> None:
        """A polyline band through pixel positions [(col, row)]."""
        self.add_band(QgsGeometry.fromPolylineXY([point_of(c, r) for c, r in vertices]), QgsWkbTypes.LineGeometry,
                      colour, width, dashed)

    def closeEvent(self, event):  # noqa: N802 (Qt API name)
        main = self.iface.mapCanvas()
        if main.mapTool() is self.pick_tool:
            main.unsetMapTool(self.pick_tool)
        super().closeEvent(event)

    def dispose(self) -> None:
        """Release the canvas's layer and rubber bands while QGIS is alive: a render job or a
        raster layer outliving QGIS's exit frees a raster pipe whose provider is gone (a crash)."""
        self.close()
        self.canvas.stopRendering()
        self.canvas.setLayers([])
        self.clear_bands()
        self.layer = None
