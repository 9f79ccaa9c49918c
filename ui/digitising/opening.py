"""The dialog that opens a scene in the docks: a scene file (or a display copy), the camera, and the
raw image of that camera proposed from the scene file's folder. Display copies are made in the
plugin's cache folder (:func:`core.measure.sources.open_image_source`), never beside the user's files.
"""
from __future__ import annotations

from pathlib import Path

from qgis.core import QgsApplication
from qgis.gui import QgsFileWidget
from qgis.PyQt.QtWidgets import QComboBox, QDialog, QDialogButtonBox, QFileDialog, QFormLayout, QLabel

from ...core.errors import PushbroomError
from ...core.formats import load_scene
from ...core.measure.sources import raw_image_candidates
from ..parameters import tr

SCENE_FILTER = ("Scenes (*.json *.JSON *.xml *.XML *.txt *.TXT *.rpb *.RPB *.tif *.TIF *.tiff *.ntf *.NTF *.vrt);;"
                "All files (*)")
IMAGE_FILTER = "Rasters (*.tif *.TIF *.tiff *.jp2 *.JP2 *.ntf *.NTF *.til *.TIL *.img *.vrt);;All files (*)"


def cache_folder() -> Path:
    """Where the docks keep their display copies: the plugin's folder in the QGIS profile's cache."""
    return Path(QgsApplication.qgisSettingsDirPath()) / "cache" / "pushbroom_adjust" / "display"


class SceneDialog(QDialog):
    """Scene file, raw image (proposed from the scene file's folder) and camera; ``chosen()``
    gives (scene, image, camera name) after OK."""

    def __init__(self, parent, title: str):
        super().__init__(parent)
        self.setWindowTitle(title)
        self.setMinimumWidth(520)
        form = QFormLayout(self)
        self.scene = QgsFileWidget()
        self.scene.setFilter(SCENE_FILTER)
        self.scene.fileChanged.connect(self._scene_changed)
        self.image = QgsFileWidget()
        self.image.setFilter(IMAGE_FILTER)
        self.camera = QComboBox()
        self.camera.currentTextChanged.connect(self._propose_image)
        self.note = QLabel(tr("The scene: scene JSON, DIMAP, Maxar XML, an RPC file or an image with RPC metadata "
                              "(or a display copy). The raw image of its camera is proposed from its folder."))
        self.note.setWordWrap(True)
        form.addRow(self.note)
        form.addRow(tr("Scene"), self.scene)
        form.addRow(tr("Camera"), self.camera)
        form.addRow(tr("Raw image"), self.image)
        buttons = QDialogButtonBox(QDialogButtonBox.Ok | QDialogButtonBox.Cancel)
        buttons.accepted.connect(self.accept)
        buttons.rejected.connect(self.reject)
        form.addRow(buttons)
        self.loaded = None

    def _scene_changed(self, path: str) -> None:
        self.camera.clear()
        self.loaded = None
        try:
            self.loaded = load_scene(path)
        except (PushbroomError, OSError) as exc:
            self.note.setText(str(exc))
            return
        self.note.setText(tr("{path}: {n} camera(s)").format(path=path, n=len(self.loaded.cameras)))
        self.camera.addItems([c.name for c in self.loaded.cameras])

    def _propose_image(self, camera: str) -> None:
        if self.loaded is None or not camera:
            return
        cam = self.loaded.cameras[self.loaded.camera_index(camera)]
        found = raw_image_candidates(self.scene.filePath(), cam.cols, cam.rows, cam.name, self.loaded.info.get("image"))
        self.image.setFilePath(str(found[0]) if found else "")
        if not found:
            self.note.setText(tr("No raster of {cols} x {rows} px (camera {camera}) beside the scene: choose its raw "
                                 "image").format(cols=cam.cols, rows=cam.rows, camera=cam.name))

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
