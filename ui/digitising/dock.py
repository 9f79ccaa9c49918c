"""The dock 'Digitise control lines on the raw image': its own map canvas showing a raw image (opened
with its scene, or a display copy) in the pixel frame x = col, y = -row, a map tool that digitises
image lines, pairing with ground lines picked on the main map canvas, ground lines predicted into
the image by the scene model, Snap (the selected line to the road's centre or an edge of the raw
image, :mod:`core.measure.snapping`, undoable) and Save to an ``image_lines`` GeoPackage layer. With
a scene, each saved line names its scene (the field ``scene``: the name bundleadjust with SCENES
gives that file, :func:`ui.inputs.block_scene_names`), so that the layer serves a block of scenes
as it is.

The logic lives in :mod:`core.measure.digitising` (vertices, undo, pairing, prediction); this module
turns mouse events and buttons into its calls and draws its state. The canvas and its tools, picking
on the main canvas and the heights form are :mod:`.base`'s (shared with the GCP dock, :mod:`.gcpdock`).
"""
from __future__ import annotations

import numpy as np
from qgis.core import (QgsCoordinateReferenceSystem, QgsCoordinateTransform, QgsGeometry, QgsMapLayerProxyModel,
                       QgsProject, QgsWkbTypes)
from qgis.gui import QgsFieldComboBox, QgsMapLayerComboBox
from qgis.PyQt.QtCore import Qt
from qgis.PyQt.QtWidgets import QComboBox, QDialog, QFileDialog, QLabel, QListWidget

from ...core.errors import PushbroomError
from ...core.measure.digitising import LineEditor, nearest_line, predict_lines
from ...core.measure.snapping import MODES as SNAP_MODES
from ...core.measure.snapping import SnapSettings
from ...core.measure.sources import open_image_source
from ...core.observations.lines import write_gpkg
from ..inputs import block_scene_names
from ..parameters import tr
from .base import PixelCanvasDock
from .canvas import point_of
from .form import labelled_row, spin_box
from .markers import legend
from .opening import SceneDialog, cache_folder

PREDICTION_STEP_M = 20.0  # ground spacing of predicted points: a few pixels of a 2-5 m GSD image


