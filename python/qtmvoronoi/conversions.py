"""The conversions between Python's data and the datasets the library reads and writes.

The library runs on GDAL dataset names, as the tool does. A GeoDataFrame or lon/lat arrays become
a GeoPackage in GDAL's in-memory file system (/vsimem/), written through osgeo (GDAL's own
Python bindings, which share this process's libgdal and so its /vsimem/ with the library); the
run writes its GeoPackage or GeoTIFF there too, and its layers are read back through GDAL's
Arrow stream as numpy columns (GeoDataFrames) and its bands as an xarray.DataArray. Nothing
touches the disk, and every in-memory file goes when the call ends.

osgeo, geopandas and xarray are imported when first needed: `import qtmvoronoi` needs numpy only.
"""

import contextlib
import math
import os
import uuid

import numpy as np

from . import _qtmvoronoi

# The layer name a frame's sites get in their in-memory GeoPackage.
SITES_LAYER = "sites"


def _require(module, package):
    """The module `module`, or ImportError naming the Debian package that has it."""
    try:
        return __import__(module, fromlist=["_"])
    except ImportError as e:
        raise ImportError(f"qtmvoronoi: this needs {module} (Debian: apt-get install {package})") from e


def _gdal():
    """osgeo.gdal (python3-gdal)."""
    return _require("osgeo.gdal", "python3-gdal")


def _ogr():
    """osgeo.ogr (python3-gdal)."""
    return _require("osgeo.ogr", "python3-gdal")


@contextlib.contextmanager
def gdal_exceptions():
    """osgeo raising exceptions within the block, and after it as before (the caller's setting kept)."""
    gdal, ogr = _gdal(), _ogr()
    before = gdal.GetUseExceptions(), ogr.GetUseExceptions()
    gdal.UseExceptions()
    ogr.UseExceptions()
    try:
        yield
    finally:
        # GDAL 3.6 keeps the modules' error handlers on a stack: undone in the reverse order.
        if not before[1]:
            ogr.DontUseExceptions()
        if not before[0]:
            gdal.DontUseExceptions()


class MemoryDirectory:
    """A directory of GDAL's in-memory file system, /vsimem/qtmvoronoi-<unique>/, removed with
    everything in it by remove(). Flat: /vsimem/ lists only the directories made with Mkdir."""

    def __init__(self):
        """Makes the directory (osgeo's GDAL checked to be the module's first)."""
        _check_shared_vsimem()
        self.path = f"/vsimem/qtmvoronoi-{uuid.uuid4().hex}"
        _gdal().Mkdir(self.path, 0o755)

    def file(self, name):
        """The in-memory file name `name` in this directory."""
        return f"{self.path}/{name}"

    def write(self, name, data):
        """Writes the bytes `data` to the in-memory file `name`; returns its name."""
        path = self.file(name)
        _gdal().FileFromMemBuffer(path, bytes(data))
        return path

    def read(self, name):
        """The bytes of the in-memory file `name`."""
        gdal = _gdal()
        path = self.file(name)
        stat = gdal.VSIStatL(path)
        f = gdal.VSIFOpenL(path, "rb")
        if stat is None or f is None:
            raise _qtmvoronoi.Error(f"'{path}': no such in-memory file")
        try:
            return bytes(gdal.VSIFReadL(1, stat.size, f)) if stat.size else b""
        finally:
            gdal.VSIFCloseL(f)

    def remove(self):
        """Removes the directory and every file in it (those GDAL made beside ours too)."""
        gdal = _gdal()
        for name in gdal.ReadDir(self.path) or []:
            gdal.Unlink(self.file(name))
        gdal.Rmdir(self.path)


_vsimem_checked = False


def _check_shared_vsimem():
    """Checks once that osgeo's GDAL is the module's (one /vsimem/ for both)."""
    global _vsimem_checked
    if _vsimem_checked:
        return
    gdal = _gdal()
    probe = f"/vsimem/qtmvoronoi-probe-{uuid.uuid4().hex}"
    gdal.FileFromMemBuffer(probe, b"qtmv")
    try:
        if _qtmvoronoi._vsi_file_size(probe) != 4:
            raise ImportError(
                f"qtmvoronoi: osgeo's GDAL ({gdal.__version__}) is not the one the module links "
                f"({_qtmvoronoi.GDAL_VERSION}): they share no in-memory files; use the system's python3-gdal")
    finally:
        gdal.Unlink(probe)
    _vsimem_checked = True


# --- Sites: a GeoDataFrame or lon/lat arrays as an in-memory GeoPackage ------------------------

