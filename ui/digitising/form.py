"""The docks' form pieces: a DEM box that starts empty and offers only rasters that look like
elevation (:func:`core.measure.sources.elevation_problem`: a wrong DEM gives every point a wrong height
without a word), labelled spin boxes and rows.
"""
from __future__ import annotations

from qgis.core import QgsMapLayerProxyModel, QgsProject, QgsRasterLayer
from qgis.gui import QgsMapLayerComboBox
from qgis.PyQt.QtWidgets import QDoubleSpinBox, QHBoxLayout, QLabel, QWidget

from ...core.measure.sources import elevation_problem
from ..parameters import tr


def layer_path(layer) -> str:
    """The file behind a layer (its source less any '|layername=' part)."""
    return layer.source().split("|")[0]


def not_elevation(layer) -> str:
    """Why ``layer`` is not offered as a DEM ('' when it is)."""
    if not isinstance(layer, QgsRasterLayer):
        return tr("not a raster")
    if layer.providerType() != "gdal":
        return tr("not a file ({provider})").format(provider=layer.providerType())
    return elevation_problem(layer_path(layer))


class DemBox(QgsMapLayerComboBox):
    """A raster layer box that starts empty and offers only the project's rasters that look like
    elevation; its tool tip names the others and why they are left out."""

    def __init__(self):
        super().__init__()
        self.setFilters(QgsMapLayerProxyModel.RasterLayer)
        self.setAllowEmptyLayer(True)
        self.problems: dict[str, str] = {}  # layer id -> why not (checked once: GDAL opens each file)
        self.refilter()
        self.setLayer(None)
        QgsProject.instance().layersAdded.connect(self.refilter)

    def refilter(self, *args) -> None:
        """Leave out the project's rasters that are no DEM (called as layers are added)."""
        layers = [lyr for lyr in QgsProject.instance().mapLayers().values() if isinstance(lyr, QgsRasterLayer)]
        for layer in layers:
            if layer.id() not in self.problems:
                self.problems[layer.id()] = not_elevation(layer)
        left_out = [lyr for lyr in layers if self.problems[lyr.id()]]
        self.setExceptedLayerList(left_out)
        notes = "".join(f"\n- {lyr.name()}: {self.problems[lyr.id()]}" for lyr in left_out)
        self.setToolTip(tr("A DEM: a raster of one band of floating point or 16-bit heights. Empty: the constant "
                           "height below.") + (tr("\nNot offered:") + notes if notes else ""))

    def dispose(self) -> None:
        try:
            QgsProject.instance().layersAdded.disconnect(self.refilter)
        except TypeError:  # disconnected already
            pass


def spin_box(value: float, low: float, high: float, suffix: str, tooltip: str, decimals: int = 2) -> QDoubleSpinBox:
    spin = QDoubleSpinBox()
    spin.setRange(low, high)
    spin.setDecimals(decimals)
    spin.setValue(value)
    spin.setSuffix(suffix)
    spin.setToolTip(tooltip)
    return spin


def labelled_row(*pairs) -> QWidget:
    """A row of (label text, widget) pairs, each widget after its label."""
    row = QWidget()
    layout = QHBoxLayout(row)
    layout.setContentsMargins(0, 0, 0, 0)
    for text, widget in pairs:
        if text:
            layout.addWidget(QLabel(text))
        layout.addWidget(widget, 1)
    return row
