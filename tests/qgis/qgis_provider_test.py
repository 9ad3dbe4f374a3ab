#!/usr/bin/python3
"""The QGIS Processing provider (qgis/qtmvoronoi_processing), headless: it shows in
`qgis_process list`; `qgis_process run` of each algorithm gives what the tool gives run by hand;
through the Python API, selected features only, a cancel (nothing left behind) and a failure
(the tool's message and exit status in the exception).

    qgis_provider_test.py QTMVORONOI SOURCE_DIR TESTDATA_DIR
"""

import hashlib
import os
import shutil
import sqlite3
import subprocess
import sys
import tempfile

tool, source_dir, testdata = sys.argv[1:4]
work = tempfile.mkdtemp(prefix="qtmv_qgis_")
profile = os.path.join(work, "profile")
plugins = os.path.join(profile, "profiles", "default", "python", "plugins")
os.makedirs(plugins)
os.symlink(os.path.join(source_dir, "qgis", "qtmvoronoi_processing"), os.path.join(plugins, "qtmvoronoi_processing"))
os.environ.update(QT_QPA_PLATFORM="offscreen", QGIS_CUSTOM_CONFIG_PATH=profile, QTMVORONOI=tool,
                  XDG_RUNTIME_DIR=work)
# Debian's /usr/bin/qgis_process wrapper passes an option (--noversioncheck) that qgis_process
# 3.22 refuses; the binary beside it is the tool itself.
qgis_process = shutil.which("qgis_process.bin") or shutil.which("qgis_process")
countries = os.path.join(testdata, "world_atlas_countries_110m.gpkg")
failures = []


def check(ok, what):
    print(("ok   " if ok else "FAIL ") + what)
    sys.stdout.flush()
    if not ok:
        failures.append(what)


def run(command):
    return subprocess.run(command, capture_output=True, text=True)


def rows_digest(path, table):
    h = hashlib.md5()
    for row in sqlite3.connect(path).execute('SELECT * FROM "%s" ORDER BY 1' % table):
        h.update(repr(row).encode())
    return h.hexdigest()


def file_digest(path):
    with open(path, "rb") as f:
        return hashlib.md5(f.read()).hexdigest()


# --- qgis_process ------------------------------------------------------------------------------
r = run([qgis_process, "plugins", "enable", "qtmvoronoi_processing"])
check(r.returncode == 0, "qgis_process plugins enable qtmvoronoi_processing: " + r.stderr[-300:])
r = run([qgis_process, "list"])
check("qtmvoronoi:voronoiregions" in r.stdout and "qtmvoronoi:voronoiraster" in r.stdout,
      "qgis_process list shows both algorithms")

regions = os.path.join(work, "qgis_regions.gpkg")
r = run([qgis_process, "run", "qtmvoronoi:voronoiregions", "--", "INPUT=%s|layername=countries_110m" % countries,
         "LEVEL=6", "DISTANCE=0", "DEVICE=1", "LAYERS=0,1", "OUTPUT=" + regions])
check(r.returncode == 0, "qgis_process run voronoiregions: " + r.stdout[-500:] + r.stderr[-500:])
by_hand = os.path.join(work, "tool_regions.gpkg")
run([tool, "-q", "-level", "6", "-distance", "exact", "-device", "cpu", "-layers", "regions,voronoi_edges",
     "-l", "countries_110m", countries, by_hand])
if os.path.exists(regions):
    for table in ("regions", "voronoi_edges"):
        check(rows_digest(regions, table) == rows_digest(by_hand, table), "voronoiregions' %s equal the tool's" % table)
    check(sqlite3.connect(regions).execute("SELECT count(*) FROM regions").fetchone()[0] == 177, "177 regions")

raster = os.path.join(work, "qgis_raster.tif")
r = run([qgis_process, "run", "qtmvoronoi:voronoiraster", "--", "INPUT=%s|layername=countries_110m" % countries,
         "LEVEL=6", "DEVICE=1", "LAYOUT=1", "PIXEL_SIZE=2", "DATA_TYPE=5", "OUTPUT=" + raster])
