"""The 'pushbroom' Processing provider: the plugin's algorithms in the toolbox and qgis_process."""
import logging

from qgis.core import QgsProcessingModelAlgorithm, QgsProcessingProvider
from qgis.PyQt.QtGui import QIcon

from . import RESOURCES
from .algorithms.bundleadjust import BundleAdjustAlgorithm
from .algorithms.exportrpc import ExportRpcAlgorithm
from .algorithms.footprint import FootprintAlgorithm
from .algorithms.groundtoimage import GroundToImageAlgorithm
from .algorithms.imagetoground import ImageToGroundAlgorithm
from .algorithms.importgcps import ImportGcpsAlgorithm
from .algorithms.importtiepoints import ImportTiePointsAlgorithm
from .algorithms.importlines import ImportLinesAlgorithm
from .algorithms.matchgcps import MatchGcpsAlgorithm
from .algorithms.matchtiepoints import MatchTiePointsAlgorithm
from .algorithms.orthorectify import OrthorectifyAlgorithm
from .algorithms.preparedigitising import PrepareDigitisingAlgorithm
from .algorithms.sensorcorrect import SensorCorrectAlgorithm
from .algorithms.simulateblock import SimulateBlockAlgorithm
from .algorithms.simulatescene import SimulateSceneAlgorithm
from .algorithms.snaplines import SnapLinesAlgorithm
from .parameters import tr

log = logging.getLogger(__name__)
MODELS = RESOURCES / "models"  # graphical models (.model3) shipped with the plugin, in the toolbox too
ALGORITHMS = (SimulateSceneAlgorithm, SimulateBlockAlgorithm, ImportGcpsAlgorithm, ImportTiePointsAlgorithm,
              ImportLinesAlgorithm,
              MatchGcpsAlgorithm, MatchTiePointsAlgorithm,
              BundleAdjustAlgorithm, GroundToImageAlgorithm, ImageToGroundAlgorithm, FootprintAlgorithm,
              OrthorectifyAlgorithm, ExportRpcAlgorithm, SensorCorrectAlgorithm, PrepareDigitisingAlgorithm,
              SnapLinesAlgorithm)


class PushbroomProvider(QgsProcessingProvider):

    def id(self):
        return "pushbroom"

    def name(self):
        return tr("Pushbroom Adjust")

    def longName(self):  # noqa: N802 (QGIS API name)
        return tr("Pushbroom Adjust — rigorous pushbroom sensor models")

    def icon(self):
        return QIcon(str(RESOURCES / "icon.svg"))

    def svgIconPath(self):  # noqa: N802 (QGIS API name)
        return str(RESOURCES / "icon.svg")

    def loadAlgorithms(self):  # noqa: N802 (QGIS API name)
        for alg in ALGORITHMS:
            self.addAlgorithm(alg())
        for path in sorted(MODELS.glob("*.model3")):
            model = QgsProcessingModelAlgorithm()
            if model.fromFile(str(path)):
                self.addAlgorithm(model)
            else:
                log.warning("cannot read the graphical model %s", path)
