#!/usr/bin/python3
"""The lon/lat raster's FID band against scipy's cKDTree (bench/ckdtree_raster.py), where the two
agree by definition: a pixel takes the site nearest to the centre of the cell that holds its
centre, which lies within a cell's size of the pixel centre; where the pixel centre's second
nearest site is farther than its nearest by more than twice that, every point that near has the
same nearest site, so the FIDs must be equal. Run at level 13 (cells of about 1.2 km) on 1-degree
and 0.25-degree pixels of the 241 country centres (FIDs 1.. as GDAL's CSV driver numbers them).

  ckdtree_oracle_test.py QTMVORONOI TESTDATA BENCH_DIR
"""
import math
import os
import subprocess
import sys
import tempfile

import numpy as np
from osgeo import gdal

gdal.UseExceptions()
tool, testdata, bench = sys.argv[1], sys.argv[2], sys.argv[3]
centres = os.path.join(testdata, "country_centres.csv")
LEVEL = 13
# A cell's centre lies within its size of any of its points: rows of 90 / 2^L degrees, cells at
# most about twice as wide where an octant's rows are short; taken generously.
CELL_RADIANS = 4 * math.radians(90.0 / 2 ** LEVEL)
failures = []

with tempfile.TemporaryDirectory() as work:
    for tr in ("1", "0.25"):
        tool_tif, ref_tif, k2 = (os.path.join(work, n) for n in (f"tool{tr}.tif", f"ref{tr}.tif", f"k2_{tr}.npy"))
        r = subprocess.run([tool, "-q", "-device", "cpu", "-level", str(LEVEL), "-tr", tr, tr, "-bands", "fid",
                            "-oo", "X_POSSIBLE_NAMES=lon", "-oo", "Y_POSSIBLE_NAMES=lat", centres, tool_tif],
                           capture_output=True, text=True)
        if r.returncode != 0:
            sys.exit(f"qtmvoronoi failed: {r.stderr}")
        r = subprocess.run(["/usr/bin/python3", os.path.join(bench, "ckdtree_raster.py"), "--tr", tr, "--bands", "fid",
                            "--k2", k2, centres, ref_tif], capture_output=True, text=True)
        if r.returncode != 0:
            sys.exit(f"ckdtree_raster.py failed: {r.stderr}")
        a, b = gdal.Open(tool_tif), gdal.Open(ref_tif)
        if (a.RasterXSize, a.RasterYSize, a.GetGeoTransform()) != (b.RasterXSize, b.RasterYSize, b.GetGeoTransform()):
            failures.append(f"-tr {tr}: grids differ: {a.RasterXSize}x{a.RasterYSize} {a.GetGeoTransform()} vs "
                            f"{b.RasterXSize}x{b.RasterYSize} {b.GetGeoTransform()}")
            continue
        fid_tool = a.GetRasterBand(1).ReadAsArray()
        fid_ref = b.GetRasterBand(1).ReadAsArray()
        gap = np.load(k2)  # second minus first nearest chord; a chord c is the angle 2 asin(c / 2)
        # A chord's angle grows faster than the chord: the angles' gap is at least the chords'.
        clear = gap > 2 * CELL_RADIANS
        checked = int(clear.sum())
        differ = int((fid_tool[clear] != fid_ref[clear]).sum())
        print(f"-tr {tr}: {fid_tool.size} pixels, {checked} clear of a tie, {differ} with another FID; "
              f"{int((fid_tool != fid_ref).sum())} differ in all")
        if checked < 0.97 * fid_tool.size:
            failures.append(f"-tr {tr}: only {checked} of {fid_tool.size} pixels clear of a tie")
        if differ:
            ys, xs = np.nonzero(clear & (fid_tool != fid_ref))
            failures.append(f"-tr {tr}: {differ} pixels clear of a tie with another FID, e.g. pixel ({xs[0]}, {ys[0]}): "
                            f"tool {fid_tool[ys[0], xs[0]]}, cKDTree {fid_ref[ys[0], xs[0]]}")

for f in failures:
    print("FAIL:", f)
sys.exit(1 if failures else 0)
