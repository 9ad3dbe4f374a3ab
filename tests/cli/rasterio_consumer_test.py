#!/usr/bin/env python3
"""The raster outputs read by rasterio (Debian's python3-rasterio) as GDAL reads them (issue 36):
band count, data types, nodata, CRS, transform, band descriptions, metadata, overviews and every
pixel's value (NaN where GDAL has NaN), for GeoTIFF and COG, QTM-coded and lon/lat, default and
-bands/-ot rasters; and GDAL's COG validator (python3-gdal) on every COG among them.

  rasterio_consumer_test.py QTMVORONOI TESTDATA
"""
import os
import subprocess
import sys
import tempfile
import warnings

import numpy as np
import rasterio
import rasterio.errors
from osgeo import gdal
from osgeo_utils.samples import validate_cloud_optimized_geotiff

gdal.UseExceptions()
# The QTM-coded raster has no georeferencing (man page, QTM_LAYOUT): rasterio's warning is expected.
warnings.filterwarnings("ignore", category=rasterio.errors.NotGeoreferencedWarning)
tool, testdata = sys.argv[1], sys.argv[2]
centres = ["-oo", "X_POSSIBLE_NAMES=lon", "-oo", "Y_POSSIBLE_NAMES=lat", "-s_srs", "EPSG:4326",
           os.path.join(testdata, "country_centres.csv")]
failures = []


def check(ok, what):
    print(("ok: " if ok else "FAILED: ") + what)
    if not ok:
        failures.append(what)


def same_values(a, b):
    return a.shape == b.shape and a.dtype == b.dtype and np.array_equal(a, b, equal_nan=a.dtype.kind == "f")


def compare(path, name):
    ds = gdal.Open(path)
    with rasterio.open(path) as r:
        check(r.count == ds.RasterCount and r.width == ds.RasterXSize and r.height == ds.RasterYSize,
              "%s: %d bands of %dx%d" % (name, r.count, r.width, r.height))
        gdal_types = [gdal.GetDataTypeName(ds.GetRasterBand(k + 1).DataType).lower() for k in range(ds.RasterCount)]
        check(list(r.dtypes) == gdal_types, "%s: types %s" % (name, list(r.dtypes)))
        nodata = [ds.GetRasterBand(k + 1).GetNoDataValue() for k in range(ds.RasterCount)]
        check(all((a is None and b is None) or (a == b) or (np.isnan(a) and np.isnan(b))
                  for a, b in zip(r.nodatavals, nodata)), "%s: nodata %s" % (name, list(r.nodatavals)))
        descriptions = [ds.GetRasterBand(k + 1).GetDescription() for k in range(ds.RasterCount)]
        check(list(r.descriptions) == descriptions, "%s: band descriptions %s" % (name, list(r.descriptions)))
        srs = ds.GetSpatialRef()
        if srs is None:
            check(r.crs is None, "%s: no CRS (not georeferenced), as GDAL says" % name)
        else:
            check(r.crs is not None and str(r.crs.to_epsg()) == srs.GetAuthorityCode(None), "%s: CRS %s" % (name, r.crs))
        check(r.transform.to_gdal() == ds.GetGeoTransform(), "%s: transform %s" % (name, r.transform.to_gdal()))
        check(r.tags().get("QTM_LEVEL") == ds.GetMetadataItem("QTM_LEVEL") and r.tags().get("QTM_LEVEL"),
              "%s: QTM_LEVEL %s" % (name, r.tags().get("QTM_LEVEL")))
        for k in range(ds.RasterCount):
            band = ds.GetRasterBand(k + 1)
            check(same_values(r.read(k + 1), band.ReadAsArray()), "%s: band %d's %d pixels equal GDAL's"
                  % (name, k + 1, r.width * r.height))
            check(r.overviews(k + 1) == [ds.RasterXSize // band.GetOverview(o).XSize for o in range(band.GetOverviewCount())],
                  "%s: band %d's overviews %s" % (name, k + 1, r.overviews(k + 1)))
            if band.GetOverviewCount():
                o = band.GetOverview(0)
                check(same_values(r.read(k + 1, out_shape=(o.YSize, o.XSize)), o.ReadAsArray()),
                      "%s: band %d's first overview equals GDAL's" % (name, k + 1))
    if ds.GetDriver().ShortName == "GTiff" and "COG" in name:
        cog_warnings, errors, _ = validate_cloud_optimized_geotiff.validate(ds, full_check=True)
        check(not errors, "%s: GDAL's COG validator: %d errors %s, %d warnings" % (name, len(errors), errors, len(cog_warnings)))
    ds = None


with tempfile.TemporaryDirectory() as work:
    cases = [
        ("GeoTIFF, QTM-coded, level 6", ["-level", "6"], "qtm.tif"),
        ("GeoTIFF, lon/lat", ["-level", "7", "-ts", "720", "360"], "lonlat.tif"),
        ("GeoTIFF, -bands fid -ot Int32", ["-level", "7", "-ts", "720", "360", "-bands", "fid", "-ot", "Int32"], "fid.tif"),
        ("GeoTIFF, -bands distance,boundary -ot Float64", ["-level", "6", "-bands", "distance,boundary", "-ot", "Float64"], "d.tif"),
        ("COG, lon/lat", ["-level", "8", "-of", "COG", "-ts", "2048", "1024"], "lonlat_cog.tif"),
        ("COG, QTM-coded", ["-level", "8", "-of", "COG"], "qtm_cog.tif"),
        ("COG, -bands fid -ot UInt16", ["-level", "8", "-of", "COG", "-ts", "2048", "1024", "-bands", "fid", "-ot", "UInt16"],
         "fid_cog.tif"),
    ]
    for name, options, file in cases:
        path = os.path.join(work, file)
        r = subprocess.run([tool, "-q", "-device", "cpu"] + options + centres + [path], capture_output=True, text=True)
        if r.returncode != 0:
            failures.append("%s: qtmvoronoi failed (%d): %s" % (name, r.returncode, r.stderr))
            continue
        compare(path, name)

for f in failures:
    print("FAILED: " + f)
sys.exit(1 if failures else 0)
