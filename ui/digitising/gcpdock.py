"""The dock 'Measure GCPs on the raw images': points clicked on the raw images of a block, their ground on
the map; predictions, Snap, Save, Open, the table. The session and its rules: :mod:`core.runs.measuregcps`."""
from __future__ import annotations

from qgis.core import QgsCoordinateTransform, QgsMapLayerProxyModel, QgsProject
from qgis.PyQt.QtCore import Qt
from qgis.PyQt.QtWidgets import (QAbstractItemView, QHeaderView, QLineEdit, QListWidget, QTableWidget,
                                 QTableWidgetItem)

from ...core.measure.sources import open_image_source
from ...core.observations.gcps import ROLES
from ...core.runs.measuregcps import GcpSession, nearest_reference, point_rows
from ..inputs import block_scene_names
from ..parameters import tr
from .base import PixelCanvasDock
from .canvas import point_of
from .form import (ask_gpkg, ask_scene, cache_folder, combo, labelled_row, layer_box, layer_parts, layer_path,
                   spin_box, wgs84)
from .markers import MainMapMarkers, legend

SNAP_TARGETS = ("other scene", "reference orthoimage")
REFERENCE_TOLERANCE_PX = 20  # screen px: a click farther from every reference point takes none of them
COLUMNS = ("Id", "Role", "Images", "Residual (px)", "h (m)", "Height from")
SORT_KEY = Qt.UserRole + 1


