#!/usr/bin/env python3
"""Outputs read right by their consumers' own validators (issue 36): GDAL's validate_gpkg.py over
every layer of a GeoPackage (written as direct rows and through OGR), SQLite's integrity check, and
GDAL's COG validator over a COG with overviews; both validators from Debian's python3-gdal.

GDAL 3.6.2's validate_gpkg.py reads the empty flag from the wrong bit and reports "Inconsistent
empty_flag vs geometry content" for every empty geometry, GDAL's own MULTIPOLYGON EMPTY included:
that message is expected once per empty region (a site without a cell), and nothing else.

  consumer_validators_test.py QTMVORONOI TESTDATA
"""
import os
import sqlite3
import subprocess
import sys
import tempfile

from osgeo import gdal
from osgeo_utils.samples import validate_cloud_optimized_geotiff, validate_gpkg

gdal.UseExceptions()
tool, testdata = sys.argv[1], sys.argv[2]
centres = ["-oo", "X_POSSIBLE_NAMES=lon", "-oo", "Y_POSSIBLE_NAMES=lat", "-s_srs", "EPSG:4326",
           os.path.join(testdata, "country_centres.csv")]
EMPTY_FLAG_BUG = "Inconsistent empty_flag vs geometry content"
failures = []


def run(args):
    r = subprocess.run([tool, "-q", "-device", "cpu"] + args, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit("qtmvoronoi %s failed (%d): %s" % (" ".join(args), r.returncode, r.stderr))


def check_gpkg(path, what):
    with sqlite3.connect(path) as db:
        integrity = db.execute("PRAGMA integrity_check").fetchone()[0]
    if integrity != "ok":
        failures.append("%s: PRAGMA integrity_check says %s" % (what, integrity))
    ds = gdal.OpenEx(path, gdal.OF_VECTOR)
    regions = ds.GetLayerByName("regions")
    empty = sum(1 for f in regions if f.GetGeometryRef() is not None and f.GetGeometryRef().IsEmpty())
    ds = None
    errors = validate_gpkg.check(path, abort_at_first_error=False, warning_msg=False)
    known = [e for e in errors if e[1] == EMPTY_FLAG_BUG]
    others = [e for e in errors if e[1] != EMPTY_FLAG_BUG]
    if others:
        failures.append("%s: validate_gpkg.py: %s" % (what, others[:5]))
    if len(known) != empty:
        failures.append("%s: %d empty-flag reports for %d empty regions" % (what, len(known), empty))
    if empty == 0:
        failures.append("%s: no empty region: the case no longer covers sites without a cell" % what)
    print("%s: integrity %s, validate_gpkg.py: %d reports, all %d of them the empty-flag bug" % (what, integrity, len(errors), len(known)))


with tempfile.TemporaryDirectory() as work:
    layers = ["-layers", "regions,boundary_cells,voronoi_edges,cells"]
    direct = os.path.join(work, "direct.gpkg")
    run(["-level", "5"] + layers + centres + [direct])  # level 5: 10 sites without a cell
    check_gpkg(direct, "GeoPackage (direct rows)")
    through_ogr = os.path.join(work, "ogr.gpkg")
    run(["-level", "5", "--config", "QTMV_GPKG_DIRECT_ROWS", "NO"] + layers + centres + [through_ogr])
    check_gpkg(through_ogr, "GeoPackage (through OGR)")

    cog = os.path.join(work, "centres.tif")
    run(["-level", "8", "-of", "COG", "-raster", "lonlat", "-ts", "2048", "1024"] + centres + [cog])
    ds = gdal.Open(cog)
    warnings, errors, _ = validate_cloud_optimized_geotiff.validate(ds, full_check=True)
    overviews = ds.GetRasterBand(1).GetOverviewCount()
    ds = None
    if errors:
        failures.append("COG: validate_cloud_optimized_geotiff.py: %s" % errors)
    if overviews == 0:
        failures.append("COG: no overviews: the case no longer checks them")
    print("COG: %d overviews, %d errors, %d warnings" % (overviews, len(errors), len(warnings)))

for f in failures:
    print("FAILED: " + f)
sys.exit(1 if failures else 0)
