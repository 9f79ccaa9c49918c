"""The dock 'Measure GCPs on the raw images': the scenes of a block (each added by its display copy,
pushbroom:preparedigitising, which names its scene file and camera), the raw image of the current
scene on the dock's canvas in the pixel frame x = col, y = -row; a click measures the selected
point there, a click on the main map canvas (or the nearest point of a reference layer) gives its
ground; where the selected point should be in the current image is drawn, a marker per estimate
(its ground, and its observation in each other scene, through the scenes' current models); Snap
refines the observation by least-squares template matching against another scene's image or a
reference orthoimage; Undo; Save to a GCP GeoPackage; Open a saved one.

The logic lives in :mod:`core.measure.gcpmeasure`; this module turns events into its calls and
draws its state. The canvas, map tool, main-canvas picking and heights form are :mod:`.base`'s.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from qgis.core import (QgsCoordinateReferenceSystem, QgsCoordinateTransform, QgsGeometry, QgsMapLayerProxyModel,
                       QgsPointXY, QgsProcessingException, QgsProject, QgsWkbTypes)
from qgis.gui import QgsMapLayerComboBox, QgsRubberBand, QgsVertexMarker
from qgis.PyQt.QtCore import Qt
from qgis.PyQt.QtGui import QColor
from qgis.PyQt.QtWidgets import (QComboBox, QDoubleSpinBox, QFileDialog, QHBoxLayout, QLineEdit, QListWidget)

from ...core.errors import PushbroomError
from ...core.files import check_outputs
from ...core.formats import load_scene
from ...core.measure.display import check_image_size, read_display_source
from ...core.measure.gcpmeasure import PointEditor, predict, snap_to_reference, snap_to_scene, surface_for
from ...core.measure.tiematching import View
from ...core.observations.gcps import ROLES, read_gpkg, write_gpkg
from ..inputs import block_scene_names
from ..parameters import tr
from .base import PixelCanvasDock, point_of

MEASURED_COLOUR, OTHER_COLOUR, PREDICTED_COLOUR = QColor(255, 60, 60), QColor(0, 200, 255), QColor(255, 0, 255)
SNAP_TARGETS = ("other scene", "reference orthoimage")
REFERENCE_TOLERANCE_PX = 20  # screen px: a click farther from every reference point takes none of them


def wgs84() -> QgsCoordinateReferenceSystem:
    """EPSG:4326, made when needed (not at import, before QGIS has its CRS database)."""
    return QgsCoordinateReferenceSystem("EPSG:4326")


class GcpDock(PixelCanvasDock):
    """The dock. ``iface``: the QGIS interface (its mapCanvas() is where ground positions are picked)."""

    def __init__(self, iface, parent=None):
        super().__init__(tr("Measure GCPs on the raw images"), "PushbroomGcpDock", iface, parent)
        self.editor = PointEditor()
        self.views: list[View] = []       # the block's images, in the scene list's order
        self.sources: list[tuple[str, str]] = []  # (scene file, display copy) of each
        self.current: int | None = None   # index of the image shown
        self.predictions = []
        self.ground_marker = QgsVertexMarker(iface.mapCanvas())
        self.ground_marker.setColor(MEASURED_COLOUR)
        self.ground_marker.setIconType(QgsVertexMarker.ICON_X)
        self.ground_marker.setIconSize(14)
        self.ground_marker.setPenWidth(2)
        self.ground_marker.hide()
        self._build()

    # --- widgets -------------------------------------------------------------------------------
    def _build(self) -> None:
        form = self.form
        self.scene_list = QListWidget()
        self.scene_list.setMaximumHeight(90)
        self.scene_list.currentRowChanged.connect(self.show_scene)
        form.addRow(tr("Scenes"), self.scene_list)
        self.id_edit = QLineEdit()
        self.id_edit.editingFinished.connect(self._edit_id)
        self.role_combo = QComboBox()
        self.role_combo.addItems(ROLES)
        self.role_combo.activated.connect(lambda _: self._edit(role=self.role_combo.currentText()))
        ident = QHBoxLayout()
        ident.addWidget(self.id_edit)
        ident.addWidget(self.role_combo)
        form.addRow(tr("Point id, role"), ident)
        sigmas = QHBoxLayout()
        for attr, tip, value, low in (("sigma_px_spin", tr("image sigma (px) of the point in the current scene"), 0.5,
                                       0.01),
                                      ("sigma_xy_spin", tr("ground sigma across (m)"), 1.0, 0.0),
                                      ("sigma_z_spin", tr("ground sigma in height (m)"), 1.0, 0.0)):
            spin = QDoubleSpinBox()
            spin.setRange(low, 1000.0)
            spin.setDecimals(2)
            spin.setValue(value)
            spin.setToolTip(tip)
            spin.editingFinished.connect(self._edit_sigmas)
            setattr(self, attr, spin)
            sigmas.addWidget(spin)
        form.addRow(tr("Sigmas px, xy m, z m"), sigmas)
        self.reference_combo = QgsMapLayerComboBox()
        self.reference_combo.setFilters(QgsMapLayerProxyModel.PointLayer)
        self.reference_combo.setAllowEmptyLayer(True)
        self.reference_combo.setLayer(None)
        form.addRow(tr("Reference points"), self.reference_combo)
        self.add_height_rows(tr("Heights of the ground positions: z = the reference point's Z, dem = the DEM below, "
                                "constant = the height below (also the surface observations are projected on)"))
        self.height_combo.setCurrentText("dem")
        self.snap_combo = QComboBox()
        self.snap_combo.addItems(SNAP_TARGETS)
        self.ortho_combo = QgsMapLayerComboBox()
        self.ortho_combo.setFilters(QgsMapLayerProxyModel.RasterLayer)
        self.ortho_combo.setAllowEmptyLayer(True)
        self.ortho_combo.setLayer(None)
        snapping = QHBoxLayout()
        snapping.addWidget(self.snap_combo)
        snapping.addWidget(self.ortho_combo)
        form.addRow(tr("Snap to"), snapping)
        rows = (("add_scene_button", tr("Add scene…"), self._choose_scene),
                ("new_button", tr("New point"), self.new_point),
                ("ground_button", tr("Ground"), self.start_ground),
                ("snap_button", tr("Snap"), self.snap),
                ("undo_button", tr("Undo"), self.undo),
                ("delete_button", tr("Delete"), self.delete_selected),
                ("open_button", tr("Open…"), self._choose_open),
                ("save_button", tr("Save…"), self._choose_save))
        self.add_buttons(rows[:4], rows[4:])
        self.point_list = self.finish_with_list(self._list_selected)

    # --- the block's scenes ---------------------------------------------------------------------
    def _choose_scene(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, tr("Display copy of a scene"), "",
                                              "Virtual raster (*.vrt);;All files (*)")
        if path:
            self.add_scene(path)

    def add_scene(self, display: str) -> bool:
        """Add the scene a display copy shows (its scene file and camera, named as the block's
        algorithms name it) and show it; False (with the reason shown) when it cannot be used."""
        try:
            source = read_display_source(display)
            if not source.scene:
                raise PushbroomError(tr("{path}: names no scene file; make it with Prepare raw image for "
                                        "digitising (pushbroom:preparedigitising)").format(path=display))
            scene = load_scene(source.scene)
            camera = scene.camera_index(source.camera or 0)
            check_image_size(source.image, scene.cameras[camera].cols, scene.cameras[camera].rows,
                             scene.cameras[camera].name)
            scene_files = list(dict.fromkeys([s for s, _ in self.sources] + [source.scene]))
            name = block_scene_names(scene_files)[scene_files.index(source.scene)]
        except (PushbroomError, QgsProcessingException) as exc:
            self.tell(str(exc))
            return False
        view = View(name, scene, camera, Path(source.image))
        if any(v.label == view.label for v in self.views):
            self.tell(tr("{label} is in the block already").format(label=view.label))
            return False
        self.views.append(view)
        self.sources.append((source.scene, display))
        self.scene_list.addItem(view.label)
        self.scene_list.setCurrentRow(len(self.views) - 1)
        return True

    def show_scene(self, index: int) -> None:
        """Show the image of the block's scene ``index`` (its display copy)."""
        if not 0 <= index < len(self.views):
            return
        if self.show_raster(self.sources[index][1], self.views[index].label):
            self.current = index
            self.redraw()

    def view(self) -> View:
        if self.current is None:
            raise PushbroomError(tr("add a scene of the block first (Add scene…: its display copy)"))
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
            self.tell(tr("Select a point first (in the list), then press Ground"))
            return
        self.start_picking(tr("Click the point on the map (the nearest reference point is taken when a reference "
                              "layer is chosen)"))

    def main_clicked(self, point) -> None:
        """The selected point's ground at ``point`` (main canvas CRS), or at the nearest point of the
        reference layer (within REFERENCE_TOLERANCE_PX of the click)."""
        canvas = self.iface.mapCanvas()
        crs = canvas.mapSettings().destinationCrs()
        at = QgsCoordinateTransform(crs, wgs84(), QgsProject.instance()).transform(point)
        lon, lat, z, source = at.x(), at.y(), None, "canvas"
        layer = self.reference_combo.currentLayer()
        if layer is not None:
            found = self._nearest_reference(layer, point, crs)
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
        try:
            ground = self.editor.set_ground_at(lon, lat, self.heights(), z, source)
        except PushbroomError as exc:
            self.tell(str(exc))
            return
        self.tell(tr("Point {id}: ground lon {lon:.6f}, lat {lat:.6f}, h {h:.1f} m (ellipsoidal) from the "
                     "{src}").format(id=self.editor.current().id, lon=ground.lon, lat=ground.lat, h=ground.h,
                                     src=source))
        self.redraw()

    @staticmethod
    def _nearest_reference(layer, click, crs):
        """(lon, lat deg, z or None, distance in ``crs`` units) of the point of ``layer`` nearest to
        ``click`` (in ``crs``, the main canvas's); None without points."""
        to_canvas = QgsCoordinateTransform(layer.crs(), crs, QgsProject.instance())
        to_wgs84 = QgsCoordinateTransform(layer.crs(), wgs84(), QgsProject.instance())
        points = []
        for feature in layer.getFeatures():
            geometry = QgsGeometry(feature.geometry())
            if not geometry.isEmpty():
                vertex = geometry.vertexAt(0)
                there = to_canvas.transform(QgsPointXY(vertex.x(), vertex.y()))
                points.append((there.x(), there.y(), vertex.x(), vertex.y(), vertex.z()))
        if not points:
            return None
        xy = np.array(points)
        distance = np.hypot(xy[:, 0] - click.x(), xy[:, 1] - click.y())
        k = int(np.argmin(distance))
        lonlat = to_wgs84.transform(QgsPointXY(xy[k, 2], xy[k, 3]))
        has_z = QgsWkbTypes.hasZ(layer.wkbType()) and np.isfinite(xy[k, 4])
        return lonlat.x(), lonlat.y(), float(xy[k, 4]) if has_z else None, float(distance[k])

    def snap(self) -> None:
        """Snap the selected point's observation in the current scene (undoable)."""
        try:
            view, point = self.view(), self.editor.current()
            surface = surface_for(self.heights(), view)
            if self.snap_combo.currentText() == SNAP_TARGETS[1]:
                ortho = self.ortho_combo.currentLayer()
                if ortho is None:
                    raise PushbroomError(tr("choose the reference orthoimage layer to snap to"))
                result = snap_to_reference(point, view, ortho.source().split("|")[0], surface)
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
        self.tell(tr("Point deleted") if self.editor.delete_selected() else tr("Select a point in the list first"))
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

    def _list_selected(self, row: int) -> None:
        if 0 <= row < len(self.editor.points) and self.editor.selected != row:
            self.editor.select(row)
            self.redraw()

    # --- files ----------------------------------------------------------------------------------
    def _choose_save(self) -> None:
        path, _ = QFileDialog.getSaveFileName(self, tr("Save GCPs"), "", "GeoPackage (*.gpkg)")
        if path:
            self.save(path)

    def inputs(self) -> dict:
        """{what: files} the dock reads: a save must not replace any of them."""
        files = {f"{v.label} ({what})": [path] for v, (scene, display) in zip(self.views, self.sources)
                 for what, path in (("scene file", scene), ("display copy", display), ("raw image", str(v.image)))}
        dem = self.dem_combo.currentLayer()
        return {**files, "DEM": [dem.source().split("|")[0]] if dem is not None else []}

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
        path, _ = QFileDialog.getOpenFileName(self, tr("Open GCPs"), "", "GeoPackage (*.gpkg)")
        if path:
            self.open_layer(path)

    def open_layer(self, path: str) -> bool:
        """Continue from a saved GCP layer (its scenes must be in the dock); False (with the reason
        shown) when it cannot be read."""
        try:
            self.editor.load(read_gpkg(path), list(dict.fromkeys(v.scene_name for v in self.views)), path)
        except PushbroomError as exc:
            self.tell(str(exc))
            return False
        self.tell(tr("{n} points read from {path}").format(n=len(self.editor.points), path=path))
        self.redraw()
        return True

    # --- drawing ----------------------------------------------------------------------------------
    def _marker(self, col: float, row: float, colour: QColor, icon) -> None:
        self.add_band(QgsGeometry.fromPointXY(point_of(col, row)), QgsWkbTypes.PointGeometry, colour, 2, icon=icon)

    def redraw(self) -> None:
        """Markers, predictions and the lists from the editor's state."""
        self.clear_bands()
        self.predictions = []
        view = self.views[self.current] if self.current is not None else None
        self._mark_ground()
        if view is not None:
            for i, point in enumerate(self.editor.points):
                seen = point.observation(view.scene_name, view.camera_name)
                if seen is not None:
                    self._marker(seen.col, seen.row, MEASURED_COLOUR if i == self.editor.selected else OTHER_COLOUR,
                                 QgsRubberBand.ICON_CROSS)
            if self.editor.selected is not None:
                self._draw_predictions(view)
        self._fill_list()

    def _mark_ground(self) -> None:
        """The selected point's ground position marked on the main map canvas (hidden without one)."""
        ground = self.editor.current().ground if self.editor.selected is not None else None
        if ground is None:
            self.ground_marker.hide()
            return
        crs = self.iface.mapCanvas().mapSettings().destinationCrs()
        at = QgsCoordinateTransform(wgs84(), crs, QgsProject.instance()).transform(QgsPointXY(ground.lon, ground.lat))
        self.ground_marker.setCenter(at)
        self.ground_marker.show()

    def closeEvent(self, event):  # noqa: N802 (Qt API name)
        self.ground_marker.hide()
        super().closeEvent(event)

    def dispose(self) -> None:
        """Also take the ground marker off the main map canvas."""
        self.iface.mapCanvas().scene().removeItem(self.ground_marker)
        super().dispose()

    def _draw_predictions(self, view: View) -> None:
        try:
            self.predictions = predict(self.editor.current(), view, {v.scene_name: v for v in self.views},
                                       surface_for(self.heights(), view))
        except PushbroomError as exc:
            self.tell(str(exc))
            return
        for p in self.predictions:
            if np.isfinite(p.col) and np.isfinite(p.row):
                self._marker(p.col, p.row, PREDICTED_COLOUR, QgsRubberBand.ICON_CIRCLE)

    def _fill_list(self) -> None:
        self.point_list.blockSignals(True)
        self.point_list.clear()
        for point in self.editor.points:
            ground = point.ground.source if point.ground is not None else tr("no ground")
            self.point_list.addItem(tr("{id} ({role}): {n} images, {ground}").format(
                id=point.id, role=point.role, n=len(point.observations), ground=ground))
        self.point_list.setCurrentRow(-1 if self.editor.selected is None else self.editor.selected)
        self.point_list.blockSignals(False)
        if self.editor.selected is not None:
            point = self.editor.current()
            self.id_edit.setText(point.id)
            self.role_combo.setCurrentText(point.role)
            if point.ground is not None:
                self.sigma_xy_spin.setValue(point.ground.sigma_xy)
                self.sigma_z_spin.setValue(point.ground.sigma_z)
            view = self.views[self.current] if self.current is not None else None
            seen = point.observation(view.scene_name, view.camera_name) if view is not None else None
            if seen is not None:
                self.sigma_px_spin.setValue(seen.sigma_px)
