"""The dock 'Measure GCPs on the raw images': the scenes of a block (each added by its scene file
and raw image, or a display copy), the raw image of the current scene on the dock's canvas in the
pixel frame x = col, y = -row; a click measures the selected point there, a click on the main map
canvas (or the nearest point of a reference layer) gives its ground; where the selected point
should be in the current image is drawn, a marker per estimate (its ground, and its observation in
each other scene, through the scenes' current models); Snap refines the observation by
least-squares template matching against another scene's image or a reference orthoimage; Undo;
Save to a GCP GeoPackage; Open a saved one, or bundleadjust's adjusted GCPs with their residuals.

The logic lives in :mod:`core.measure.gcpmeasure`; this module turns events into its calls and
draws its state. The canvas and its tools, main-canvas picking and the heights form are
:mod:`.base`'s; the table :mod:`.pointtable`'s, the markers :mod:`.markers`' and :mod:`.mainmap`'s.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from qgis.core import QgsMapLayerProxyModel, QgsProcessingException
from qgis.gui import QgsMapLayerComboBox
from qgis.PyQt.QtCore import Qt
from qgis.PyQt.QtWidgets import QComboBox, QDialog, QFileDialog, QLineEdit, QListWidget

from ...core.errors import PushbroomError
from ...core.files import check_outputs
from ...core.measure.gcpmeasure import PointEditor, predict, snap_to_reference, snap_to_scene, surface_for
from ...core.measure.sources import ImageSource, open_image_source
from ...core.measure.tiematching import View
from ...core.observations.gcps import ROLES, read_gpkg, write_gpkg
from ..inputs import block_scene_names
from ..parameters import tr
from .base import PixelCanvasDock
from .canvas import point_of
from .form import labelled_row, layer_path, spin_box
from .mainmap import MainMapMarkers, canvas_to_wgs84, nearest_reference
from .markers import legend
from .opening import SceneDialog, cache_folder
from .pointtable import PointTable

SNAP_TARGETS = ("other scene", "reference orthoimage")
REFERENCE_TOLERANCE_PX = 20  # screen px: a click farther from every reference point takes none of them


class GcpDock(PixelCanvasDock):
    """The dock. ``iface``: the QGIS interface (its mapCanvas() is where ground positions are picked)."""

    def __init__(self, iface, parent=None):
        super().__init__(tr("Measure GCPs on the raw images"), "PushbroomGcpDock", iface,
                         tr("Add scene… to start: a scene file and its raw image, for each scene of the block"), parent)
        self.editor = PointEditor()
        self.views: list[View] = []                # the block's images, in the scene list's order
        self.sources: list[tuple[str, ImageSource]] = []  # (the file opened, what it opened) of each
        self.current: int | None = None            # index of the image shown
        self.predictions = []
        self.main_markers = MainMapMarkers(iface.mapCanvas())
        self._build()

    # --- widgets -------------------------------------------------------------------------------
    def _build(self) -> None:
        form = self.form
        self.scene_list = QListWidget()
        self.scene_list.setMaximumHeight(80)
        self.scene_list.currentRowChanged.connect(self.show_scene)
        form.addRow(tr("Scenes"), self.scene_list)
        self.id_edit = QLineEdit()
        self.id_edit.editingFinished.connect(self._edit_id)
        self.role_combo = QComboBox()
        self.role_combo.addItems(ROLES)
        self.role_combo.activated.connect(lambda _: self._edit(role=self.role_combo.currentText()))
        form.addRow(tr("Point"), labelled_row((tr("id"), self.id_edit), (tr("role"), self.role_combo)))
        self.sigma_px_spin = spin_box(0.5, 0.01, 1000.0, " px", tr("image sigma of the point in the scene shown"))
        self.sigma_xy_spin = spin_box(1.0, 0.0, 1000.0, " m", tr("ground sigma in plan"))
        self.sigma_z_spin = spin_box(1.0, 0.0, 1000.0, " m", tr("ground sigma in height"))
        for spin in (self.sigma_px_spin, self.sigma_xy_spin, self.sigma_z_spin):
            spin.editingFinished.connect(self._edit_sigmas)
        form.addRow(tr("Sigmas"), labelled_row((tr("image"), self.sigma_px_spin), (tr("plan"), self.sigma_xy_spin),
                                               (tr("height"), self.sigma_z_spin)))
        self.reference_combo = QgsMapLayerComboBox()
        self.reference_combo.setFilters(QgsMapLayerProxyModel.PointLayer)
        self.reference_combo.setAllowEmptyLayer(True)
        self.reference_combo.setLayer(None)
        form.addRow(tr("Reference points"), self.reference_combo)
        self.add_height_rows(tr("Heights of the ground positions: z = the reference point's Z, dem = the DEM below "
                                "(the constant when none is chosen), constant = the height below; also the surface "
                                "observations are projected on"), tr("the reference point's Z"), "dem")
        self.snap_combo = QComboBox()
        self.snap_combo.addItems(SNAP_TARGETS)
        self.ortho_combo = QgsMapLayerComboBox()
        self.ortho_combo.setFilters(QgsMapLayerProxyModel.RasterLayer)
        self.ortho_combo.setAllowEmptyLayer(True)
        self.ortho_combo.setLayer(None)
        form.addRow(tr("Snap to"), labelled_row(("", self.snap_combo), (tr("orthoimage"), self.ortho_combo)))
        self.table = PointTable(self.select_point)
        self.build(((("add_scene_button", tr("Add scene…"), self._choose_scene),
                     ("new_button", tr("New point"), self.new_point),
                     ("ground_button", tr("Ground"), self.start_ground),
                     ("snap_button", tr("Snap"), self.snap)),
                    (("open_button", tr("Open…"), self._choose_open),
                     ("save_button", tr("Save…"), self._choose_save))),
                   (tr("Measure: a click measures the selected point (a new one when none is)"),
                    "/mActionCapturePoint.svg"),
                   legend(("selected", "measured", "ground", "scene")), self.table)

    # --- the block's scenes ---------------------------------------------------------------------
    def _choose_scene(self) -> None:
        dialog = SceneDialog(self, tr("Add a scene of the block"))
        if dialog.exec_() == QDialog.Accepted:
            self.add_scene(*dialog.chosen())

    def add_scene(self, path: str, image: str | None = None, camera: str | None = None) -> bool:
        """Add a scene of the block: its scene file with raw ``image`` of ``camera`` (None: the
        image found beside the scene, its first camera), or a display copy (which names them),
        named as the block's algorithms name it, and show it; False (with the reason shown) when
        it cannot be used."""
        try:
            source = open_image_source(path, cache_folder(), image, camera)
            scene_files = list(dict.fromkeys([s.scene_path for _, s in self.sources] + [source.scene_path]))
            name = block_scene_names(scene_files)[scene_files.index(source.scene_path)]
        except (PushbroomError, QgsProcessingException) as exc:
            self.tell(str(exc))
            return False
        view = View(name, source.scene, source.camera, source.image)
        if any(v.label == view.label for v in self.views):
            self.tell(tr("{label} is in the block already").format(label=view.label))
            return False
        self.views.append(view)
        self.sources.append((str(path), source))
        self.scene_list.addItem(view.label)
        self.scene_list.setCurrentRow(len(self.views) - 1)
        return True

    def show_scene(self, index: int) -> None:
        """Show the image of the block's scene ``index`` (its display copy)."""
        if 0 <= index < len(self.views) and self.show_raster(str(self.sources[index][1].display),
                                                            self.views[index].label):
            self.current = index
            self.redraw()

    def view(self) -> View:
        if self.current is None:
            raise PushbroomError(tr("add a scene of the block first (Add scene…)"))
        return self.views[self.current]

    # --- measuring ------------------------------------------------------------------------------
    def new_point(self) -> None:
        self._run(lambda: self.editor.new_point(), tr("New point: click it on the image, and press Ground"))

    def image_clicked(self, col: float, row: float, button) -> None:
        """Left click measures the selected point in the current scene (a new point when none is)."""
        if button != Qt.LeftButton:
            return
        try:
            view = self.view()
            if self.editor.selected is None:
                self.editor.new_point()
            cam = view.scene.cameras[view.camera]
            done = self.editor.measure(view.scene_name, view.camera_name, col, row, (cam.cols, cam.rows))
        except PushbroomError as exc:
            self.tell(str(exc))
            return
        self.tell(tr("Point {id} {done} in {scene} at col {col:.2f}, row {row:.2f} px").format(
            id=self.editor.current().id, done=done, scene=view.label, col=col, row=row))
        self.redraw()

    def start_ground(self) -> None:
        """The next click on the main map canvas gives the selected point's ground."""
        if self.editor.selected is None:
            self.tell(tr("Select a point first (in the table), then press Ground"))
            return
        self.start_picking(tr("Click the point on the map (the nearest reference point is taken when a reference "
                              "layer is chosen)"))

    def main_clicked(self, point) -> None:
        """The selected point's ground at ``point`` (main canvas CRS), or at the nearest point of the
        reference layer (within REFERENCE_TOLERANCE_PX of the click); its height as the form says."""
        canvas = self.iface.mapCanvas()
        at = canvas_to_wgs84(canvas, point)
        lon, lat, z, source = at.x(), at.y(), None, "canvas"
        layer = self.reference_combo.currentLayer()
        if layer is not None:
            found = nearest_reference(layer, point, canvas.mapSettings().destinationCrs())
            if found is None:
                self.tell(tr("The reference layer {name} holds no point").format(name=layer.name()))
                return
            lon, lat, z, distance = found
            pixels = distance / max(canvas.mapUnitsPerPixel(), 1e-12)
            if pixels > REFERENCE_TOLERANCE_PX:
                self.tell(tr("No point of the reference layer {name} within {tol} screen px of the click (the "
                             "nearest is {px:.0f} px away): click nearer, or choose no reference layer to take the "
                             "click itself").format(name=layer.name(), tol=REFERENCE_TOLERANCE_PX, px=pixels))
                return
            source = "reference"
        heights, words = self.heights()
        try:
            ground = self.editor.set_ground_at(lon, lat, heights, z, source, words)
        except PushbroomError as exc:
            self.tell(str(exc))
            return
        self.tell(tr("Point {id}: ground lon {lon:.6f}, lat {lat:.6f} from the {src}, h {h:.1f} m (ellipsoidal) from "
                     "{words}").format(id=self.editor.current().id, lon=ground.lon, lat=ground.lat, src=source,
                                       h=ground.h, words=words))
        self.redraw()

    def snap(self) -> None:
        """Snap the selected point's observation in the current scene (undoable)."""
        try:
            view, point = self.view(), self.editor.current()
            surface = surface_for(self.heights()[0], view)
            if self.snap_combo.currentText() == SNAP_TARGETS[1]:
                ortho = self.ortho_combo.currentLayer()
                if ortho is None:
                    raise PushbroomError(tr("choose the reference orthoimage layer to snap to"))
                result = snap_to_reference(point, view, layer_path(ortho), surface)
                target = ortho.name()
            else:
                others = [v for v in self.views if v.scene_name != view.scene_name
                          and point.observation(v.scene_name, v.camera_name) is not None]
                if not others:
                    raise PushbroomError(tr("point {id} is measured in no other scene: measure it there first, or "
                                            "snap to a reference orthoimage").format(id=point.id))
                target, result = self._best_match(point, view, others, surface)
            self.editor.snapped(view.scene_name, view.camera_name, result)
        except PushbroomError as exc:
            self.tell(str(exc))
            return
        self.tell(tr("Snapped by {dc:+.2f}, {dr:+.2f} px to {target} (sigma {s:.2f} px, correlation {c:.2f}); Undo "
                     "restores the click").format(dc=result.shift[0], dr=result.shift[1], target=target,
                                                  s=result.sigma_px, c=result.correlation))
        self.redraw()

    @staticmethod
    def _best_match(point, view: View, others: list[View], surface):
        """(label, snap result) of the other scene whose image matches the point's best (the highest
        correlation: another date, a cloud or a shadow can spoil one of them); PushbroomError with
        each scene's reason when none matches."""
        results, reasons = [], []
        for other in others:
            try:
                results.append((other.label, snap_to_scene(point, view, other, surface)))
            except PushbroomError as exc:
                reasons.append(f"{other.label}: {exc}")
        if not results:
            raise PushbroomError("; ".join(reasons))
        return max(results, key=lambda item: item[1].correlation)

    def undo(self) -> None:
        what = self.editor.undo()
        self.tell(tr("Undone: {what}").format(what=what) if what else tr("Nothing to undo"))
        self.redraw()

    def delete_selected(self) -> None:
        self.tell(tr("Point deleted (Ctrl+Z brings it back)") if self.editor.delete_selected()
                  else tr("Select a point in the table first"))
        self.redraw()

    def _edit(self, **change) -> None:
        self._run(lambda: self.editor.edit(**change), "")

    def _edit_id(self) -> None:
        if self.editor.selected is not None and self.id_edit.text().strip() != self.editor.current().id:
            self._edit(point_id=self.id_edit.text())

    def _edit_sigmas(self) -> None:
        if self.editor.selected is None:
            return
        point, change = self.editor.current(), {}
        if point.ground is not None:
            change.update(sigma_xy=self.sigma_xy_spin.value(), sigma_z=self.sigma_z_spin.value())
        if self.current is not None and point.observation(self.view().scene_name, self.view().camera_name):
            change["sigma_px"] = (self.view().scene_name, self.view().camera_name, self.sigma_px_spin.value())
        self._edit(**change)

    def _run(self, call, message: str) -> bool:
        """Call ``call`` (an editor change), then show ``message`` or its refusal, and redraw."""
        try:
            call()
        except PushbroomError as exc:
            self.tell(str(exc))
            return False
        if message:
            self.tell(message)
        self.redraw()
        return True

    def select_point(self, index: int | None) -> None:
        """Select point ``index`` (of the editor's list), draw it and zoom to it."""
        if index is not None and not 0 <= index < len(self.editor.points):
            return
        self.editor.select(index)
        self.redraw()
        if self.selected_pixels():
            self.zoom_to_selected()

    def selected_pixels(self) -> list[tuple[float, float]]:
        """The selected point in the scene shown: its measurement, else where it is predicted."""
        if self.editor.selected is None or self.current is None:
            return []
        view = self.views[self.current]
        seen = self.editor.current().observation(view.scene_name, view.camera_name)
        if seen is not None:
            return [(seen.col, seen.row)]
        at = [(p.col, p.row) for p in self.predictions if np.isfinite(p.col) and np.isfinite(p.row)]
        return [tuple(np.mean(at, axis=0))] if at else []

    # --- files ----------------------------------------------------------------------------------
    def _choose_save(self) -> None:
        path, _ = QFileDialog.getSaveFileName(self, tr("Save GCPs"), "", "GeoPackage (*.gpkg)")
        if path:
            self.save(path)

    def inputs(self) -> dict:
        """{what: files} the dock reads: a save must not replace any of them."""
        files = {}
        for view, (opened, source) in zip(self.views, self.sources):
            displays = [str(source.display)] + [opened] * (opened not in (source.scene_path, str(source.image)))
            for what, paths in (("scene file", [source.scene_path]), ("display copy", displays),
                                ("raw image", [str(source.image)])):
                files[f"{view.label} ({what})"] = paths
        dem = self.dem_combo.currentLayer()
        return {**files, "DEM": [layer_path(dem)] if dem is not None else []}

    def save(self, path: str) -> bool:
        """Write the points to GeoPackage ``path`` (layer gcps, replaced whole, or not at all);
        False (with the reason shown) when they cannot be saved."""
        try:
            check_outputs(self.inputs(), {tr("GCP layer"): [path]})
            table = self.editor.table()
            write_gpkg(table, path)
        except PushbroomError as exc:
            self.tell(str(exc))
            return False
        self.tell(tr("{n} observations of {p} points saved to {path}").format(n=len(table), p=len(self.editor.points),
                                                                            path=path))
        return True

    def _choose_open(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, tr("Open GCPs (saved here, or adjusted by bundleadjust)"), "",
                                              "GeoPackage (*.gpkg)")
        if path:
            self.open_layer(path)

    def open_layer(self, path: str) -> bool:
        """Continue from a saved GCP layer, or bundleadjust's adjusted GCPs (OUTPUT_GCPS: their
        residuals shown in the table); its scenes must be in the dock (those that are not are
        named); False (with the reason shown) when it cannot be read."""
        try:
            self.editor.load(read_gpkg(path), list(dict.fromkeys(v.scene_name for v in self.views)), path,
                             tr("the layer {name}").format(name=Path(path).name))
        except PushbroomError as exc:
            self.tell(str(exc))
            return False
        with_residuals = sum(o.residual is not None for p in self.editor.points for o in p.observations)
        self.tell(tr("{n} points read from {path}").format(n=len(self.editor.points), path=path)
                  + (tr(", {k} observations with their residuals").format(k=with_residuals) if with_residuals else ""))
        self.redraw()
        return True

    # --- drawing ----------------------------------------------------------------------------------
    def redraw(self) -> None:
        """Markers (the image's, the main map's), predictions and the table from the editor's state."""
        self.drawing.clear()
        self.predictions = []
        view = self.views[self.current] if self.current is not None else None
        if view is not None:
            if self.editor.selected is not None:
                self._draw_predictions(view)
            for i, point in enumerate(self.editor.points):
                seen = point.observation(view.scene_name, view.camera_name)
                if seen is not None:
                    self.drawing.marker(point_of(seen.col, seen.row),
                                        "selected" if i == self.editor.selected else "measured", point.id)
        self.main_markers.show(self.editor.points, self.editor.selected)
        self._fill_form(view)

    def _draw_predictions(self, view: View) -> None:
        point = self.editor.current()
        try:
            self.predictions = predict(point, view, {v.scene_name: v for v in self.views},
                                       surface_for(self.heights()[0], view))
        except PushbroomError as exc:
            self.tell(str(exc))
            return
        shown = [p for p in self.predictions if np.isfinite(p.col) and np.isfinite(p.row)]
        for k, p in enumerate(shown):
            # estimates within a pixel of an earlier one share its label, which names them all
            near = [q.source for q in shown if abs(q.col - p.col) < 1.0 and abs(q.row - p.row) < 1.0]
            first = next(i for i, q in enumerate(shown) if q.source == near[0])
            self.drawing.marker(point_of(p.col, p.row), "ground" if p.source == "ground" else "scene",
                                f"{point.id} ({', '.join(near)})" if first == k else "")

    def _fill_form(self, view: View | None) -> None:
        self.table.fill(self.editor.points, self.editor.selected, view.scene_name if view else None,
                        view.camera_name if view else None)
        if self.editor.selected is None:
            return
        point = self.editor.current()
        self.id_edit.setText(point.id)
        self.role_combo.setCurrentText(point.role)
        if point.ground is not None:
            self.sigma_xy_spin.setValue(point.ground.sigma_xy)
            self.sigma_z_spin.setValue(point.ground.sigma_z)
        seen = point.observation(view.scene_name, view.camera_name) if view is not None else None
        if seen is not None:
            self.sigma_px_spin.setValue(seen.sigma_px)

    def closeEvent(self, event):  # noqa: N802 (Qt API name)
        self.main_markers.hide()  # back when the dock is shown again
        super().closeEvent(event)

    def showEvent(self, event):  # noqa: N802 (Qt API name)
        super().showEvent(event)
        self.main_markers.show(self.editor.points, self.editor.selected)

    def dispose(self) -> None:
        """Also take the markers off the main map canvas."""
        self.main_markers.dispose()
        super().dispose()
