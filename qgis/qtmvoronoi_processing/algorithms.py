"""The Processing algorithms: Voronoi regions (vector layers) and a Voronoi raster. Each builds a
qtmvoronoi command line from its parameters and runs it (tool.py)."""

import os

from qgis.core import (QgsProcessing, QgsProcessingAlgorithm, QgsProcessingException,
                       QgsProcessingParameterEnum, QgsProcessingParameterFeatureSource,
                       QgsProcessingParameterNumber, QgsProcessingParameterRasterDestination,
                       QgsProcessingParameterVectorDestination)

from .tool import run_tool

DISTANCES = ["exact", "cell"]
DEVICES = ["auto", "cpu", "cuda", "cuda:all"]
LAYER_NAMES = ["regions", "voronoi_edges", "boundary_cells", "cells"]
LAYOUTS = ["qtm", "lonlat"]
DATA_TYPES = ["default", "Byte", "UInt16", "Int16", "UInt32", "Int32", "Float32", "Float64"]
# Formats the tool reads a layer from as it is; others, and selections, go through a copy.
READABLE = ["gpkg", "shp", "geojson", "json", "fgb", "gml", "kml", "csv", "sqlite", "tab", "mif"]


class QtmvoronoiAlgorithm(QgsProcessingAlgorithm):
    """Parameters and arguments common to both algorithms."""

    INPUT, LEVEL, DISTANCE, DEVICE, OUTPUT = "INPUT", "LEVEL", "DISTANCE", "DEVICE", "OUTPUT"

    def group(self):
        return "Voronoi"

    def groupId(self):  # noqa: N802
        return "voronoi"

    def add_common_parameters(self):
        self.addParameter(QgsProcessingParameterFeatureSource(
            self.INPUT, "Sites (points, lines or polygons)", [QgsProcessing.TypeVectorAnyGeometry]))
        self.addParameter(QgsProcessingParameterNumber(
            self.LEVEL, "QTM level (0-24; 8 x 4^level cells)", QgsProcessingParameterNumber.Integer, 9, False, 0, 24))
        self.addParameter(QgsProcessingParameterEnum(
            self.DISTANCE, "Distance rule (exact: to the cell's nearest point of the site; cell: the paper's cell centres)",
            DISTANCES, defaultValue=0))
        self.addParameter(QgsProcessingParameterEnum(
            self.DEVICE, "Device (auto: a GPU when there is one)", DEVICES, defaultValue=0))

    def common_arguments(self, parameters, context, feedback):
        """-level, -distance, -device, -l and the source's path: a layer the tool cannot read as
        it is, or only its selected features, is first written to a GeoPackage."""
        path, layer = self.parameterAsCompatibleSourceLayerPathAndLayerName(
            parameters, self.INPUT, context, READABLE, "gpkg", feedback)
        if not path:
            raise QgsProcessingException("no sites layer")
        arguments = ["-overwrite",
                     "-level", self.parameterAsInt(parameters, self.LEVEL, context),
                     "-distance", DISTANCES[self.parameterAsEnum(parameters, self.DISTANCE, context)],
                     "-device", DEVICES[self.parameterAsEnum(parameters, self.DEVICE, context)]]
        if layer:
            arguments += ["-l", layer]
        return arguments, path


class VoronoiRegions(QtmvoronoiAlgorithm):
    LAYERS = "LAYERS"

    def name(self):
        return "voronoiregions"

    def displayName(self):  # noqa: N802
        return "Voronoi regions (geodesic, QTM grid)"

    def shortHelpString(self):  # noqa: N802
        return ("The geodesic Voronoi regions of the sites on the whole globe: every cell of the QTM grid at "
                "the level goes to its nearest site by great-circle distance to the site's exact geometry. "
                "Writes the layers chosen (regions: a MultiPolygon per site with its fields, site_fid, cells "
                "and area_m2; voronoi_edges; boundary_cells; cells) into one dataset, and loads the first. "
                "Runs the qtmvoronoi tool (man qtmvoronoi).")

    def createInstance(self):  # noqa: N802
        return VoronoiRegions()

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add_common_parameters()
        self.addParameter(QgsProcessingParameterEnum(
            self.LAYERS, "Layers to write", LAYER_NAMES, allowMultiple=True, defaultValue=[0]))
        self.addParameter(QgsProcessingParameterVectorDestination(
            self.OUTPUT, "Voronoi regions", QgsProcessing.TypeVectorPolygon))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        arguments, source = self.common_arguments(parameters, context, feedback)
        layers = [LAYER_NAMES[k] for k in self.parameterAsEnums(parameters, self.LAYERS, context)] or ["regions"]
        output = self.parameterAsOutputLayer(parameters, self.OUTPUT, context)
        run_tool(arguments + ["-layers", ",".join(layers), source, output], feedback)
        if os.path.splitext(output)[1].lower() == ".gpkg":
            return {self.OUTPUT: output + "|layername=" + layers[0]}
        return {self.OUTPUT: output}


class VoronoiRaster(QtmvoronoiAlgorithm):
    LAYOUT, PIXEL_SIZE, DATA_TYPE = "LAYOUT", "PIXEL_SIZE", "DATA_TYPE"

    def name(self):
        return "voronoiraster"

    def displayName(self):  # noqa: N802
        return "Voronoi raster (geodesic, QTM grid)"

    def shortHelpString(self):  # noqa: N802
        return ("The geodesic Voronoi diagram of the sites as a raster of three bands: the nearest site's FID, "
                "a boundary flag, the distance in metres. qtm: the QTM-coded raster, one pixel per cell; "
                "lonlat: a georeferenced EPSG:4326 grid of the pixel size given (degrees; 0: the tool's "
                "default). Runs the qtmvoronoi tool (man qtmvoronoi).")

    def createInstance(self):  # noqa: N802
        return VoronoiRaster()

    def initAlgorithm(self, config=None):  # noqa: N802
        self.add_common_parameters()
        self.addParameter(QgsProcessingParameterEnum(self.LAYOUT, "Raster", LAYOUTS, defaultValue=0))
        self.addParameter(QgsProcessingParameterNumber(
            self.PIXEL_SIZE, "Pixel size of the lonlat raster (degrees; 0: the tool's default)",
            QgsProcessingParameterNumber.Double, 0.0, False, 0.0, 90.0))
        self.addParameter(QgsProcessingParameterEnum(self.DATA_TYPE, "Band type", DATA_TYPES, defaultValue=0))
        self.addParameter(QgsProcessingParameterRasterDestination(self.OUTPUT, "Voronoi raster"))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802
        arguments, source = self.common_arguments(parameters, context, feedback)
        layout = LAYOUTS[self.parameterAsEnum(parameters, self.LAYOUT, context)]
        pixel = self.parameterAsDouble(parameters, self.PIXEL_SIZE, context)
        data_type = DATA_TYPES[self.parameterAsEnum(parameters, self.DATA_TYPE, context)]
        arguments += ["-raster", layout]
        if pixel > 0:
            if layout != "lonlat":
                raise QgsProcessingException("a pixel size is for the lonlat raster: the QTM-coded raster's follows the level")
            arguments += ["-tr", repr(pixel), repr(pixel)]
        if data_type != "default":
            arguments += ["-ot", data_type]
        output = self.parameterAsOutputLayer(parameters, self.OUTPUT, context)
        run_tool(arguments + [source, output], feedback)
        return {self.OUTPUT: output}
