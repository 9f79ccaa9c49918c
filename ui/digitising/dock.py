"""The dock 'Digitise control lines on the raw image': lines clicked on it, paired with ground lines on the
map, predicted, snapped, saved. The session and its rules: :mod:`core.runs.digitiselines`."""
from __future__ import annotations

import numpy as np
from qgis.core import QgsCoordinateReferenceSystem, QgsMapLayerProxyModel, QgsWkbTypes
from qgis.gui import QgsFieldComboBox, QgsMapLayerComboBox
from qgis.PyQt.QtCore import Qt
from qgis.PyQt.QtWidgets import QLabel, QListWidget

from ...core.errors import InputError
from ...core.measure.snapping import MODES as SNAP_MODES
from ...core.measure.snapping import SnapSettings
from ...core.measure.sources import open_image_source
from ...core.runs.digitiselines import LineSession
from ..inputs import block_scene_names
from ..parameters import tr
from .base import PixelCanvasDock
from .canvas import point_of
from .form import ask_gpkg, ask_scene, cache_folder, combo, labelled_row, layer_parts, spin_box
from .markers import legend


class DigitisingDock(PixelCanvasDock):
    """The dock. ``iface``: the QGIS interface (its mapCanvas() is where ground lines are picked)."""

    def __init__(self, iface, parent=None):
        super().__init__(tr("Digitise control lines on the raw image"), "PushbroomDigitisingDock", iface,
                         tr("Open image… to start: a scene file and its raw image"), parent)
        self.session = LineSession()
        self.editor = self.session.editor
        form = self.form
        self.scene_label = QLabel(tr("none"), wordWrap=True)
        form.addRow(tr("Scene"), self.scene_label)
        self.ground_combo, self.id_combo = QgsMapLayerComboBox(), QgsFieldComboBox()
        self.ground_combo.setFilters(QgsMapLayerProxyModel.LineLayer)
        self.ground_combo.layerChanged.connect(self.id_combo.setLayer)
        self.id_combo.setLayer(self.ground_combo.currentLayer())
        form.addRow(tr("Ground lines"), labelled_row(("", self.ground_combo), (tr("id field"), self.id_combo)))
        self.add_height_rows(tr("Heights of the ground lines for the prediction: z = the lines' Z values, dem = the "
                                "DEM below (the constant when none is chosen), constant = the height below"),
                             tr("the lines' Z"), "z")
        self.snap_mode_combo = combo(SNAP_MODES, tr("Snap moves the selected line's vertices across it to the centre "
                                                    "of a bright band (a road) or to the strongest edge"))
        self.snap_width_spin = spin_box(SnapSettings().width, 0.5, 19.5, " px", tr("the band's width"))
        form.addRow(tr("Snap to"), labelled_row(("", self.snap_mode_combo), (tr("band width"), self.snap_width_spin)))
        self.line_list = QListWidget(currentRowChanged=self._list_selected)
        self.build(((("image_button", tr("Open image…"),
                      lambda: ask_scene(self, tr("Open a raw image with its scene"), self.open_image)),
                     ("finish_button", tr("Finish"), self.finish_line),
                     ("pair_button", tr("Pair"), lambda: self.start_picking(
                         tr("Click the matching ground line on the map"),
                         tr("Select an image line first (in the list), then press Pair")))),
                    (("snap_button", tr("Snap"), self.snap), ("predict_button", tr("Predict"), self.predict),
                     ("save_button", tr("Save…"), lambda: ask_gpkg(self, tr("Save image lines"), self.save)))),
                   (tr("Digitise: left click adds a vertex, right click ends the line"), "/mActionCaptureLine.svg"),
                   legend((), (("line", tr("lines")), ("selected", tr("selected")), ("drawing", tr("being drawn")),
                               ("predicted", tr("ground lines predicted")))), self.line_list)

    source = property(lambda self: self.session.source)
    scene = property(lambda self: self.session.scene)
    raw_image = property(lambda self: self.session.raw_image)
    predicted = property(lambda self: self.session.predicted)

    def image_clicked(self, col: float, row: float, button) -> None:
        """Left click adds a vertex, right click finishes the line."""
        if button == Qt.LeftButton:
            self.add_vertex(col, row)
        else:
            self.finish_line()

    def open_image(self, path: str, image: str | None = None, camera: str | None = None) -> bool:
        """Show a scene's raw image, a display copy or a raster alone; False (said) when it cannot."""
        def show() -> str:
            source = open_image_source(path, cache_folder(), image, camera, require_scene=False)
            self.show_raster(str(source.display), tr("Raw image"))
            return self.session.open(str(path), source)
        opened = self.attempt(show)
        self.scene_label.setText(self.session.scene_words())
        return opened

    def add_vertex(self, col: float, row: float) -> None:
        self.attempt(lambda: self.editor.add_vertex(col, row))

    def finish_line(self) -> None:
        self.attempt(self.session.finish)

    def snap(self) -> None:
        """Snap the selected line to the raw image's feature across it (undoable)."""
        self.attempt(lambda: self.session.snap(SnapSettings(mode=self.snap_mode_combo.currentText(),
                                                            width=self.snap_width_spin.value())))

    def _list_selected(self, row: int) -> None:
        if 0 <= row < len(self.editor.lines) and self.editor.selected != row:
            self.editor.select(row)
            self.redraw()

    def ground_parts(self, crs: QgsCoordinateReferenceSystem) -> tuple[list[str], list[np.ndarray]]:
        """(ids, parts [(n, 2|3)]) of the chosen ground layer's lines, x, y in ``crs`` (z kept)."""
        layer, field = self.ground_combo.currentLayer(), self.id_combo.currentField()
        if layer is None or not field:
            raise InputError(tr("choose a ground line layer and its line id field"))
        ids, parts = layer_parts(layer, crs, field)
        return ids, parts if QgsWkbTypes.hasZ(layer.wkbType()) else [p[:, :2] for p in parts]

    def main_clicked(self, point) -> None:
        """Pair the selected image line with the ground line nearest to ``point`` (main canvas CRS)."""
        crs = self.iface.mapCanvas().mapSettings().destinationCrs()
        self.attempt(lambda: self.session.pair(*self.ground_parts(crs), point.x(), point.y()))

    def predict(self) -> None:
        """Draw the chosen ground lines as the scene model sees them in this camera."""
        self.attempt(lambda: self.session.predict(lambda: self.ground_parts(QgsCoordinateReferenceSystem("EPSG:4326")),
                                                  *self.heights()))

    def save(self, path: str) -> bool:
        """Write the lines to layer ``image_lines`` of GeoPackage ``path``; False (said) when they cannot."""
        return self.attempt(lambda: self.session.save(path, block_scene_names), False)

    def redraw(self) -> None:
        """Bands and the list from the session."""
        self.drawing.clear()
        for vertices, kind in self.session.bands():
            self.drawing.polyline([point_of(c, r) for c, r in vertices], kind)
        self.line_list.blockSignals(True)
        self.line_list.clear()
        self.line_list.addItems(self.session.rows())
        self.line_list.setCurrentRow(-1 if self.editor.selected is None else self.editor.selected)
        self.line_list.blockSignals(False)
