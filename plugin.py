"""Plugin shell: registers the Processing provider and the docks 'Digitise control lines on the raw
image' and 'Measure GCPs on the raw images' (each a toolbar button and a Plugins menu entry)."""
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
        self.action = self.gcp_action = None
        self.dock = self.gcp_dock = None

    def initProcessing(self):  # noqa: N802 (QGIS plugin API)
        from .ui.provider import PushbroomProvider
        self.provider = PushbroomProvider()
        QgsApplication.processingRegistry().addProvider(self.provider)

    def initGui(self):  # noqa: N802
        if self.provider is None:  # QGIS calls initProcessing first for plugins with a provider
            self.initProcessing()
        from .ui.parameters import tr
        self.action = self._add_action(tr("Digitise control lines on the raw image"), self.show_dock)
        self.gcp_action = self._add_action(tr("Measure GCPs on the raw images"), self.show_gcp_dock)

    def _add_action(self, text: str, slot) -> QAction:
        """A toolbar button and a Plugins menu entry calling ``slot``."""
        action = QAction(QIcon(str(ICON)), text, self.iface.mainWindow())
        action.triggered.connect(slot)
        self.iface.addToolBarIcon(action)
        self.iface.addPluginToMenu(MENU, action)
        return action

    def show_dock(self):
        """Open the line digitising dock (made on first use)."""
        from .ui.digitising.dock import DigitisingDock
        self.dock = self._shown(self.dock, DigitisingDock)

    def show_gcp_dock(self):
        """Open the GCP measuring dock (made on first use)."""
        from .ui.digitising.gcpdock import GcpDock
        self.gcp_dock = self._shown(self.gcp_dock, GcpDock)

    def _shown(self, dock, dock_class):
        """``dock`` (made of ``dock_class`` when None), shown and raised."""
        if dock is None:
            dock = dock_class(self.iface, self.iface.mainWindow())
            self.iface.addDockWidget(Qt.RightDockWidgetArea, dock)
        dock.show()
        dock.raise_()
        return dock

    def unload(self):
        self.remove_gui()
        if self.provider is not None:
            QgsApplication.processingRegistry().removeProvider(self.provider)
            self.provider = None

    def remove_gui(self):
        """Remove the actions, their menu entries and the docks."""
        for action in (self.action, self.gcp_action):
            if action is not None:
                self.iface.removePluginMenu(MENU, action)
                self.iface.removeToolBarIcon(action)
        for dock in (self.dock, self.gcp_dock):
            if dock is not None:
                self.iface.removeDockWidget(dock)
                dock.dispose()
                dock.deleteLater()
        self.action = self.gcp_action = None
        self.dock = self.gcp_dock = None
