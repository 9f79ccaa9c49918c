"""Plugin shell: registers the Processing provider and the dock 'Digitise control lines on the raw
image' (a toolbar button and a Plugins menu entry)."""
from pathlib import Path

from qgis.core import QgsApplication
from qgis.PyQt.QtCore import Qt
from qgis.PyQt.QtGui import QIcon
from qgis.PyQt.QtWidgets import QAction

MENU = "&Pushbroom Adjust"
ICON = Path(__file__).resolve().parent / "resources" / "icon.svg"


class PushbroomAdjustPlugin:

    def __init__(self, iface):
        self.iface = iface
        self.provider = None
        self.action = None
        self.dock = None

    def initProcessing(self):  # noqa: N802 (QGIS plugin API)
        from .ui.provider import PushbroomProvider
        self.provider = PushbroomProvider()
        QgsApplication.processingRegistry().addProvider(self.provider)

    def initGui(self):  # noqa: N802
        if self.provider is None:  # QGIS calls initProcessing first for plugins with a provider
            self.initProcessing()
        from .ui.parameters import tr
        self.action = QAction(QIcon(str(ICON)), tr("Digitise control lines on the raw image"),
                              self.iface.mainWindow())
        self.action.triggered.connect(self.show_dock)
        self.iface.addToolBarIcon(self.action)
        self.iface.addPluginToMenu(MENU, self.action)

    def show_dock(self):
        """Open the digitising dock (made on first use)."""
        if self.dock is None:
            from .ui.digitising.dock import DigitisingDock
            self.dock = DigitisingDock(self.iface, self.iface.mainWindow())
            self.iface.addDockWidget(Qt.RightDockWidgetArea, self.dock)
        self.dock.show()
        self.dock.raise_()

    def unload(self):
        self.remove_gui()
        if self.provider is not None:
            QgsApplication.processingRegistry().removeProvider(self.provider)
            self.provider = None

    def remove_gui(self):
        """Remove the action, its menu entry and the dock."""
        if self.action is not None:
            self.iface.removePluginMenu(MENU, self.action)
            self.iface.removeToolBarIcon(self.action)
            self.action = None
        if self.dock is not None:
            self.iface.removeDockWidget(self.dock)
            self.dock.dispose()
            self.dock.deleteLater()
            self.dock = None
