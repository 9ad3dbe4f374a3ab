#!/usr/bin/python3
"""Checks the spatial indexes of GeoPackages as SQLite and GDAL use them, and that two files answer
every spatial query alike: for each file SQLite's `PRAGMA integrity_check` and `rtreecheck()` of
each R-tree, GDAL's validate_gpkg (its errors, less the known false one of GDAL 3.6's validator,
which reads the empty-geometry flag from the wrong bit), and for each indexed layer a set of
windows queried through the R-tree (SQL on the rtree table: never fewer rows than a scan of the
rows' envelopes finds) and through OGR's spatial filter (which uses it). With two files, every
window's FIDs, both ways, must be the same.

    /usr/bin/python3 bench/gpkg_rtree_check.py NEW.gpkg [OLD.gpkg] [--windows N]

Run with Debian's Python (it has osgeo). Prints one line per check; exits 1 if any fails.
"""
import random
import sqlite3
import struct
import sys

from osgeo import gdal, ogr

gdal.UseExceptions()


def rtrees(path):
    """(table, geometry column, rtree name) of the file's indexed layers."""
    db = sqlite3.connect(path)
    out = []
    for table, column in db.execute("SELECT table_name, column_name FROM gpkg_geometry_columns ORDER BY table_name"):
        name = "rtree_%s_%s" % (table, column)
        if db.execute("SELECT 1 FROM sqlite_master WHERE name = ?", (name,)).fetchone():
            out.append((table, column, name))
    db.close()
    return out


def envelopes(db, table, column):
    """fid -> (min x, max x, min y, max y) from each non-empty geometry blob's header."""
    out = {}
    for fid, blob in db.execute('SELECT fid, "%s" FROM "%s"' % (column, table)):
        if blob is None or blob[3] & 0x10:
            continue
        kind = (blob[3] >> 1) & 7
        if kind == 0:
            continue
        out[fid] = struct.unpack_from("<dddd", blob, 8)
    return out


def windows(count, seed):
    rng = random.Random(seed)
    out = [(-180.0, 180.0, -90.0, 90.0), (179.0, 180.0, -90.0, 90.0), (-10.0, 10.0, 89.0, 90.0)]
    while len(out) < count:
        x, y = rng.uniform(-180, 180), rng.uniform(-90, 90)
        w, h = 10 ** rng.uniform(-3, 2), 10 ** rng.uniform(-3, 1.5)
        out.append((x, min(180.0, x + w), y, min(90.0, y + h)))
    return out


def answers(path, count):
    """Per indexed layer, the FIDs of each window: from the rtree table, from OGR's spatial
    filter, and from a scan; with the problems found."""
    problems = []
    db = sqlite3.connect(path)
    if db.execute("PRAGMA integrity_check").fetchone()[0] != "ok":
        problems.append("integrity_check failed")
    found = {}
    ds = ogr.Open(path)
    for table, column, rtree in rtrees(path):
        check = db.execute("SELECT rtreecheck(?)", (rtree,)).fetchone()[0]
        if check != "ok":
            problems.append("rtreecheck(%s): %s" % (rtree, check))
        boxes = envelopes(db, table, column)
        layer = ds.GetLayerByName(table)
        for k, (x0, x1, y0, y1) in enumerate(windows(count, sum(table.encode()))):
            tree = sorted(r[0] for r in db.execute(
                'SELECT id FROM "%s" WHERE maxx >= ? AND minx <= ? AND maxy >= ? AND miny <= ?' % rtree, (x0, x1, y0, y1)))
            # The tree's float32 boxes hold the double ones: it may find a few more, never fewer.
            scan = sorted(f for f, (a, b, c, d) in boxes.items() if b >= x0 and a <= x1 and d >= y0 and c <= y1)
            missed = set(scan) - set(tree)
            if missed:
                problems.append("%s window %d: the R-tree misses %d rows" % (table, k, len(missed)))
            layer.SetSpatialFilterRect(x0, y0, x1, y1)
            filtered = sorted(f.GetFID() for f in layer)  # GDAL may test the geometries too
            found[(table, k)] = (tree, filtered)
        layer.SetSpatialFilter(None)
    ds = None
    db.close()
    return found, problems


def validator_errors(path):
    from osgeo_utils.samples import validate_gpkg
    checker = validate_gpkg.GPKGChecker(path, abort_at_first_error=False, warning_msg=False)
    try:
        checker.check()
    except Exception as e:  # noqa: BLE001 - a crash of the validator is a finding too
        return ["validator stopped: %s" % e]
    return ["Req %s: %s" % e for e in checker.errors if "empty_flag" not in e[1]]


def main(argv):
    count = 200
    if "--windows" in argv:
        at = argv.index("--windows")
        count = int(argv[at + 1])
        del argv[at:at + 2]
    paths = argv[1:]
    failed = False
    results = []
    for path in paths:
        found, problems = answers(path, count)
        problems += validator_errors(path)
        layers = sorted({t for t, _ in found})
        print("%s: R-trees of %s; integrity_check, rtreecheck, validate_gpkg, %d windows each: %s" % (
            path, ", ".join(layers) or "no layer", count, "ok" if not problems else "; ".join(problems[:5])))
        failed = failed or bool(problems)
        results.append(found)
    if len(results) == 2:
        differ = [key for key in results[0] if results[0][key] != results[1].get(key)]
        differ += [key for key in results[1] if key not in results[0]]
        print("same answers to %d window queries: %s" % (len(results[0]), "yes" if not differ else "NO (%s)" % differ[:5]))
        failed = failed or bool(differ)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
