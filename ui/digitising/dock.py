"""The dock 'Digitise control lines on the raw image': its own map canvas showing a display copy
(pushbroom:preparedigitising) in the pixel frame x = col, y = -row, a map tool that digitises
image lines, pairing with ground lines picked on the main map canvas, ground lines predicted into
the image by the scene model, Snap (the selected line to the road's centre or an edge of the raw
image the display copy shows, :mod:`core.snapping`, undoable) and Save to an ``image_lines``
GeoPackage layer. With a scene file given, each saved line names its scene (the field ``scene``: the
name bundleadjust with SCENES gives that file, :func:`ui.inputs.block_scene_names`), so that the
layer serves a block of scenes as it is.

The logic lives in :mod:`core.measure.digitising` (vertices, undo, pairing, prediction); this module
turns mouse events and buttons into its calls and draws its state. The canvas, its map tool, picking
on the main canvas, the heights form and the rubber bands are :mod:`.base`'s (shared with the GCP
dock, :mod:`.gcpdock`).
"""
from __future__ import annotations

import numpy as np
from qgis.core import (QgsCoordinateReferenceSystem, QgsCoordinateTransform, QgsGeometry, QgsMapLayerProxyModel,
                       QgsProject, QgsWkbTypes)
from qgis.gui import QgsFieldComboBox, QgsMapLayerComboBox
from qgis.PyQt.QtCore import Qt
from qgis.PyQt.QtGui import QColor
from qgis.PyQt.QtWidgets import (QComboBox, QDoubleSpinBox, QFileDialog, QHBoxLayout, QLabel, QLineEdit, QPushButton)

from ...core.errors import PushbroomError
from ...core.formats import load_scene
from ...core.measure.digitising import LineEditor, nearest_line, predict_lines
from ...core.measure.display import read_display_source
from ...core.measure.snapping import MODES as SNAP_MODES
from ...core.measure.snapping import SnapSettings
from ...core.observations.lines import write_gpkg
from ..inputs import block_scene_names
from ..parameters import tr
from .base import PixelCanvasDock

LINE_COLOUR, CURRENT_COLOUR, SELECTED_COLOUR, PREDICTED_COLOUR = (QColor(0, 200, 255), QColor(255, 220, 0),
                                                                    QColor(255, 60, 60), QColor(255, 0, 255))
PREDICTION_STEP_M = 20.0  # ground spacing of predicted points: a few pixels of a 2-5 m GSD image


