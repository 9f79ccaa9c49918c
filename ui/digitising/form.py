"""The docks' forms and dialogs: a DEM box offering only rasters that look like elevation (a wrong DEM
gives every point a wrong height without a word), the scene dialog, small widgets, the layers' files
and parts. Display copies live in the plugin's cache, never beside the user's files."""
from __future__ import annotations

from contextlib import suppress
from pathlib import Path

import numpy as np
from qgis.core import (QgsApplication, QgsCoordinateReferenceSystem, QgsCoordinateTransform, QgsGeometry,
                       QgsMapLayerProxyModel, QgsProject, QgsRasterLayer, QgsWkbTypes)
from qgis.gui import QgsFileWidget, QgsMapLayerComboBox
from qgis.PyQt.QtWidgets import (QComboBox, QDialog, QDialogButtonBox, QDoubleSpinBox, QFileDialog, QFormLayout,
                                 QHBoxLayout, QLabel, QWidget)

from ...core.measure.sources import elevation_problem
from ...core.runs.docks import proposed_image, scene_cameras
from ..parameters import tr

SCENE_FILTER = ("Scenes (*.json *.JSON *.xml *.XML *.txt *.TXT *.rpb *.RPB *.tif *.TIF *.tiff *.ntf *.NTF *.vrt);;"
                "All files (*)")
IMAGE_FILTER = "Rasters (*.tif *.TIF *.tiff *.jp2 *.JP2 *.ntf *.NTF *.til *.TIL *.img *.vrt);;All files (*)"


def cache_folder() -> Path:
    """Where the docks keep their display copies: the plugin's folder in the QGIS profile's cache."""
    return Path(QgsApplication.qgisSettingsDirPath()) / "cache" / "pushbroom_adjust" / "display"


def wgs84() -> QgsCoordinateReferenceSystem:
    """EPSG:4326, made when needed (not at import, before QGIS has its CRS database)."""
    return QgsCoordinateReferenceSystem("EPSG:4326")


def layer_path(layer) -> str:
    """The file behind a layer (its source less any '|layername=' part)."""
    return layer.source().split("|")[0]


def layer_parts(layer, crs: QgsCoordinateReferenceSystem, field: str = "") -> tuple[list[str], list[np.ndarray]]:
    """(each part's ``field`` value ('' for none), parts [(n, 3)] x, y in ``crs``, z or NaN) of ``layer``."""
    transform = QgsCoordinateTransform(layer.crs(), crs, QgsProject.instance())
    has_z = QgsWkbTypes.hasZ(layer.wkbType())
    ids, parts = [], []
    for feature in layer.getFeatures():
        geometry = QgsGeometry(feature.geometry())
        if geometry.isEmpty():
            continue
        geometry.transform(transform)
        for part in geometry.constParts():
            parts.append(np.array([(p.x(), p.y(), p.z() if has_z else np.nan) for p in part.vertices()], dtype=float))
            ids.append(str(feature[field]) if field else "")
    return ids, parts


def not_elevation(layer) -> str:
    """Why ``layer`` is not offered as a DEM ('' when it is)."""
    if not isinstance(layer, QgsRasterLayer):
        return tr("not a raster")
    if layer.providerType() != "gdal":
        return tr("not a file ({provider})").format(provider=layer.providerType())
    return elevation_problem(layer_path(layer))


class DemBox(QgsMapLayerComboBox):
    """Starts empty, offers only the project's rasters that look like elevation, says why not the others."""

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
        self.problems.update({lyr.id(): not_elevation(lyr) for lyr in layers if lyr.id() not in self.problems})
        left_out = [lyr for lyr in layers if self.problems[lyr.id()]]
        self.setExceptedLayerList(left_out)
        notes = "".join(f"\n- {lyr.name()}: {self.problems[lyr.id()]}" for lyr in left_out)
        self.setToolTip(tr("A DEM: a raster of one band of floating point or 16-bit heights. Empty: the constant "
                           "height below.") + (tr("\nNot offered:") + notes if notes else ""))

    def dispose(self) -> None:
        with suppress(TypeError):  # disconnected already
            QgsProject.instance().layersAdded.disconnect(self.refilter)


def layer_box(filters) -> QgsMapLayerComboBox:
    """A layer box of ``filters`` that starts empty."""
    box = QgsMapLayerComboBox()
    box.setFilters(filters)
    box.setAllowEmptyLayer(True)
    box.setLayer(None)
    return box


def combo(items, tooltip: str = "", current: str = "") -> QComboBox:
    """A box of ``items`` showing ``current`` (the first when '')."""
    box = QComboBox(toolTip=tooltip)
    box.addItems(items)
    box.setCurrentText(current or items[0])
    return box


def spin_box(value: float, low: float, high: float, suffix: str, tooltip: str) -> QDoubleSpinBox:
    spin = QDoubleSpinBox(suffix=suffix, toolTip=tooltip)
    spin.setRange(low, high)
    spin.setValue(value)
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


class SceneDialog(QDialog):
    """Scene file, camera, raw image (proposed from the scene file's folder): ``chosen()`` after OK."""

    def __init__(self, parent, title: str):
        super().__init__(parent)
        self.setWindowTitle(title)
        self.setMinimumWidth(520)
        form = QFormLayout(self)
        self.scene, self.image, self.camera, self.loaded = QgsFileWidget(), QgsFileWidget(), QComboBox(), None
        self.scene.setFilter(SCENE_FILTER)
        self.scene.fileChanged.connect(self._scene_changed)
        self.image.setFilter(IMAGE_FILTER)
        self.camera.currentTextChanged.connect(self._propose_image)
        self.note = QLabel(tr("The scene: scene JSON, DIMAP, Maxar XML, an RPC file or an image with RPC metadata "
                              "(or a display copy). The raw image of its camera is proposed from its folder."),
                           wordWrap=True)
        form.addRow(self.note)
        for label, widget in ((tr("Scene"), self.scene), (tr("Camera"), self.camera), (tr("Raw image"), self.image)):
            form.addRow(label, widget)
        form.addRow(QDialogButtonBox(QDialogButtonBox.Ok | QDialogButtonBox.Cancel, accepted=self.accept,
                                     rejected=self.reject))

    def _scene_changed(self, path: str) -> None:
        self.camera.clear()
        self.loaded, cameras, note = scene_cameras(path)
        self.note.setText(note)
        self.camera.addItems(cameras)

    def _propose_image(self, camera: str) -> None:
        if self.loaded is not None and camera:
            image, note = proposed_image(self.loaded, self.scene.filePath(), camera)
            self.image.setFilePath(image)
            if note:
                self.note.setText(note)

    def chosen(self) -> tuple[str, str | None, str | None]:
        """(scene file, raw image or None, camera name or None)."""
        return self.scene.filePath(), self.image.filePath() or None, self.camera.currentText() or None


def ask_scene(parent, title: str, then) -> None:
    """Ask for a scene, its camera and raw image; ``then(scene, image, camera)`` after OK."""
    dialog = SceneDialog(parent, title)
    if dialog.exec_() == QDialog.Accepted:
        then(*dialog.chosen())


def ask_gpkg(parent, title: str, then, save: bool = True) -> None:
    """Ask for a GeoPackage to write (to read when not ``save``); ``then(path)`` when one is chosen."""
    path, _ = (QFileDialog.getSaveFileName if save else QFileDialog.getOpenFileName)(parent, title, "",
                                                                                      "GeoPackage (*.gpkg)")
    if path:
        then(path)
