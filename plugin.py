"""Plugin shell: registers the Processing provider and the docks 'Digitise control lines on the raw
image' and 'Measure GCPs on the raw images' (each a toolbar button with an icon of its own, a
Plugins menu entry, an entry of the Processing menu and of the provider's button in the Processing
toolbox). The docks share the right dock area as tabs."""
from pathlib import Path

from qgis.core import QgsApplication
from qgis.PyQt.QtCore import Qt
from qgis.PyQt.QtGui import QIcon
from qgis.PyQt.QtWidgets import QAction, QMenu

MENU = "&Pushbroom Adjust"
RESOURCES = Path(__file__).resolve().parent / "resources"
PROCESSING_MENU = "processing"  # the object name of the Processing plugin's menu


class ToolboxEntry:
    """An entry of the provider's button in the Processing toolbox (what the toolbox's provider
    actions need: a name, setData and execute), opening a dock."""

    def __init__(self, action: QAction):
        self.name, self.action = action.text(), action

    def setData(self, toolbox):  # noqa: N802 (Processing API name)
        self.toolbox = toolbox

    def execute(self):
        self.action.trigger()


class PushbroomAdjustPlugin:

    def __init__(self, iface):
        self.iface = iface
        self.provider = None
        self.action = self.gcp_action = None
        self.dock = self.gcp_dock = None
        self.processing_menu = None

    def initProcessing(self):  # noqa: N802 (QGIS plugin API)
        from .ui.provider import PushbroomProvider
        self.provider = PushbroomProvider()
        QgsApplication.processingRegistry().addProvider(self.provider)

    def initGui(self):  # noqa: N802
        if self.provider is None:  # QGIS calls initProcessing first for plugins with a provider
            self.initProcessing()
        from .ui.parameters import tr
        self.action = self._add_action(tr("Digitise control lines on the raw image"), "icon_lines.svg", self.show_dock)
        self.gcp_action = self._add_action(tr("Measure GCPs on the raw images"), "icon_gcp.svg", self.show_gcp_dock)
        self._register_toolbox_entries()
        completed = getattr(self.iface, "initializationCompleted", None)  # not in every stand-in for QGIS
        if not self._add_processing_menu() and completed is not None:  # Processing makes its menu after us at start
            completed.connect(self._add_processing_menu)

    def _add_action(self, text: str, icon: str, slot) -> QAction:
        """A toolbar button and a Plugins menu entry calling ``slot``."""
        action = QAction(QIcon(str(RESOURCES / icon)), text, self.iface.mainWindow())
        action.triggered.connect(slot)
        self.iface.addToolBarIcon(action)
        self.iface.addPluginToMenu(MENU, action)
        return action

    def _register_toolbox_entries(self) -> None:
        """The docks in the menu of the provider's button of the Processing toolbox (made when the
        toolbox is, at start-up)."""
        try:
            from processing.gui.ProviderActions import ProviderActions
        except ImportError:  # no Processing plugin
            return
        ProviderActions.registerProviderActions(self.provider, [ToolboxEntry(self.gcp_action),
                                                                ToolboxEntry(self.action)])

    def _add_processing_menu(self) -> bool:
        """A 'Pushbroom Adjust' submenu of the Processing menu with the docks; False when there is
        no Processing menu (yet)."""
        if self.processing_menu is not None or self.action is None:
            return True
        menu_bar = self.iface.mainWindow().menuBar() if hasattr(self.iface.mainWindow(), "menuBar") else None
        processing = menu_bar.findChild(QMenu, PROCESSING_MENU) if menu_bar is not None else None
        if processing is None:
            return False
        self.processing_menu = processing.addMenu(QIcon(str(RESOURCES / "icon.svg")), "Pushbroom Adjust")
        self.processing_menu.addActions([self.gcp_action, self.action])
        return True

    def show_dock(self):
        """Open the line digitising dock (made on first use)."""
        from .ui.digitising.dock import DigitisingDock
        self.dock = self._shown(self.dock, DigitisingDock, self.gcp_dock)

    def show_gcp_dock(self):
        """Open the GCP measuring dock (made on first use)."""
        from .ui.digitising.gcpdock import GcpDock
        self.gcp_dock = self._shown(self.gcp_dock, GcpDock, self.dock)

    def _shown(self, dock, dock_class, other):
        """``dock`` (made of ``dock_class`` when None, a tab beside ``other`` when that one is in the
        main window), shown and raised."""
        if dock is None:
            main = self.iface.mainWindow()
            dock = dock_class(self.iface, main)
            self.iface.addDockWidget(Qt.RightDockWidgetArea, dock)
            if other is not None and main.dockWidgetArea(other) == main.dockWidgetArea(dock) != Qt.NoDockWidgetArea:
                main.tabifyDockWidget(other, dock)
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
        if self.processing_menu is not None:
            self.processing_menu.parent().removeAction(self.processing_menu.menuAction())
            self.processing_menu.deleteLater()
            self.processing_menu = None
        try:
            self.iface.initializationCompleted.disconnect(self._add_processing_menu)
        except (TypeError, AttributeError):  # never connected, or no such signal
            pass
        if self.provider is not None:
            try:
                from processing.gui.ProviderActions import ProviderActions
                ProviderActions.deregisterProviderActions(self.provider)
            except ImportError:
                pass
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
