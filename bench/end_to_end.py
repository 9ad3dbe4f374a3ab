#!/usr/bin/env python3
"""The end-to-end benchmark: qtmvoronoi as a user runs it, process start to exit.

Each case runs the tool `--repeat` times, each run with its destination removed and the page
cache's writes flushed before it (outside the timing: see settle); the table gives the median wall time, the peak host
memory (the child's maximum resident set, from wait4) and the stage times of the tool's summary
line (read / label / write). Ratios are taken within one run of this script, on one machine.

  bench/end_to_end.py --tool PATH [--device cuda|cpu|both|cuda:all|cuda:0,1] [--cases NAMES] [--repeat N]
                      [--threads N[,M...]] [--csv OUT] [--data DIR] [--tiles N]

--threads N,M,...: each case once per -threads value (0: the tool's default, all cores), on every
device (the readers and writers run on the host's cores whatever labels), for the sweep that shows
whether a stage gets slower with more threads.

--tiles N: each vector case also as N tile jobs (-tile K/N) run one after another, then the merge
(-merge); its wall time is the sum of all N + 1 processes, its peak memory the largest of them, and
its regions are compared with the whole run's (the rows of the GeoPackage's regions table).

PATH is the qtmvoronoi binary or the bundle's bin/qtmvoronoi wrapper (scripts/make_bundle.sh).
The inputs: testdata/country_centres.csv (241 points), and 135 233 and 1 000 000 points spread evenly
over the sphere (seeded; written here as CSV, so that no GDAL tool is needed on the machine, and the
million also as a GeoPackage written with sqlite3: the points1m-gpkg cases); for the
polygon cases, Natural Earth's 50m countries and 10m land as GeoPackages in --data DIR (made by
bench/make_natural_earth.sh where GDAL's tools are; copied to the GPU machine with the bundle).
Standard library only: it runs on the GPU machine too.
"""
import argparse
import csv
import math
import os
import random
import re
import shutil
import statistics
import sqlite3
import struct
import hashlib
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
CENTRES = os.path.join(HERE, "..", "testdata", "country_centres.csv")
CSV_OPTIONS = ["-oo", "X_POSSIBLE_NAMES=lon", "-oo", "Y_POSSIBLE_NAMES=lat", "-s_srs", "EPSG:4326"]

# name: (input, level, layers, devices it runs on)
CASES = {
    "centres-L10-regions": ("centres", 10, "regions", ("cpu", "cuda")),
    "centres-L12-regions": ("centres", 12, "regions", ("cpu", "cuda")),
    "centres-L15-regions": ("centres", 15, "regions", ("cuda",)),
    "centres-L16-regions": ("centres", 16, "regions", ("cuda",)),
    "centres-L17-regions": ("centres", 17, "regions", ("cuda",)),
    "centres-L20-regions": ("centres", 20, "regions", ("cuda",)),
    "points135k-L16-regions": ("points", 16, "regions", ("cuda",)),
    "points135k-L17-regions": ("points", 17, "regions", ("cuda",)),
    "centres-L13-regions+edges": ("centres", 13, "regions,voronoi_edges", ("cpu", "cuda")),
    "centres-L14-regions+edges": ("centres", 14, "regions,voronoi_edges", ("cpu", "cuda")),
    "centres-L15-regions+edges": ("centres", 15, "regions,voronoi_edges", ("cpu", "cuda")),
    "centres-L16-regions+edges": ("centres", 16, "regions,voronoi_edges", ("cuda",)),
    "centres-L17-regions+edges": ("centres", 17, "regions,voronoi_edges", ("cuda",)),
    "centres-L18-regions+edges": ("centres", 18, "regions,voronoi_edges", ("cuda",)),
    "points135k-L13-regions": ("points", 13, "regions", ("cpu", "cuda")),
    "points1m-L10-regions": ("points1m", 10, "regions", ("cpu", "cuda")),
    "points1m-L12-regions": ("points1m", 12, "regions", ("cpu", "cuda")),
    "points1m-L14-regions": ("points1m", 14, "regions", ("cpu", "cuda")),
    "points1m-L16-regions": ("points1m", 16, "regions", ("cuda",)),
    "points10m-L14-regions": ("points10m", 14, "regions", ("cuda",)),
    "points1m-gpkg-L10-regions": ("points1m-gpkg", 10, "regions", ("cpu", "cuda")),
    "points1m-gpkg-L14-regions": ("points1m-gpkg", 14, "regions", ("cpu", "cuda")),
    "points1m-gpkg-L16-regions": ("points1m-gpkg", 16, "regions", ("cuda",)),
    "points135k-L15-regions": ("points", 15, "regions", ("cpu", "cuda")),
    "points135k-L11-tif": ("points", 11, "tif", ("cpu", "cuda")),
    "points135k-L13-tif": ("points", 13, "tif", ("cpu", "cuda")),
    "countries50-L10-regions": ("countries50", 10, "regions", ("cpu", "cuda")),
    "countries50-L12-regions": ("countries50", 12, "regions", ("cpu", "cuda")),
    "countries50-L14-regions": ("countries50", 14, "regions", ("cuda",)),
    "land10-L12-regions": ("land10", 12, "regions", ("cpu", "cuda")),
    "land10-L14-regions": ("land10", 14, "regions", ("cuda",)),
}
# Natural Earth inputs in --data: file and layer.
NATURAL_EARTH = {"countries50": ("countries50.gpkg", "countries"), "land10": ("land10.gpkg", "land")}

