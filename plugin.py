"""Plugin shell: registers the Processing provider (the plugin's only user interface so far)."""
from qgis.core import QgsApplication


class PushbroomAdjustPlugin:

    def __init__(self, iface):
        self.iface = iface
        self.provider = None

    def initProcessing(self):  # noqa: N802 (QGIS plugin API)
        from .ui.provider import PushbroomProvider
        self.provider = PushbroomProvider()
        QgsApplication.processingRegistry().addProvider(self.provider)

    def initGui(self):  # noqa: N802
        self.initProcessing()

    def unload(self):
        if self.provider is not None:
            QgsApplication.processingRegistry().removeProvider(self.provider)
            self.provider = None