class DigitisingDock(PixelCanvasDock):
    """The dock. ``iface``: the QGIS interface (its mapCanvas() is where ground lines are picked)."""

    def __init__(self, iface, parent=None):
        super().__init__(tr("Digitise control lines on the raw image"), "PushbroomDigitisingDock", iface,
                         tr("Open image… to start: a scene file and its raw image"), parent)
        self.editor = LineEditor()
        self.source = None  # the core.measure.sources.ImageSource shown
        self.raw_image = ""  # the raw image shown (snapping reads its pixels)
        self.scene, self.predicted = None, []
        self._build()

    # --- widgets -------------------------------------------------------------------------------
    def _build(self) -> None:
        form = self.form
        self.scene_label = QLabel(tr("none"))
        self.scene_label.setWordWrap(True)
        form.addRow(tr("Scene"), self.scene_label)
        self.ground_combo = QgsMapLayerComboBox()
        self.ground_combo.setFilters(QgsMapLayerProxyModel.LineLayer)
        self.id_combo = QgsFieldComboBox()
        self.ground_combo.layerChanged.connect(self.id_combo.setLayer)
        self.id_combo.setLayer(self.ground_combo.currentLayer())
        form.addRow(tr("Ground lines"), labelled_row(("", self.ground_combo), (tr("id field"), self.id_combo)))
        self.add_height_rows(tr("Heights of the ground lines for the prediction: z = the lines' Z values, dem = the "
                                "DEM below (the constant when none is chosen), constant = the height below"),
                             tr("the lines' Z"), "z")
        self.snap_mode_combo = QComboBox()
        self.snap_mode_combo.addItems(SNAP_MODES)
        self.snap_mode_combo.setToolTip(tr("Snap moves the selected line's vertices across it to the centre of a "
                                           "bright band (a road) or to the strongest edge"))
        self.snap_width_spin = spin_box(SnapSettings().width, 0.5, 19.5, " px", tr("the band's width"))
        form.addRow(tr("Snap to"), labelled_row(("", self.snap_mode_combo), (tr("band width"), self.snap_width_spin)))
        self.line_list = QListWidget()
        self.line_list.currentRowChanged.connect(self._list_selected)
        self.build(((("image_button", tr("Open image…"), self._choose_image),
                     ("finish_button", tr("Finish"), self.finish_line),
                     ("pair_button", tr("Pair"), self.start_pairing)),
                    (("snap_button", tr("Snap"), self.snap),
                     ("predict_button", tr("Predict"), self.predict),
                     ("save_button", tr("Save…"), self._choose_save))),
                   (tr("Digitise: left click adds a vertex, right click ends the line"), "/mActionCaptureLine.svg"),
                   legend((), (("line", tr("lines")), ("selected", tr("selected")), ("drawing", tr("being drawn")),
                               ("predicted", tr("ground lines predicted")))), self.line_list)

    def image_clicked(self, col: float, row: float, button) -> None:
        """Left click adds a vertex, right click finishes the line."""
        if button == Qt.LeftButton:
            self.add_vertex(col, row)
        else:
            self.finish_line()

    # --- image and scene ------------------------------------------------------------------------
    def _choose_image(self) -> None:
        dialog = SceneDialog(self, tr("Open a raw image with its scene"))
        if dialog.exec_() == QDialog.Accepted:
            self.open_image(*dialog.chosen())

    def open_image(self, path: str, image: str | None = None, camera: str | None = None) -> bool:
        """Show a raw image: the scene file ``path`` with its raw ``image`` of ``camera`` (None: the
        image found beside the scene, its first camera), a display copy (which names them), or a
        raster alone (no scene: no prediction, no scene name on saving); False (with a message)
        when it cannot be read."""
        try:
            source = open_image_source(path, cache_folder(), image, camera, require_scene=False)
        except PushbroomError as exc:
            self.tell(str(exc))
            return False
        if not self.show_raster(str(source.display), tr("Raw image")):
            return False
        self.source, self.raw_image, self.scene, self.predicted = source, str(source.image), source.scene, []
        self.scene_label.setText(f"{source.scene_path} ({source.camera_name})" if source.scene_path else
                                 tr("none: the image alone (no prediction)"))
        self.tell(tr("{image} shown{scene}").format(image=source.image, scene=tr(", camera {c} of {s}").format(
            c=source.camera_name, s=source.scene_path) if source.scene_path else tr(" without a scene")))
        self.redraw()
        return True

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
            self.tell(tr("Open the image first"))
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

    def selected_pixels(self) -> list[tuple[float, float]]:
        """The selected line's vertices (or those of the line being drawn)."""
        if self.editor.selected is not None:
            return list(self.editor.lines[self.editor.selected].vertices)
        return list(self.editor.current)

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
                xyz = np.array([(p.x(), p.y(), p.z()) for p in part.vertices()], dtype=float)
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
            self.tell(tr("No scene: open the image with its scene file to see where the ground lines are"))
            return
        heights, words = self.heights()
        try:
            ids, parts = self.ground_parts(QgsCoordinateReferenceSystem("EPSG:4326"))
            self.predicted = predict_lines(self.scene, self.source.camera, ids, parts, heights, PREDICTION_STEP_M)
        except (PushbroomError, ValueError) as exc:
            self.tell(str(exc))
            return
        shown = sum(bool(p.runs()) for p in self.predicted)
        self.tell(tr("{shown} of {n} ground lines predicted into the image, heights from {words}").format(
            shown=shown, n=len(self.predicted), words=words))
        self.redraw()

    # --- saving -------------------------------------------------------------------------------
    def _choose_save(self) -> None:
        path, _ = QFileDialog.getSaveFileName(self, tr("Save image lines"), "", "GeoPackage (*.gpkg)")
        if path:
            self.save(path)

    def save(self, path: str) -> bool:
        """Write the lines to layer ``image_lines`` of GeoPackage ``path`` (replaced whole, or not at
        all), naming the scene file's block name when there is one; False (with the reason shown)
        when they cannot be saved."""
        scene_file = self.source.scene_path if self.source is not None else ""
        camera = self.source.camera_name if self.source is not None else ""
        try:
            scene = block_scene_names([scene_file])[0] if scene_file else ""
            write_gpkg(path, image=self.editor.image_lines(camera, scene=scene))
        except PushbroomError as exc:
            self.tell(str(exc))
            return False
        self.tell(tr("{n} image lines saved to {path}").format(n=len(self.editor.lines), path=path))
        return True

    # --- drawing ------------------------------------------------------------------------------
    def redraw(self) -> None:
        """Bands and the list from the editor's state and the prediction."""
        self.drawing.clear()
        for line in self.predicted:
            for run in line.runs():
                self.drawing.polyline([point_of(c, r) for c, r in run.tolist()], "predicted")
        for i, line in enumerate(self.editor.lines):
            self.drawing.polyline([point_of(c, r) for c, r in line.vertices],
                                  "selected" if i == self.editor.selected else "line")
        if self.editor.current:
            self.drawing.polyline([point_of(c, r) for c, r in self.editor.current], "drawing")
        self.line_list.blockSignals(True)
        self.line_list.clear()
        for i, line in enumerate(self.editor.lines):
            self.line_list.addItem(tr("{n}: {id} ({v} vertices)").format(
                n=i + 1, id=line.line_id or tr("not paired"), v=len(line.vertices)))
        self.line_list.setCurrentRow(-1 if self.editor.selected is None else self.editor.selected)
        self.line_list.blockSignals(False)
