"""QGIS plugin entry point: a Processing provider for the qtmvoronoi tool."""


def classFactory(iface):  # noqa: N802 (QGIS's name)
    from .provider import QtmvoronoiPlugin
    return QtmvoronoiPlugin(iface)
