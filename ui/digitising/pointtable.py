"""The GCP dock's table of points, as the Georeferencer's GCP table (rows from
:func:`core.runs.measuregcps.point_rows`): sortable by any column; a click selects the point."""
from __future__ import annotations

from qgis.PyQt.QtCore import Qt
from qgis.PyQt.QtWidgets import QAbstractItemView, QHeaderView, QTableWidget, QTableWidgetItem

from ...core.runs.measuregcps import point_rows
from ..parameters import tr

COLUMNS = ("Id", "Role", "Images", "Residual (px)", "h (m)", "Height from")
SORT_KEY = Qt.UserRole + 1


class Cell(QTableWidgetItem):
    """A read-only cell showing ``value`` that sorts by ``sort_key`` (numbers as numbers) when
    given, else by its text."""

    def __init__(self, value, sort_key=None):
        super().__init__(str(value))
        self.setData(SORT_KEY, sort_key)
        self.setFlags(self.flags() & ~Qt.ItemIsEditable)

    def __lt__(self, other):
        mine, theirs = self.data(SORT_KEY), other.data(SORT_KEY)
        return mine < theirs if mine is not None and theirs is not None else self.text() < other.text()


class PointTable(QTableWidget):
    """The table; ``on_select(index)`` gets the index (in the editor's list) of a clicked point."""

    def __init__(self, on_select):
        super().__init__(0, len(COLUMNS))
        self.setHorizontalHeaderLabels([tr(c) for c in COLUMNS])
        self.setSelectionBehavior(QAbstractItemView.SelectRows)
        self.setSelectionMode(QAbstractItemView.SingleSelection)
        self.verticalHeader().hide()
        self.horizontalHeader().setSectionResizeMode(QHeaderView.ResizeToContents)
        self.horizontalHeader().setStretchLastSection(True)
        self.setSortingEnabled(True)
        self.sortByColumn(0, Qt.AscendingOrder)
        self.on_select = on_select
        self.itemSelectionChanged.connect(self._selected)  # keys move the selection too
        self.clicked.connect(self._selected)  # a click on the selected row zooms to it again

    def fill(self, points, selected: int | None, scene: str | None, camera: str | None) -> None:
        """One row per point (its index in ``points`` kept with the row); the residual is the one
        of its observation in ``scene``'s ``camera`` (the scene shown), blank without one."""
        self.blockSignals(True)
        self.setSortingEnabled(False)
        self.setRowCount(len(points))
        for row, (cells, tip) in enumerate(point_rows(points, scene, camera)):
            items = [Cell(text, key) for text, key in cells]
            items[0].setData(Qt.UserRole, row)
            items[0].setToolTip(tip)
            for column, item in enumerate(items):
                self.setItem(row, column, item)
        self.setSortingEnabled(True)
        self.clearSelection()
        if selected is not None:
            for row in range(self.rowCount()):
                if self.item(row, 0).data(Qt.UserRole) == selected:
                    self.selectRow(row)
        self.blockSignals(False)

    def _selected(self, *args) -> None:
        rows = self.selectionModel().selectedRows()
        if rows:
            self.on_select(self.item(rows[0].row(), 0).data(Qt.UserRole))
