"""The plugin (registers the provider, in QGIS and in qgis_process) and the Processing provider."""

from qgis.core import QgsApplication, QgsProcessingProvider

from .algorithms import VoronoiRaster, VoronoiRegions
from .tool import find_tool, tool_version


class QtmvoronoiProvider(QgsProcessingProvider):
    def id(self):
        return "qtmvoronoi"

    def name(self):
        return "qtmvoronoi"

    def longName(self):  # noqa: N802
        version = tool_version()
        return "qtmvoronoi " + version if version else "qtmvoronoi (tool not found)"

    def loadAlgorithms(self):  # noqa: N802
        self.addAlgorithm(VoronoiRegions())
        self.addAlgorithm(VoronoiRaster())

    def canBeActivated(self):  # noqa: N802
        return find_tool() is not None

    def warningMessage(self):  # noqa: N802
        if find_tool() is None:
            return "qtmvoronoi was not found: install the qtmvoronoi package, or set QTMVORONOI to the tool's path"
        return ""


class QtmvoronoiPlugin:
    def __init__(self, iface):
        self.iface = iface
        self.provider = None

    def initProcessing(self):  # noqa: N802 (called by qgis_process, and by initGui)
        self.provider = QtmvoronoiProvider()
        QgsApplication.processingRegistry().addProvider(self.provider)

    def initGui(self):  # noqa: N802
        self.initProcessing()

    def unload(self):
        if self.provider is not None:
            QgsApplication.processingRegistry().removeProvider(self.provider)
            self.provider = None
