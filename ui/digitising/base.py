"""What the docks share: the layout of QGIS's Georeferencer (form, buttons, tools, the canvas of the raw
image, legend, list), picking on the main map, releasing everything before QGIS exits."""
from __future__ import annotations

from qgis.core import QgsPointXY, QgsProcessingException
from qgis.gui import QgsMapToolEmitPoint
from qgis.PyQt.QtCore import Qt
from qgis.PyQt.QtGui import QKeySequence
from qgis.PyQt.QtWidgets import (QAction, QDockWidget, QFormLayout, QFrame, QHBoxLayout, QLabel,
                                 QPushButton, QScrollArea, QSplitter, QVBoxLayout, QWidget)

from ...core.errors import InputError, PushbroomError
from ...core.runs.docks import form_heights, frame
from ..parameters import DATUMS, HEIGHT_SOURCES, tr
from .canvas import CanvasTools, PixelCanvas, PixelTool, pixel_of, theme_icon
from .form import DemBox, combo, layer_path, spin_box
from .markers import CanvasDrawing


class PixelCanvasDock(QDockWidget):
    """Subclasses hold a ``session`` and an ``editor``, fill ``self.form``, call :meth:`build` and implement
    ``image_clicked(col, row, button)``, ``main_clicked(point)`` (main canvas CRS) and ``redraw()``."""

    def __init__(self, title: str, name: str, iface, hint: str, parent=None):
        super().__init__(title, parent, objectName=name, minimumWidth=380)
        self.iface, self.canvas, self.form, self.dem_combo = iface, PixelCanvas(hint), QFormLayout(), None
        self.drawing, self.tool = CanvasDrawing(self.canvas), PixelTool(self.canvas, self.image_clicked)
        self.canvas.xyCoordinates.connect(lambda at: self.show_pixel(*pixel_of(at)))  # whatever the tool
        self.pixel_label = QLabel(" ")
        self.message_label = QLabel(wordWrap=True, textInteractionFlags=Qt.TextSelectableByMouse)
        self.previous_main_tool, self.pick_tool = None, QgsMapToolEmitPoint(iface.mapCanvas())
        self.pick_tool.canvasClicked.connect(self._picked)

    def build(self, buttons, measure: tuple[str, str], legend: QWidget, below: QWidget) -> None:
        """Lay out ``buttons``: rows of (``self.<attribute>``, text, slot); ``measure``: (tool tip, icon)."""
        form_box, self.form_pane, centre = QWidget(), QScrollArea(), QWidget()
        form_box.setLayout(self.form)
        self.form_pane.setWidget(form_box)
        self.form_pane.setWidgetResizable(True)
        self.form_pane.setFrameShape(QFrame.NoFrame)
        column = QVBoxLayout(centre)
        column.setContentsMargins(0, 0, 0, 0)
        for row in buttons:
            line = QHBoxLayout()
            for attr, text, slot in row:
                setattr(self, attr, QPushButton(text, clicked=slot))
                line.addWidget(getattr(self, attr))
            column.addLayout(line)
        self.tools = CanvasTools(self.canvas, self.tool, *measure, self.zoom_to_selected)
        self.tools.addSeparator()
        self.undo_action = self._action("/mActionUndo.svg", tr("Undo the last change (Ctrl+Z)"), QKeySequence.Undo,
                                        self.undo)
        self.delete_action = self._action("/mActionDeleteSelected.svg", tr("Delete the selected one (Delete)"),
                                          QKeySequence.Delete, self.delete_selected)
        self.undo_button = self.tools.widgetForAction(self.undo_action)
        self.delete_button = self.tools.widgetForAction(self.delete_action)
        self.tools.addSeparator()
        self.form_action = QAction(theme_icon("/mActionOptions.svg"), tr("Show or hide the settings"), self.tools,
                                   checkable=True, checked=True, toggled=self.form_pane.setVisible)
        self.tools.addAction(self.form_action)
        for widget, stretch in ((self.tools, 0), (self.canvas, 1), (legend, 0), (self.pixel_label, 0)):
            column.addWidget(widget, stretch)
        self.splitter = QSplitter(Qt.Vertical)
        for k, (widget, stretch) in enumerate(((self.form_pane, 0), (centre, 1), (below, 0))):
            self.splitter.addWidget(widget)
            self.splitter.setStretchFactor(k, stretch)
        self.splitter.setCollapsible(1, False)
        self.splitter.setSizes([250, 520, 140])
        body = QWidget()
        layout = QVBoxLayout(body)
        layout.addWidget(self.splitter, 1)
        layout.addWidget(self.message_label)
        self.setWidget(body)

    def _action(self, icon: str, text: str, keys, slot) -> QAction:
        """A tool bar action with a shortcut that works while the focus is in the dock."""
        action = QAction(theme_icon(icon), text, self, shortcutContext=Qt.WidgetWithChildrenShortcut, triggered=slot)
        action.setShortcut(keys)
        self.tools.addAction(action)
        self.addAction(action)
        return action

    def add_height_rows(self, tooltip: str, z_words: str, source: str) -> None:
        """Heights from z, dem or constant (``source``), DEM, datum, constant; ``z_words``: what 'z' is."""
        self.z_words, self.dem_combo, self.datum_combo = z_words, DemBox(), combo(DATUMS)
        self.height_combo, self.height_spin = combo(HEIGHT_SOURCES, tooltip, source), spin_box(0, -500, 9000, " m", "")
        for label, widget in ((tr("Heights from"), self.height_combo), (tr("DEM"), self.dem_combo),
                              (tr("Height datum"), self.datum_combo), (tr("Constant height"), self.height_spin)):
            self.form.addRow(label, widget)

    def heights(self):
        """(:class:`core.observations.tables.Heights`, where they come from in words)."""
        dem = self.dem_combo.currentLayer()
        return form_heights(self.height_combo.currentText(), self.datum_combo.currentText(), self.height_spin.value(),
                            layer_path(dem) if dem is not None else None, dem.name() if dem is not None else "",
                            self.z_words)

    def tell(self, text: str) -> None:
        self.message_label.setText(text)

    def attempt(self, call, redraw: bool = True) -> bool:
        """Call ``call``: show the sentence it returns and redraw, or show its refusal; whether it went."""
        try:
            message = call()
        except (PushbroomError, QgsProcessingException) as exc:
            self.tell(str(exc))
            return False
        if isinstance(message, str) and message:
            self.tell(message)
        if redraw:
            self.redraw()
        return True

    def show_pixel(self, col: float, row: float) -> None:
        """Pixel coordinates under the cursor, in the dock's status line."""
        self.pixel_label.setText(tr("col {col:.1f}, row {row:.1f} px").format(col=col, row=row))

    def show_raster(self, path: str, name: str) -> None:
        """Show the raster at ``path`` (a display copy) alone, whole; InputError when QGIS cannot."""
        if not self.canvas.show_raster(path, name):
            raise InputError(tr("{path}: QGIS cannot show this raster").format(path=path))

    def undo(self) -> None:
        self.attempt(self.session.undo)

    def delete_selected(self) -> None:
        self.attempt(self.session.delete)

    def zoom_to_selected(self) -> None:
        """Frame what is selected (a point: at ZOOM_TO_POINT_PX either side; a line: its vertices)."""
        pixels = self.session.selected_pixels()
        if not pixels:
            self.tell(tr("Nothing selected to zoom to"))
        elif len(pixels) == 1:
            self.canvas.zoom_to_pixel(*pixels[0])
        else:
            self.canvas.zoom_to_pixel(*frame(pixels))

    def start_picking(self, message: str, refusal: str) -> None:
        """The main map's next click goes to ``main_clicked`` (``refusal`` said if nothing is selected)."""
        if self.editor.selected is None:
            self.tell(refusal)
            return
        main = self.iface.mapCanvas()
        if main.mapTool() is not self.pick_tool:
            self.previous_main_tool = main.mapTool()
        main.setMapTool(self.pick_tool)
        self.tell(message)

    def _picked(self, point: QgsPointXY, button=None) -> None:
        main = self.iface.mapCanvas()
        if self.previous_main_tool is not None:
            main.setMapTool(self.previous_main_tool)
        else:
            main.unsetMapTool(self.pick_tool)
        self.main_clicked(point)

    def closeEvent(self, event):  # noqa: N802 (Qt API name)
        main = self.iface.mapCanvas()
        if main.mapTool() is self.pick_tool:
            main.unsetMapTool(self.pick_tool)
        super().closeEvent(event)

    def dispose(self) -> None:
        """Release all while QGIS is alive (a raster pipe outliving its provider: a crash); safe twice."""
        self.close()
        self.drawing.clear()
        self.canvas.dispose()
        if self.dem_combo is not None:
            self.dem_combo.dispose()