def _field_type(series):
    """The OGR field type (and subtype) of a pandas column."""
    ogr = _ogr()
    kind = series.dtype.kind
    if kind == "b" or str(series.dtype) == "boolean":
        return ogr.OFTInteger, ogr.OFSTBoolean
    if kind in "iu":
        small = series.dtype.itemsize < 4 or (series.dtype.itemsize == 4 and kind == "i")
        return (ogr.OFTInteger if small else ogr.OFTInteger64), ogr.OFSTNone
    if kind == "f":
        return ogr.OFTReal, ogr.OFSTNone
    if kind == "M":
        return ogr.OFTDateTime, ogr.OFSTNone
    return ogr.OFTString, ogr.OFSTNone


def _column_values(series, field_type):
    """The column as Python values for OGR's SetField, None where it is null."""
    ogr = _ogr()
    isnull = series.isna().to_numpy()
    if field_type == ogr.OFTDateTime:
        values = [None if n else (v.year, v.month, v.day, v.hour, v.minute, v.second + v.microsecond / 1e6, 100 if v.tzinfo else 0)
                  for v, n in zip(series.dt.tz_convert("UTC") if series.dt.tz is not None else series, isnull)]
        return values
    if field_type == ogr.OFTString:
        return [None if n else str(v) for v, n in zip(series.tolist(), isnull)]
    if field_type in (ogr.OFTInteger, ogr.OFTInteger64):
        return [None if n else int(v) for v, n in zip(series.tolist(), isnull)]
    return [None if n else float(v) for v, n in zip(series.tolist(), isnull)]


def _unused_name(preferred, taken):
    """`preferred`, or preferred_1, preferred_2, ...: the first not in `taken` (lower case names)."""
    name, k = preferred, 1
    while name.lower() in taken:
        name, k = f"{preferred}_{k}", k + 1
    return name


def _srs_of(crs):
    """An osr.SpatialReference of a pyproj CRS (None: none), lon/lat in the data's x/y order."""
    if crs is None:
        return None
    osr = _require("osgeo.osr", "python3-gdal")
    srs = osr.SpatialReference()
    epsg = crs.to_epsg()
    if epsg is not None:
        srs.ImportFromEPSG(epsg)
    else:
        srs.ImportFromWkt(crs.to_wkt())
    srs.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    return srs


def write_frame(frame, path):
    """Writes a GeoDataFrame (or GeoSeries) to the GeoPackage `path` as the layer SITES_LAYER.

    Each row a feature, FIDs 1..n in row order; the active geometry its geometry (None or empty:
    none, which the reader names and skips), every other column a field of its type (bool,
    integers, floats, datetimes; anything else as text), nulls as nulls. The frame's CRS is the
    layer's (None: none).
    """
    gpd = _require("geopandas", "python3-geopandas")
    ogr = _ogr()
    if isinstance(frame, gpd.GeoSeries):
        frame = gpd.GeoDataFrame(geometry=frame)
    geometry_name = frame.geometry.name
    attributes = [c for c in frame.columns if c != geometry_name]
    taken = {str(c).lower() for c in attributes}
    options = ["SPATIAL_INDEX=NO", f"FID={_unused_name('fid', taken)}", f"GEOMETRY_NAME={_unused_name('geom', taken)}"]
    with gdal_exceptions():
        dataset = ogr.GetDriverByName("GPKG").CreateDataSource(path)
        try:
            layer = dataset.CreateLayer(SITES_LAYER, _srs_of(frame.crs), ogr.wkbUnknown, options)
            columns = []
            for name in attributes:
                series = frame[name]
                if isinstance(series.dtype, gpd.array.GeometryDtype):  # another geometry column: its WKT
                    series = series.to_wkt()
                field_type, subtype = _field_type(series)
                field = ogr.FieldDefn(str(name), field_type)
                field.SetSubType(subtype)
                layer.CreateField(field)
                columns.append(_column_values(series, field_type))
            definition = layer.GetLayerDefn()
            dataset.StartTransaction()
            for row, geometry in enumerate(frame.geometry.values):
                feature = ogr.Feature(definition)
                for k, values in enumerate(columns):
                    value = values[row]
                    if value is None:
                        feature.SetFieldNull(k)
                    elif isinstance(value, tuple):
                        feature.SetField(k, *value)
                    else:
                        feature.SetField(k, value)
                if geometry is not None and not geometry.is_empty:
                    feature.SetGeometryDirectly(ogr.CreateGeometryFromWkb(geometry.wkb))
                layer.CreateFeature(feature)
            dataset.CommitTransaction()
        finally:
            dataset = None


