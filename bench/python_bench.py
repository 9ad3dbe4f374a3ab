#!/usr/bin/python3
"""The Python package's goals (issue 39), measured:

1. the grid: lon/lat to code (and code to centre) over numpy arrays on one core, in cells a
   second of CPU time (goal: at least 20 million a second);
2. a notebook's one call, qtmvoronoi.voronoi(frame of the country centres, level), against the
   tool on the same sites (process start to exit, -layers regions, GeoPackage on disk): the call
   split into writing the sites to /vsimem/, the run (the library's total) and making the result's
   GeoDataFrame (goal: the call within 10% of the tool's time plus that frame's construction).

    PYTHONPATH=build/python bench/python_bench.py [--tool build/tools/qtmvoronoi/qtmvoronoi]
        [--levels 9,12] [--repeat 5] [--device cpu]

Medians of --repeat runs, the tool and the call alternating (the machine may be shared).
"""

import argparse
import os
import statistics
import subprocess
import tempfile
import time

import numpy as np

import qtmvoronoi
from qtmvoronoi import conversions, run

HERE = os.path.dirname(os.path.abspath(__file__))
CENTRES = os.path.join(HERE, "..", "testdata", "country_centres.csv")


def grid_rates(samples, repeat):
    rng = np.random.default_rng(1)
    lon = rng.uniform(-180, 180, samples)
    lat = np.degrees(np.arcsin(rng.uniform(-1, 1, samples)))
    for level in (9, 16, 24):
        best_encode = best_decode = float("inf")
        for _ in range(repeat):
            t = time.process_time()
            codes = qtmvoronoi.lonlat_to_code(lon, lat, level)
            best_encode = min(best_encode, time.process_time() - t)
            t = time.process_time()
            qtmvoronoi.code_to_lonlat(codes, level)
            best_decode = min(best_decode, time.process_time() - t)
        print(f"grid level {level:2d}: lonlat_to_code {samples / best_encode / 1e6:6.1f} M/s, "
              f"code_to_lonlat {samples / best_decode / 1e6:6.1f} M/s  (one core, CPU time, {samples} points)")


def one_call(frame, level, device):
    """voronoi(frame, level) as voronoi() does it, each part timed: (seconds of the whole, of the sites, of the run, of the frame)."""
    t0 = time.perf_counter()
    directory = conversions.MemoryDirectory()
    try:
        source, description = conversions.sites_source(frame, directory)
        t1 = time.perf_counter()
        options = run.make_options(level, device=device)
        options.format = "GPKG"
        summary = run.execute(source, directory.file("result.gpkg"), options, description=description)
        t2 = time.perf_counter()
        conversions.read_layer(directory.file("result.gpkg"), "regions")
        t3 = time.perf_counter()
    finally:
        directory.remove()
    return t3 - t0, t1 - t0, t2 - t1, t3 - t2, summary.total_seconds


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--tool", default=os.path.join(HERE, "..", "build", "tools", "qtmvoronoi", "qtmvoronoi"))
    parser.add_argument("--levels", default="9,12")
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--samples", type=int, default=10_000_000)
    args = parser.parse_args()

    grid_rates(args.samples, args.repeat)

    import geopandas as gpd
    import pandas as pd

    table = pd.read_csv(CENTRES, float_precision="round_trip")
    frame = gpd.GeoDataFrame(table, geometry=gpd.points_from_xy(table.lon, table.lat), crs="EPSG:4326")
    with tempfile.TemporaryDirectory() as work:
        for level in map(int, args.levels.split(",")):
            tool, calls = [], []
            for _ in range(args.repeat):
                t = time.perf_counter()
                subprocess.run([args.tool, "-q", "-overwrite", "-device", args.device, "-level", str(level), "-layers", "regions",
                                "-oo", "X_POSSIBLE_NAMES=lon", "-oo", "Y_POSSIBLE_NAMES=lat", "-s_srs", "EPSG:4326",
                                CENTRES, os.path.join(work, "out.gpkg")], check=True)
                tool.append(time.perf_counter() - t)
                calls.append(one_call(frame, level, args.device))
            cli = statistics.median(tool)
            whole, sites, runs, result, library = (statistics.median(c[k] for c in calls) for k in range(5))
            print(f"level {level:2d}: tool {cli:.3f} s; voronoi() {whole:.3f} s = sites {sites:.3f} + run {runs:.3f} "
                  f"(library {library:.3f}) + result frame {result:.3f}; "
                  f"call less the frame / tool = {(whole - result) / cli:.2f}")


if __name__ == "__main__":
    main()