check(r.returncode == 0, "qgis_process run voronoiraster: " + r.stdout[-500:] + r.stderr[-500:])
raster_by_hand = os.path.join(work, "tool_raster.tif")
run([tool, "-q", "-level", "6", "-device", "cpu", "-raster", "lonlat", "-tr", "2.0", "2.0", "-ot", "Int32",
     "-l", "countries_110m", countries, raster_by_hand])
check(os.path.exists(raster) and file_digest(raster) == file_digest(raster_by_hand),
      "voronoiraster's GeoTIFF equals the tool's, byte for byte")

# --- the Python API: selection, cancel, failure -------------------------------------------------
sys.path.insert(0, "/usr/share/qgis/python/plugins")
sys.path.insert(0, os.path.join(source_dir, "qgis"))
from qgis.core import (QgsApplication, QgsProcessingException, QgsProcessingFeatureSourceDefinition,  # noqa: E402
                       QgsProcessingFeedback, QgsProject, QgsVectorLayer)

app = QgsApplication([], False)
app.initQgis()
from processing.core.Processing import Processing  # noqa: E402
import processing  # noqa: E402
from qtmvoronoi_processing.provider import QtmvoronoiProvider  # noqa: E402

Processing.initialize()
provider = QtmvoronoiProvider()  # kept: the registry does not own a Python provider
QgsApplication.processingRegistry().addProvider(provider)

layer = QgsVectorLayer(countries + "|layername=countries_110m", "countries", "ogr")
QgsProject.instance().addMapLayer(layer)
chosen = sorted(f.id() for f in layer.getFeatures())[10:15]
layer.selectByIds(chosen)
selected = os.path.join(work, "selected.gpkg")
processing.run("qtmvoronoi:voronoiregions", {
    "INPUT": QgsProcessingFeatureSourceDefinition(layer.id(), selectedFeaturesOnly=True),
    "LEVEL": 5, "DEVICE": 1, "LAYERS": [0], "OUTPUT": selected})
n = sqlite3.connect(selected).execute("SELECT count(*) FROM regions").fetchone()[0]
check(n == len(chosen), "selected features only: %d regions for %d selected" % (n, len(chosen)))


class CancelAtFirstProgress(QgsProcessingFeedback):
    def __init__(self):
        super().__init__()
        self.seen = []
        self.progressChanged.connect(self.on_progress)

    def on_progress(self, value):
        self.seen.append(value)
        if value > 0:
            self.cancel()


stopped = os.path.join(work, "stopped.gpkg")
feedback = CancelAtFirstProgress()
try:
    processing.run("qtmvoronoi:voronoiregions", {"INPUT": countries + "|layername=countries_110m", "LEVEL": 10,
                                                   "DEVICE": 1, "LAYERS": [0, 2], "OUTPUT": stopped}, feedback=feedback)
    check(False, "a cancelled run raises")
except QgsProcessingException as e:
    check("cancelled" in str(e), "a cancelled run says so: " + str(e))
check(not os.path.exists(stopped), "a cancelled run leaves no output")
check(any(0 < v < 100 for v in feedback.seen), "the tool's progress reaches the feedback: %s" % feedback.seen[:5])

try:
    processing.run("qtmvoronoi:voronoiregions", {"INPUT": countries + "|layername=countries_110m", "LEVEL": 24,
                                                   "DEVICE": 1, "LAYERS": [3], "OUTPUT": os.path.join(work, "big.gpkg")})
    check(False, "a run the tool refuses raises")
except QgsProcessingException as e:
    check("exit status 1" in str(e) and "needs about" in str(e), "the tool's refusal and exit status: " + str(e))

app.exitQgis()
shutil.rmtree(work, ignore_errors=True)
print("%d failure(s)" % len(failures))
sys.exit(1 if failures else 0)