def write_lonlat(lon, lat, path):
    """Writes points (lon, lat) (degrees, EPSG:4326; arrays of one length) to the GeoPackage `path`
    as the layer SITES_LAYER, FIDs 1..n in order, without attributes."""
    ogr = _ogr()
    lon = np.asarray(lon, dtype=np.float64).ravel()
    lat = np.asarray(lat, dtype=np.float64).ravel()
    if lon.shape != lat.shape:
        raise _qtmvoronoi.OptionError(f"sites: lon and lat differ in length ({lon.size} and {lat.size})")
    osr = _require("osgeo.osr", "python3-gdal")
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(4326)
    srs.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    with gdal_exceptions():
        dataset = ogr.GetDriverByName("GPKG").CreateDataSource(path)
        try:
            layer = dataset.CreateLayer(SITES_LAYER, srs, ogr.wkbPoint, ["SPATIAL_INDEX=NO"])
            definition = layer.GetLayerDefn()
            dataset.StartTransaction()
            for x, y in zip(lon.tolist(), lat.tolist()):
                feature = ogr.Feature(definition)
                point = ogr.Geometry(ogr.wkbPoint)
                point.AddPoint_2D(x, y)
                feature.SetGeometryDirectly(point)
                layer.CreateFeature(feature)
            dataset.CommitTransaction()
        finally:
            dataset = None


def sites_source(sites, directory):
    """The dataset name the library reads `sites` from, and a description of them for messages.

    sites: a path or GDAL dataset name (str or os.PathLike: read as it is); a GeoDataFrame or
    GeoSeries; or a pair (lon, lat) of arrays (degrees). The latter two are written to an
    in-memory GeoPackage in `directory` (a MemoryDirectory).
    """
    if isinstance(sites, (str, os.PathLike)):
        return os.fspath(sites), None
    if isinstance(sites, tuple) and len(sites) == 2:
        path = directory.file("sites.gpkg")
        write_lonlat(sites[0], sites[1], path)
        return path, "the lon/lat arrays"
    gpd = _require("geopandas", "python3-geopandas")
    if isinstance(sites, (gpd.GeoDataFrame, gpd.GeoSeries)):
        path = directory.file("sites.gpkg")
        write_frame(sites, path)
        return path, "the GeoDataFrame" if isinstance(sites, gpd.GeoDataFrame) else "the GeoSeries"
    raise TypeError(f"sites: a path, a GeoDataFrame, a GeoSeries or (lon, lat) arrays, not {type(sites).__name__}")


# --- Results: layers as GeoDataFrames, rasters as xarray.DataArray ------------------------------

def _numpy_column(values):
    """A column of GDAL's Arrow stream as pandas takes it: text decoded, nulls None or NaN."""
    if isinstance(values, np.ma.MaskedArray):
        mask = np.ma.getmaskarray(values)
        if not mask.any():
            return values.data if values.dtype.kind not in "SV" else _numpy_column(values.data)
        if values.dtype.kind in "iuf":  # as pandas makes a column of numbers and nulls: float64, NaN
            return values.astype(np.float64).filled(np.nan)
        if values.dtype.kind == "M":
            return values.filled(np.datetime64("NaT"))
        if values.dtype.kind == "b":
            data = values.data.astype(object)
            data[mask] = None
            return data
        values = values.data
    else:
        mask = None
    if values.dtype.kind in "SV":
        # Text comes as fixed-width bytes; binary (WKB) of one length in a batch as fixed-size void.
        if values.dtype.kind == "S":
            data = np.array([v.decode("utf-8") for v in values.tolist()], dtype=object)
        else:
            data = np.array([v.tobytes() for v in values], dtype=object)
        if mask is not None:
            data[mask] = np.nan  # as geopandas.read_file has null text
        return data
    return values


def _boolean_column(layer, index):
    """A Boolean field's values, read feature by feature: GDAL 3.6's Arrow stream to numpy
    mis-reads bit-packed Booleans."""
    definition = layer.GetLayerDefn()
    others = [definition.GetFieldDefn(k).GetName() for k in range(definition.GetFieldCount()) if k != index]
    layer.SetIgnoredFields(others + ["OGR_GEOMETRY"])
    layer.ResetReading()
    values = [feature.GetField(index) for feature in layer]
    layer.SetIgnoredFields([])
    return np.array(values, dtype=object if None in values else bool)