class GcpDock(PixelCanvasDock):
    """The dock. ``iface``: the QGIS interface (its mapCanvas() is where ground positions are picked)."""

    def __init__(self, iface, parent=None):
        super().__init__(tr("Measure GCPs on the raw images"), "PushbroomGcpDock", iface,
                         tr("Add scene… to start: a scene file and its raw image, for each scene of the block"), parent)
        self.session = GcpSession()
        self.editor = self.session.editor
        self.main_markers = MainMapMarkers(iface.mapCanvas())
        form = self.form
        self.scene_list = QListWidget(maximumHeight=80, currentRowChanged=self.show_scene)
        form.addRow(tr("Scenes"), self.scene_list)
        self.id_edit, self.role_combo = QLineEdit(), combo(ROLES)
        self.id_edit.editingFinished.connect(lambda: self.attempt(lambda: self.session.rename(self.id_edit.text())))
        self.role_combo.activated.connect(lambda _: self.attempt(lambda: self.editor.edit(
            role=self.role_combo.currentText())))
        form.addRow(tr("Point"), labelled_row((tr("id"), self.id_edit), (tr("role"), self.role_combo)))
        self.sigma_px_spin = spin_box(0.5, 0.01, 1000.0, " px", tr("image sigma of the point in the scene shown"))
        self.sigma_xy_spin = spin_box(1.0, 0.0, 1000.0, " m", tr("ground sigma in plan"))
        self.sigma_z_spin = spin_box(1.0, 0.0, 1000.0, " m", tr("ground sigma in height"))
        for spin in (self.sigma_px_spin, self.sigma_xy_spin, self.sigma_z_spin):
            spin.editingFinished.connect(lambda: self.attempt(lambda: self.session.edit_sigmas(
                self.sigma_xy_spin.value(), self.sigma_z_spin.value(), self.sigma_px_spin.value())))
        form.addRow(tr("Sigmas"), labelled_row((tr("image"), self.sigma_px_spin), (tr("plan"), self.sigma_xy_spin),
                                               (tr("height"), self.sigma_z_spin)))
        self.reference_combo = layer_box(QgsMapLayerProxyModel.PointLayer)
        form.addRow(tr("Reference points"), self.reference_combo)
        self.add_height_rows(tr("Heights of the ground positions: z = the reference point's Z, dem = the DEM below "
                                "(the constant when none is chosen), constant = the height below; also the surface "
                                "observations are projected on"), tr("the reference point's Z"), "dem")
        self.snap_combo, self.ortho_combo = combo(SNAP_TARGETS), layer_box(QgsMapLayerProxyModel.RasterLayer)
        form.addRow(tr("Snap to"), labelled_row(("", self.snap_combo), (tr("orthoimage"), self.ortho_combo)))
        self.table = PointTable(self.select_point)
        self.build(((("add_scene_button", tr("Add scene…"),
                      lambda: ask_scene(self, tr("Add a scene of the block"), self.add_scene)),
                     ("new_button", tr("New point"), lambda: self.attempt(self.session.new_point)),
                     ("ground_button", tr("Ground"), lambda: self.start_picking(
                         tr("Click the point on the map (the nearest reference point is taken when a reference layer "
                            "is chosen)"), tr("Select a point first (in the table), then press Ground"))),
                     ("snap_button", tr("Snap"), self.snap)),
                    (("open_button", tr("Open…"), lambda: ask_gpkg(
                        self, tr("Open GCPs (saved here, or adjusted by bundleadjust)"), self.open_layer, False)),
                     ("save_button", tr("Save…"), lambda: ask_gpkg(self, tr("Save GCPs"), self.save)))),
                   (tr("Measure: a click measures the selected point (a new one when none is)"),
                    "/mActionCapturePoint.svg"),
                   legend(("selected", "measured", "ground", "scene")), self.table)

    predictions = property(lambda self: self.session.predictions)

    def add_scene(self, path: str, image: str | None = None, camera: str | None = None) -> bool:
        """Add a scene named as the block's algorithms name it, and show it; False (said) when it cannot."""
        if not self.attempt(lambda: self.session.add(str(path), open_image_source(path, cache_folder(), image, camera),
                                                     block_scene_names), redraw=False):
            return False
        self.scene_list.addItem(self.session.views[-1].label)
        self.scene_list.setCurrentRow(len(self.session.views) - 1)
        return True

    def show_scene(self, index: int) -> None:
        """Show the image of the block's scene ``index`` (its display copy)."""
        def show() -> None:
            self.show_raster(str(self.session.sources[index][1].display), self.session.views[index].label)
            self.session.current = index
        if 0 <= index < len(self.session.views):
            self.attempt(show)

    def image_clicked(self, col: float, row: float, button) -> None:
        """Left click measures the selected point in the current scene (a new point when none is)."""
        if button == Qt.LeftButton:
            self.attempt(lambda: self.session.measure(col, row))

    def main_clicked(self, point) -> None:
        """The selected point's ground at a click on the main map, its height as the form says."""
        self.attempt(lambda: self.session.set_ground(*self.picked(point), *self.heights()))

    def picked(self, point) -> tuple:
        """(lon, lat, z, source) of a click at ``point``: it, or the nearest reference point near it."""
        canvas, layer = self.iface.mapCanvas(), self.reference_combo.currentLayer()
        crs = canvas.mapSettings().destinationCrs()
        if layer is None:
            at = QgsCoordinateTransform(crs, wgs84(), QgsProject.instance()).transform(point)
            return at.x(), at.y(), None, "canvas"
        here, there = (layer_parts(layer, to)[1] for to in (crs, wgs84()))
        return (*nearest_reference(layer.name(), [p[0] for p in here], [p[0] for p in there], (point.x(), point.y()),
                                   canvas.mapUnitsPerPixel(), REFERENCE_TOLERANCE_PX), "reference")

    def snap(self) -> None:
        """Snap the selected point's observation in the current scene (undoable)."""
        ortho = self.ortho_combo.currentLayer()
        self.attempt(lambda: self.session.snap(self.heights()[0], self.snap_combo.currentText() == SNAP_TARGETS[1],
                                               (layer_path(ortho), ortho.name()) if ortho is not None else None))

    def select_point(self, index: int | None) -> None:
        """Select point ``index`` (of the editor's list), draw it and zoom to it."""
        if index is None or 0 <= index < len(self.editor.points):
            self.editor.select(index)
            self.redraw()
            if self.session.selected_pixels():
                self.zoom_to_selected()

    def save(self, path: str) -> bool:
        """Write the points to GeoPackage ``path``; False (said) when they cannot be saved."""
        dem = self.dem_combo.currentLayer()
        return self.attempt(lambda: self.session.save(path, layer_path(dem) if dem is not None else None), False)

    def open_layer(self, path: str) -> bool:
        """Continue from a saved or adjusted GCP layer; False (said) when it cannot be read."""
        return self.attempt(lambda: self.session.open_layer(path))

    def redraw(self) -> None:
        """Markers (the image's, the main map's), the table and the form from the session."""
        self.drawing.clear()
        markers, problem = self.session.markers(self.heights()[0])
        if problem:
            self.tell(problem)
        for col, row, kind, label in markers:
            self.drawing.marker(point_of(col, row), kind, label)
        self.main_markers.show(self.session.ground_marks())
        self.table.fill(self.editor.points, self.editor.selected, *self.session.shown())
        values = self.session.selected_values()
        if values is not None:
            self.id_edit.setText(values[0])
            self.role_combo.setCurrentText(values[1])
            for spin, value in zip((self.sigma_xy_spin, self.sigma_z_spin, self.sigma_px_spin), values[2:]):
                if value is not None:
                    spin.setValue(value)

    def closeEvent(self, event):  # noqa: N802 (Qt API name)
        self.main_markers.hide()  # back when the dock is shown again
        super().closeEvent(event)

    def showEvent(self, event):  # noqa: N802 (Qt API name)
        super().showEvent(event)
        self.main_markers.show(self.session.ground_marks())

    def dispose(self) -> None:
        """Also take the markers off the main map canvas."""
        self.main_markers.dispose()
        super().dispose()