class DigitisingDock(PixelCanvasDock):
    """The dock. ``iface``: the QGIS interface (its mapCanvas() is where ground lines are picked)."""

    def __init__(self, iface, parent=None):
        super().__init__(tr("Digitise control lines on the raw image"), "PushbroomDigitisingDock", iface, parent)
        self.editor = LineEditor()
        self.raw_image = ""  # the raw image the display copy shows (snapping reads its pixels)
        self.scene, self.camera_name, self.predicted = None, "", []
        self._build()

    # --- widgets -------------------------------------------------------------------------------
    def _build(self) -> None:
        form = self.form
        self.image_button = QPushButton(tr("Open display copy…"))
        self.image_button.clicked.connect(self._choose_image)
        form.addRow(tr("Image"), self.image_button)
        self.scene_edit, self.camera_edit = QLineEdit(), QLineEdit()
        self.scene_edit.editingFinished.connect(self._load_scene)
        form.addRow(tr("Scene"), self.scene_edit)
        form.addRow(tr("Camera"), self.camera_edit)
        self.ground_combo = QgsMapLayerComboBox()
        self.ground_combo.setFilters(QgsMapLayerProxyModel.LineLayer)
        self.id_combo = QgsFieldComboBox()
        self.ground_combo.layerChanged.connect(self.id_combo.setLayer)
        self.id_combo.setLayer(self.ground_combo.currentLayer())
        form.addRow(tr("Ground lines"), self.ground_combo)
        form.addRow(tr("Line id field"), self.id_combo)
        self.add_height_rows(tr("Heights of the ground lines for the prediction: z = the lines' Z values, dem = the "
                                "DEM below, constant = the height below"))
        self.snap_mode_combo = QComboBox()
        self.snap_mode_combo.addItems(SNAP_MODES)
        self.snap_mode_combo.setToolTip(tr("Snap moves the selected line's vertices across it to the centre of a "
                                           "bright band (a road) or to the strongest edge"))
        self.snap_width_spin = QDoubleSpinBox()
        self.snap_width_spin.setRange(0.5, 19.5)
        self.snap_width_spin.setValue(SnapSettings().width)
        snapping = QHBoxLayout()
        snapping.addWidget(self.snap_mode_combo)
        snapping.addWidget(QLabel(tr("band width (px)")))
        snapping.addWidget(self.snap_width_spin)
        form.addRow(tr("Snap to"), snapping)
        self.add_buttons((("finish_button", tr("Finish"), self.finish_line),
                          ("undo_button", tr("Undo"), self.undo),
                          ("delete_button", tr("Delete"), self.delete_selected),
                          ("pair_button", tr("Pair"), self.start_pairing),
                          ("snap_button", tr("Snap"), self.snap),
                          ("predict_button", tr("Predict"), self.predict),
                          ("save_button", tr("Save…"), self._choose_save)))
        self.line_list = self.finish_with_list(self._list_selected)

    def image_clicked(self, col: float, row: float, button) -> None:
        """Left click adds a vertex, right click finishes the line."""
        if button == Qt.LeftButton:
            self.add_vertex(col, row)
        else:
            self.finish_line()

    # --- image and scene ------------------------------------------------------------------------
    def _choose_image(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, tr("Display copy"), "", "Virtual raster (*.vrt);;All files (*)")
        if path:
            self.open_image(path)

    def open_image(self, path: str) -> bool:
        """Show a display copy (or any raster in the pixel frame) and take the scene and camera it
        names; False (with a message) when it cannot be read."""
        try:
            source = read_display_source(path)
        except PushbroomError as exc:
            self.tell(str(exc))
            return False
        if not self.show_raster(path, tr("Display copy")):
            return False
        self.raw_image = source.image
        self.scene_edit.setText(source.scene)
        self.camera_edit.setText(source.camera)
        self._load_scene()
        return True

    def _load_scene(self) -> None:
        path = self.scene_edit.text().strip()
        self.scene = None
        if not path:
            self.tell(tr("No scene: give the scene file to see predicted ground lines"))
            return
        try:
            self.scene = load_scene(path)
        except PushbroomError as exc:
            self.tell(str(exc))

    def camera_index(self) -> int:
        text = self.camera_edit.text().strip()
        return self.scene.camera_index(int(text) if text.isdigit() else text) if text else 0

    # --- digitising -----------------------------------------------------------------------------
    def add_vertex(self, col: float, row: float) -> None:
        self.editor.add_vertex(col, row)
        self.redraw()

    def finish_line(self) -> None:
        try:
            index = self.editor.finish()
        except PushbroomError as exc:
            self.tell(str(exc))
            return
        self.tell(tr("Line {n} finished: press Pair, then click its ground line on the map").format(n=index + 1))
        self.redraw()

    def undo(self) -> None:
        removed = self.editor.undo()
        self.tell({"vertex": tr("Last vertex removed"), "line": tr("Last line removed"),
                   "snap": tr("Snap undone"), "": tr("Nothing to undo")}[removed])
        self.redraw()

    def snap(self) -> None:
        """Snap the selected line to the raw image's feature across it (undoable)."""
        if not self.raw_image:
            self.tell(tr("Open the display copy first"))
            return
        try:
            refined, total = self.editor.snap_selected(self.raw_image, SnapSettings(
                mode=self.snap_mode_combo.currentText(), width=self.snap_width_spin.value()))
        except PushbroomError as exc:
            self.tell(str(exc))
            return
        self.tell(tr("{refined} of {total} vertices snapped (Undo restores them); the others found no clear "
                     "feature and kept their place").format(refined=refined, total=total))
        self.redraw()

    def delete_selected(self) -> None:
        self.tell(tr("Line deleted") if self.editor.delete_selected() else tr("Select a line in the list first"))
        self.redraw()

    def _list_selected(self, row: int) -> None:
        if 0 <= row < len(self.editor.lines) and self.editor.selected != row:
            self.editor.select(row)
            self.redraw()

    # --- pairing with ground lines ------------------------------------------------------------
    def start_pairing(self) -> None:
        """Next click on the main map canvas picks the selected line's ground line."""
        if self.editor.selected is None:
            self.tell(tr("Select an image line first (in the list), then press Pair"))
            return
        self.start_picking(tr("Click the matching ground line on the map"))

    def ground_parts(self, crs: QgsCoordinateReferenceSystem) -> tuple[list[str], list[np.ndarray]]:
        """(ids, parts [(n, 2|3)]) of the chosen ground layer's lines, x, y in ``crs`` (z kept)."""
        layer, field = self.ground_combo.currentLayer(), self.id_combo.currentField()
        if layer is None or not field:
            raise ValueError(tr("choose a ground line layer and its line id field"))
        transform = QgsCoordinateTransform(layer.crs(), crs, QgsProject.instance())
        ids, parts = [], []
        for feature in layer.getFeatures():
            geometry = QgsGeometry(feature.geometry())
            if geometry.isEmpty():
                continue
            geometry.transform(transform)
            for part in geometry.constParts():
                points = [(p.x(), p.y(), p.z()) for p in part.vertices()]
                xyz = np.array(points, dtype=float)
                parts.append(xyz if QgsWkbTypes.hasZ(layer.wkbType()) else xyz[:, :2])
                ids.append(str(feature[field]))
        return ids, parts

    def main_clicked(self, point) -> None:
        """Pair the selected image line with the ground line nearest to ``point`` (main canvas CRS)."""
        try:
            ids, parts = self.ground_parts(self.iface.mapCanvas().mapSettings().destinationCrs())
            index, _ = nearest_line(parts, point.x(), point.y())
            self.editor.pair_selected(ids[index])
        except (PushbroomError, ValueError) as exc:
            self.tell(str(exc))
            return
        self.tell(tr("Line {n} paired with ground line {id}").format(n=self.editor.selected + 1, id=ids[index]))
        self.redraw()

    # --- prediction ---------------------------------------------------------------------------
    def predict(self) -> None:
        """Draw the chosen ground lines as the scene model sees them in this camera."""
        if self.scene is None:
            self.tell(tr("No scene: give the scene file first"))
            return
        try:
            ids, parts = self.ground_parts(QgsCoordinateReferenceSystem("EPSG:4326"))
            self.predicted = predict_lines(self.scene, self.camera_index(), ids, parts, self.heights(),
                                           PREDICTION_STEP_M)
        except (PushbroomError, ValueError) as exc:
            self.tell(str(exc))
            return
        shown = sum(bool(p.runs()) for p in self.predicted)
        self.tell(tr("{shown} of {n} ground lines predicted into the image").format(shown=shown,
                                                                                     n=len(self.predicted)))
        self.redraw()

    # --- saving -------------------------------------------------------------------------------
    def _choose_save(self) -> None:
        path, _ = QFileDialog.getSaveFileName(self, tr("Save image lines"), "", "GeoPackage (*.gpkg)")
        if path:
            self.save(path)

    def save(self, path: str) -> bool:
        """Write the lines to layer ``image_lines`` of GeoPackage ``path`` (replaced whole, or not at
        all), naming the scene file's block name when one is given; False (with the reason shown)
        when they cannot be saved."""
        scene_file = self.scene_edit.text().strip()
        try:
            scene = block_scene_names([scene_file])[0] if scene_file else ""
            write_gpkg(path, image=self.editor.image_lines(self.camera_edit.text().strip(), scene=scene))
        except PushbroomError as exc:
            self.tell(str(exc))
            return False
        self.tell(tr("{n} image lines saved to {path}").format(n=len(self.editor.lines), path=path))
        return True

    # --- drawing ------------------------------------------------------------------------------
    def redraw(self) -> None:
        """Rubber bands and the list from the editor's state and the prediction."""
        self.clear_bands()
        for line in self.predicted:
            for run in line.runs():
                self.add_polyline(run.tolist(), PREDICTED_COLOUR, 1, dashed=True)
        for i, line in enumerate(self.editor.lines):
            self.add_polyline(line.vertices, SELECTED_COLOUR if i == self.editor.selected else LINE_COLOUR, 2)
        if self.editor.current:
            self.add_polyline(self.editor.current, CURRENT_COLOUR, 2)
        self.line_list.blockSignals(True)
        self.line_list.clear()
        for i, line in enumerate(self.editor.lines):
            self.line_list.addItem(tr("{n}: {id} ({v} vertices)").format(
                n=i + 1, id=line.line_id or tr("not paired"), v=len(line.vertices)))
        self.line_list.setCurrentRow(-1 if self.editor.selected is None else self.editor.selected)
        self.line_list.blockSignals(False)