CHOSEN = re.compile(r"cells; (?:auto: )?([^;(,]+?)[ ;(,]")
SUMMARY = re.compile(r"read ([0-9.]+) s .*label ([0-9.]+) s \(prepare ([0-9.]+) s\), write ([0-9.]+) s; total ([0-9.]+) s")


def even_points(path, n=135233, seed=135233):
    rng = random.Random(seed)
    with open(path, "w") as f:
        f.write("id,lon,lat\n")
        for k in range(n):
            z = rng.uniform(-1.0, 1.0)
            lon = rng.uniform(-180.0, 180.0)
            f.write("%d,%.7f,%.7f\n" % (k, lon, math.degrees(math.asin(z))))


def points_geopackage(csv_path, gpkg_path):
    """The points of a CSV of id,lon,lat (even_points) as a GeoPackage of one point layer in
    EPSG:4326 with its R-tree, written with sqlite3 (no GDAL on the GPU machine): the same sites in
    the format a user's million points often come in, read by GDAL's GeoPackage driver rather than
    its CSV parser."""
    if os.path.exists(gpkg_path):
        os.remove(gpkg_path)
    name = os.path.splitext(os.path.basename(gpkg_path))[0]
    db = sqlite3.connect(gpkg_path)
    db.execute("PRAGMA application_id = 1196444487")  # 'GPKG'
    db.execute("PRAGMA user_version = 10300")
    db.executescript("""
        CREATE TABLE gpkg_spatial_ref_sys (srs_name TEXT NOT NULL, srs_id INTEGER PRIMARY KEY, organization TEXT NOT NULL,
            organization_coordsys_id INTEGER NOT NULL, definition TEXT NOT NULL, description TEXT);
        CREATE TABLE gpkg_contents (table_name TEXT NOT NULL PRIMARY KEY, data_type TEXT NOT NULL, identifier TEXT UNIQUE,
            description TEXT DEFAULT '', last_change DATETIME NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now')),
            min_x DOUBLE, min_y DOUBLE, max_x DOUBLE, max_y DOUBLE, srs_id INTEGER);
        CREATE TABLE gpkg_geometry_columns (table_name TEXT NOT NULL, column_name TEXT NOT NULL, geometry_type_name TEXT NOT NULL,
            srs_id INTEGER NOT NULL, z TINYINT NOT NULL, m TINYINT NOT NULL, PRIMARY KEY (table_name, column_name));""")
    wgs84 = ('GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563,AUTHORITY["EPSG","7030"]],'
             'AUTHORITY["EPSG","6326"]],PRIMEM["Greenwich",0,AUTHORITY["EPSG","8901"]],UNIT["degree",0.0174532925199433,'
             'AUTHORITY["EPSG","9122"]],AXIS["Latitude",NORTH],AXIS["Longitude",EAST],AUTHORITY["EPSG","4326"]]')
    db.executemany("INSERT INTO gpkg_spatial_ref_sys VALUES (?, ?, ?, ?, ?, ?)",
                   [("Undefined cartesian SRS", -1, "NONE", -1, "undefined", None),
                    ("Undefined geographic SRS", 0, "NONE", 0, "undefined", None),
                    ("WGS 84 geodetic", 4326, "EPSG", 4326, wgs84, None)])
    db.execute("INSERT INTO gpkg_contents (table_name, data_type, identifier, min_x, min_y, max_x, max_y, srs_id) "
               "VALUES (?, 'features', ?, -180, -90, 180, 90, 4326)", (name, name))
    db.execute("INSERT INTO gpkg_geometry_columns VALUES (?, 'geom', 'POINT', 4326, 0, 0)", (name,))
    db.execute('CREATE TABLE "%s" (fid INTEGER PRIMARY KEY AUTOINCREMENT NOT NULL, geom POINT, id INTEGER)' % name)
    # A GeoPackage geometry: "GP", version 0, flags 1 (little-endian, no envelope), the SRS id, then WKB.
    header = b"GP\x00\x01" + struct.pack("<i", 4326)
    with open(csv_path) as f:
        next(f)
        rows = ((header + struct.pack("<BIdd", 1, 1, float(lon), float(lat)), int(k))
                for k, lon, lat in (line.split(",") for line in f))
        db.executemany('INSERT INTO "%s" (geom, id) VALUES (?, ?)' % name, rows)
    # The spatial index GDAL writes (the gpkg_rtree_index extension), so that a tile job (-tile
    # K/N) reads only the points near its tile. The triggers are GDAL's, for a valid file: they
    # only run when the table is edited, where GDAL (SpatiaLite's ST_ functions) is there.
    db.executescript("""
        CREATE TABLE gpkg_extensions (table_name TEXT, column_name TEXT, extension_name TEXT NOT NULL,
            definition TEXT NOT NULL, scope TEXT NOT NULL, CONSTRAINT ge_tce UNIQUE (table_name, column_name, extension_name));
        CREATE VIRTUAL TABLE "rtree_%s_geom" USING rtree(id, minx, maxx, miny, maxy);""" % name)
    db.execute("INSERT INTO gpkg_extensions VALUES (?, 'geom', 'gpkg_rtree_index', "
               "'http://www.geopackage.org/spec120/#extension_rtree', 'write-only')", (name,))
    with open(csv_path) as f:
        next(f)
        db.executemany('INSERT INTO "rtree_%s_geom" VALUES (?, ?, ?, ?, ?)' % name,
                       ((fid, float(lon), float(lon), float(lat), float(lat))
                        for fid, (k, lon, lat) in enumerate((line.split(",") for line in f), start=1)))
    t, r = '"%s"' % name, '"rtree_%s_geom"' % name
    box = 'VALUES (NEW.fid, ST_MinX(NEW.geom), ST_MaxX(NEW.geom), ST_MinY(NEW.geom), ST_MaxY(NEW.geom))'
    filled, empty = "NEW.geom NOTNULL AND NOT ST_IsEmpty(NEW.geom)", "NEW.geom ISNULL OR ST_IsEmpty(NEW.geom)"
    for trigger, event, when, body in (
            ("insert", "INSERT", filled, "INSERT OR REPLACE INTO %s " + box),
            ("update1", "UPDATE OF geom", "OLD.fid = NEW.fid AND (%s)" % filled, "INSERT OR REPLACE INTO %s " + box),
            ("update2", "UPDATE OF geom", "OLD.fid = NEW.fid AND (%s)" % empty, "DELETE FROM %s WHERE id = OLD.fid"),
            ("update3", "UPDATE", "OLD.fid != NEW.fid AND (%s)" % filled,
             "DELETE FROM %s WHERE id = OLD.fid; INSERT OR REPLACE INTO %s " + box),
            ("update4", "UPDATE", "OLD.fid != NEW.fid AND (%s)" % empty, "DELETE FROM %s WHERE id IN (OLD.fid, NEW.fid)"),
            ("delete", "DELETE", "OLD.geom NOT NULL", "DELETE FROM %s WHERE id = OLD.fid")):
        db.execute('CREATE TRIGGER "rtree_%s_geom_%s" AFTER %s ON %s WHEN %s BEGIN %s; END'
                   % (name, trigger, event, t, when, body.replace("%s", r)))
    db.commit()
    db.close()