class Cell(QTableWidgetItem):
    """A read-only cell showing ``text`` that sorts by ``key`` (numbers as numbers), else by its text."""

    def __init__(self, text: str, key=None):
        super().__init__(text)
        self.setData(SORT_KEY, key)
        self.setFlags(self.flags() & ~Qt.ItemIsEditable)

    def __lt__(self, other):
        mine, theirs = self.data(SORT_KEY), other.data(SORT_KEY)
        return mine < theirs if mine is not None and theirs is not None else self.text() < other.text()


class PointTable(QTableWidget):
    """The points as the Georeferencer's GCP table, sortable; ``on_select(index)`` on a click."""

    def __init__(self, on_select):
        super().__init__(0, len(COLUMNS), selectionBehavior=QAbstractItemView.SelectRows,
                         selectionMode=QAbstractItemView.SingleSelection)
        self.setHorizontalHeaderLabels([tr(c) for c in COLUMNS])
        self.verticalHeader().hide()
        self.horizontalHeader().setSectionResizeMode(QHeaderView.ResizeToContents)
        self.horizontalHeader().setStretchLastSection(True)
        self.setSortingEnabled(True)
        self.sortByColumn(0, Qt.AscendingOrder)
        self.on_select = on_select
        self.itemSelectionChanged.connect(self._selected)  # keys move the selection too
        self.clicked.connect(self._selected)  # a click on the selected row zooms to it again

    def fill(self, points, selected: int | None, scene: str | None, camera: str | None) -> None:
        """One row per point, its index in ``points`` kept with the row; residuals in ``scene``'s ``camera``."""
        self.blockSignals(True)
        self.setSortingEnabled(False)
        self.setRowCount(len(points))
        for row, (cells, tip) in enumerate(point_rows(points, scene, camera)):
            for column, (text, key) in enumerate(cells):
                self.setItem(row, column, Cell(text, key))
            self.item(row, 0).setData(Qt.UserRole, row)
            self.item(row, 0).setToolTip(tip)
        self.setSortingEnabled(True)
        self.clearSelection()
        for row in range(self.rowCount()):
            if selected is not None and self.item(row, 0).data(Qt.UserRole) == selected:
                self.selectRow(row)
        self.blockSignals(False)

    def _selected(self, *args) -> None:
        rows = self.selectionModel().selectedRows()
        if rows:
            self.on_select(self.item(rows[0].row(), 0).data(Qt.UserRole))