def read_layer(dataset, name):
    """The layer `name` of the dataset `dataset` (a GDAL name) as a GeoDataFrame.

    The rows in FID order with a RangeIndex, its fields as columns (text as str; nulls NaN, NaT
    in datetimes; integers with nulls float64), its geometry last as 'geometry', its CRS: what geopandas.read_file
    gives for the layer, read through GDAL's Arrow stream (numpy columns, not one Python object
    per feature).
    """
    gpd = _require("geopandas", "python3-geopandas")
    ogr = _ogr()
    with gdal_exceptions():
        source = ogr.Open(dataset)
        layer = source.GetLayerByName(name)
        if layer is None:
            raise _qtmvoronoi.Error(f"'{name}': no such layer in the result")
        definition = layer.GetLayerDefn()
        fields = [definition.GetFieldDefn(k).GetName() for k in range(definition.GetFieldCount())]
        geometry_field = layer.GetGeometryColumn() or "wkb_geometry"
        batches = {}
        for batch in layer.GetArrowStreamAsNumPy(options=["INCLUDE_FID=NO"]):
            for key, values in batch.items():
                batches.setdefault(key, []).append(values)
        booleans = {definition.GetFieldDefn(k).GetName(): _boolean_column(layer, k) for k in range(len(fields))
                     if definition.GetFieldDefn(k).GetSubType() == ogr.OFSTBoolean}
        srs = layer.GetSpatialRef()
        crs = srs.ExportToWkt() if srs is not None else None
        layer = source = None

    def column(key):
        """The field's values over every batch (each converted on its own: their fixed widths differ)."""
        parts = [_numpy_column(p) for p in batches.get(key, [])]
        return np.concatenate(parts) if parts else np.array([], dtype=object)

    data = {f: booleans[f] if f in booleans else column(f) for f in fields}
    geometry = gpd.GeoSeries.from_wkb(column(geometry_field), crs=crs)
    return gpd.GeoDataFrame(data, geometry=geometry, crs=crs)


def read_raster(dataset):
    """The raster `dataset` (a GDAL name) as an xarray.DataArray of dimensions (band, y, x).

    band: the bands' descriptions (site_fid, boundary, distance_m); the values as the file holds
    them (its type, nodata where no cell's centre is). A lon/lat raster has coordinates x and y
    (degrees: longitude and latitude of the pixels' centres) and its CRS as CF's and rioxarray's
    'spatial_ref' coordinate (crs_wkt, GeoTransform); a QTM-coded raster has dimensions
    (band, row, col): row octant * 2**level + i, column j of cell (octant, i, j). attrs: the file's
    metadata (QTM_LEVEL, QTM_LAYOUT, ...), nodata, and the bands' units.
    """
    xr = _require("xarray", "python3-xarray")
    gdal = _gdal()
    with gdal_exceptions():
        ds = gdal.Open(dataset)
        values = ds.ReadAsArray()
        if values.ndim == 2:
            values = values[np.newaxis]
        bands = [ds.GetRasterBand(k + 1) for k in range(ds.RasterCount)]
        names = [b.GetDescription() or f"band_{k + 1}" for k, b in enumerate(bands)]
        attrs = dict(ds.GetMetadata() or {})
        attrs["nodata"] = bands[0].GetNoDataValue()
        attrs["units"] = [b.GetUnitType() for b in bands]
        transform = ds.GetGeoTransform(can_return_null=True)
        wkt = ds.GetProjection()
        width, height = ds.RasterXSize, ds.RasterYSize
        ds = None
    if attrs.get("QTM_LAYOUT") == "lonlat" or (wkt and transform is not None):
        x = transform[0] + (np.arange(width) + 0.5) * transform[1]
        y = transform[3] + (np.arange(height) + 0.5) * transform[5]
        spatial_ref = xr.DataArray(0, attrs={"crs_wkt": wkt, "spatial_ref": wkt,
                                             "GeoTransform": " ".join(repr(v) for v in transform)})
        coords = {"band": names, "y": y, "x": x, "spatial_ref": spatial_ref}
        dims = ("band", "y", "x")
        attrs["crs"] = wkt
    else:
        coords = {"band": names, "row": np.arange(height), "col": np.arange(width)}
        dims = ("band", "row", "col")
    return xr.DataArray(values, dims=dims, coords=coords, attrs=attrs, name="qtmvoronoi")


def cell_polygons(codes, level, crs="EPSG:4326"):
    """The cells of `codes` (integers of `level`) as a GeoSeries of polygons (degrees, EPSG:4326),
    as the tool draws them (code_to_polygon: three corners, four for an octant's pole cell)."""
    gpd = _require("geopandas", "python3-geopandas")
    from shapely.geometry import Polygon

    rings = np.asarray(_qtmvoronoi.code_to_polygon(np.atleast_1d(codes), level)).reshape(-1, 4, 2)
    polygons = [Polygon(r[:3] if math.isnan(r[3, 0]) else r) for r in rings]
    return gpd.GeoSeries(polygons, crs=crs)