def settle(path):
    """Before a timed run, outside its time: the previous run's output removed and the page cache's
    writes flushed, so that a run pays neither for deleting the file it replaces nor for writing
    back the one before (seconds at the finer levels: bench/RESULTS.md, session 12)."""
    if os.path.isdir(path):
        shutil.rmtree(path)
    elif os.path.exists(path):
        os.remove(path)
    os.sync()


def run_once(command):
    """Wall seconds, peak resident set (bytes), exit status, stderr of one run."""
    start = time.monotonic()
    child = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    err = child.stderr.read().decode(errors="replace")
    _, status, usage = os.wait4(child.pid, 0)
    wall = time.monotonic() - start
    child.returncode = os.waitstatus_to_exitcode(status)
    return wall, usage.ru_maxrss * 1024, child.returncode, err


def regions_digest(path):
    """md5 of the regions table's rows (a GeoPackage's own timestamps aside)."""
    h = hashlib.md5()
    with sqlite3.connect(path) as db:
        for row in db.execute("select * from regions order by 1"):
            h.update(repr(row).encode())
    return h.hexdigest()


def run_tiles(args, command, whole_out, name, device, level, layers, whole_wall):
    """The case as args.tiles tile jobs one after another, then the merge; repeated, median."""
    source, out = command[-2], command[-1]
    tile_dir = out + ".tiles"
    os.makedirs(tile_dir, exist_ok=True)
    merged = out.replace(".gpkg", "-merged.gpkg")
    reading = [a for a in command[1:-2] if a != "-layers" and a != layers]
    totals, peaks = [], []
    for _ in range(args.repeat):
        total, peak = 0.0, 0
        for k in range(1, args.tiles + 1):
            wall, rss, status, err = run_once([command[0]] + reading + ["-tile", "%d/%d" % (k, args.tiles), source,
                                                                         os.path.join(tile_dir, "%d.qtmt" % k)])
            if status != 0:
                sys.exit("tile %d failed: %s" % (k, err))
            total, peak = total + wall, max(peak, rss)
        merge_command = command[:-2] + ["-merge", tile_dir, source, merged]
        wall, rss, status, err = run_once(merge_command)
        if status != 0:
            sys.exit("merge failed: %s" % err)
        totals.append(total + wall)
        peaks.append(max(peak, rss))
    wall = statistics.median(totals)
    same = regions_digest(merged) == regions_digest(whole_out)
    print("| %s | %s, %d tiles one after another + merge | %.2f (%.2fx the whole run) | %.0f | regions %s |" %
          (name, device, args.tiles, wall, wall / whole_wall, max(peaks) / 1e6, "identical" if same else "DIFFER"))
    sys.stdout.flush()
    return {"case": name, "device": "%s %d tiles+merge" % (device, args.tiles), "level": level, "layers": layers,
            "wall_s": "%.3f" % wall, "peak_mb": "%.0f" % (max(peaks) / 1e6), "read_s": 0, "label_s": 0, "write_s": 0,
            "walls": " ".join("%.3f" % t for t in totals),
            "command": "for K in 1..%d: %s -tile K/%d %s TILE; %s" % (args.tiles, command[0], args.tiles,
                                                                 " ".join(reading[1:]), " ".join(merge_command))}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tool", required=True)
    parser.add_argument("--device", default="both", help="cpu, cuda, both, or any -device value (cuda:all, cuda:0,1, auto: every case, the choice shown)")
    parser.add_argument("--tiles", type=int, default=0, help="also run each vector case as N tile jobs and a merge")
    parser.add_argument("--cases", default=",".join(CASES), help="comma-separated case names")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--threads", default="0", help="-threads values, comma-separated, each a row (0: the default)")
    parser.add_argument("--csv", help="also write the rows here")
    parser.add_argument("--keep", help="directory for the outputs (default: a temporary one)")
    parser.add_argument("--data", default=os.path.join(HERE, "..", "build", "bench-data"),
                        help="directory of bench/make_natural_earth.sh's GeoPackages")
    args = parser.parse_args()

    work = args.keep or tempfile.mkdtemp(prefix="qtmv_e2e_")
    # The evenly spread points: the input's name, its count and its seed.
    spread = {"points": (135233, 135233), "points1m": (1000000, 1000000), "points10m": (10000000, 10000000)}
    inputs = {"centres": CENTRES}
    names = [c for c in args.cases.split(",") if c]
    for source, (count, seed) in spread.items():
        inputs[source] = os.path.join(work, "%s.csv" % source)
        if any(CASES[c][0] in (source, source + "-gpkg") for c in names):
            even_points(inputs[source], count, seed)
        if any(CASES[c][0] == source + "-gpkg" for c in names):
            inputs[source + "-gpkg"] = os.path.join(work, "%s.gpkg" % source)
            points_geopackage(inputs[source], inputs[source + "-gpkg"])
    thread_counts = [int(t) for t in args.threads.split(",") if t]
    devices = ["cpu", "cuda"] if args.device == "both" else [args.device]
    kind = lambda device: "cuda" if device.startswith("cuda") else device

    rows = []
    print("| case | device | wall s (median of %d) | peak host memory MB | read / label / write s | outline output MB |" % args.repeat)
    print("|---|---|---|---|---|---|")
    for name in names:
        source, level, layers, allowed = CASES[name]
        for device, threads in [(d, t) for d in devices for t in thread_counts]:
            if device != "auto" and kind(device) not in allowed:
                continue
            raster = layers == "tif"
            out = os.path.join(work, "%s-%s.%s" % (name, device, "tif" if raster else "gpkg"))
            command = [args.tool, "-overwrite", "-device", device, "-level", str(level)]
            if not raster:
                command += ["-layers", layers]
            if threads:
                command += ["-threads", str(threads)]
            label = device + (" -threads %d" % threads if threads else "")
            if source in NATURAL_EARTH:
                file, layer = NATURAL_EARTH[source]
                command += ["-l", layer, os.path.join(args.data, file), out]
            elif source.endswith("-gpkg"):
                command += [inputs[source], out]
            else:
                command += CSV_OPTIONS + [inputs[source], out]
            runs = []
            for _ in range(args.repeat):
                settle(command[-1])
                runs.append(run_once(command))
            failed = [r for r in runs if r[2] != 0]
            if failed:
                print("| %s | %s | failed (exit %d): %s |" % (name, label, failed[0][2], failed[0][3].strip().splitlines()[-1]))
                sys.stdout.flush()
                continue
            wall = statistics.median(r[0] for r in runs)
            peak = max(r[1] for r in runs) / 1e6
            stages = [SUMMARY.search(r[3]) for r in runs]
            stage = [statistics.median(float(m.group(g)) for m in stages if m) for g in (1, 2, 4)] if all(stages) else [0, 0, 0]
            size = os.path.getsize(out) / 1e6
            if device == "auto":  # the device auto chose, from the summary line
                chosen = CHOSEN.search(runs[0][3])
                label = "auto (%s)" % (chosen.group(1) if chosen else "?")
            print("| %s | %s | %.2f | %.0f | %.2f / %.2f / %.2f | %.1f |" % (name, label, wall, peak, *stage, size))
            sys.stdout.flush()
            rows.append({"case": name, "device": label, "level": level, "layers": layers, "wall_s": "%.3f" % wall,
                         "peak_mb": "%.0f" % peak, "read_s": stage[0], "label_s": stage[1], "write_s": stage[2],
                         "walls": " ".join("%.3f" % r[0] for r in runs), "command": " ".join(command)})
            if args.tiles and not raster:
                rows.append(run_tiles(args, command, out, name, device, level, layers, wall))
    if args.csv and rows:
        with open(args.csv, "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)


if __name__ == "__main__":
    main()
