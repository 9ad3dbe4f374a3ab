"""qtmvoronoi: spherical Voronoi diagrams on the QTM global grid, from Python.

The grid (the octahedral quaternary triangular mesh of docs/QTM-SPEC.md), vectorised over numpy
arrays (the GIL released, exactly the C++ library's results):

    lonlat_to_code(lon, lat, level)   positions (degrees) to cell codes
    code_to_lonlat(codes, level)      cell centres (degrees)
    code_to_cell / cell_to_code       codes to and from (octant, row, col)
    code_to_boundary(codes, level)    the three vertices of each cell (degrees)
    code_to_polygon, cell_polygons    each cell as the ring the tool draws (a GeoSeries)
    parent, children, neighbours      the hierarchy and the edge neighbours
    is_valid_code, cell_count, INVALID_CODE, MIN_LEVEL, MAX_LEVEL

The Voronoi run, the library's (man qtmvoronoi):

    voronoi(sites, level, ...)        GeoDataFrame, path or (lon, lat) in; GeoDataFrames or an
                                      xarray.DataArray out, without a file unless asked
    run_voronoi(source, destination, VoronoiOptions(...))   dataset to dataset, as the tool
    qtmvoronoi.dask.voronoi(client, sites, level, tiles=N)  tile jobs as Dask tasks, merged

Errors: Error (a failed run, the tool's message), OptionError (a bad option; also a ValueError),
Interrupted (stopped by the progress callback); Ctrl-C raises KeyboardInterrupt. Warnings of a
run are QtmvoronoiWarning.
"""

from ._qtmvoronoi import (
    GDAL_VERSION,
    INVALID_CODE,
    MAX_LEVEL,
    MIN_LEVEL,
    Error,
    Interrupted,
    OptionError,
    VoronoiOptions,
    VoronoiSummary,
    __version__,
    cell_count,
    cell_to_code,
    children,
    code_to_boundary,
    code_to_cell,
    code_to_lonlat,
    code_to_polygon,
    is_valid_code,
    lonlat_to_code,
    neighbours,
    parent,
    run_voronoi,
)
from .conversions import cell_polygons
from .run import QtmvoronoiWarning, voronoi

__all__ = [
    "GDAL_VERSION", "INVALID_CODE", "MAX_LEVEL", "MIN_LEVEL", "Error", "Interrupted", "OptionError",
    "QtmvoronoiWarning", "VoronoiOptions", "VoronoiSummary", "__version__", "cell_count", "cell_polygons",
    "cell_to_code", "children", "code_to_boundary", "code_to_cell", "code_to_lonlat", "code_to_polygon",
    "is_valid_code", "lonlat_to_code", "neighbours", "parent", "run_voronoi", "voronoi",
]
