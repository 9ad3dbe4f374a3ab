#!/usr/bin/env python3
"""A PostgreSQL/PostGIS destination (PG:...) written all or nothing (issue 36), on the throwaway
cluster pg_virtualenv starts (postgis_destination_test.sh; the PG* variables name it):

- PostGIS's geodesic area (ST_Area of geography) of each region is its area_m2;
- every layer's rows and geometries read back equal the GeoPackage output's of the same run (Real
  fields to 1e-12: GDAL 3.6's PostgreSQL driver writes them as text of 15 significant digits or
  fewer, OGRFormatDouble's, so 411697493366.1709 becomes 411697493366.171);
- an existing table without -overwrite: 1 before any work, naming it, the tables untouched;
- -overwrite replaces only the layers written, and keeps the user's other tables;
- a run failing late (a bad -lco found at the write) or stopped by SIGINT while writing leaves
  the old tables as they were, and no staging schema;
- two runs at once without -overwrite: one writes, the other fails naming the table.

  postgis_destination_test.py QTMVORONOI TESTDATA
"""
import os
import signal
import subprocess
import sys
import tempfile
import time

from osgeo import gdal, ogr

gdal.UseExceptions()
tool, testdata = sys.argv[1], sys.argv[2]
DB = "PG:dbname=" + os.environ.get("PGDATABASE", "postgres")
centres = ["-oo", "X_POSSIBLE_NAMES=lon", "-oo", "Y_POSSIBLE_NAMES=lat", "-s_srs", "EPSG:4326",
           os.path.join(testdata, "country_centres.csv")]
ALL = "regions,boundary_cells,voronoi_edges,cells"
failures = []


def check(ok, what):
    print(("ok: " if ok else "FAILED: ") + what)
    if not ok:
        failures.append(what)


def sql(statement):
    r = subprocess.run(["psql", "-qAtX", "-v", "ON_ERROR_STOP=1", "-c", statement], capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit("psql %s: %s" % (statement, r.stderr))
    return r.stdout.strip()


def start(args):
    return subprocess.Popen([tool, "-q", "-device", "cpu"] + args, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)


def run(args):
    p = start(args)
    out, err = p.communicate(timeout=300)
    return p.returncode, err


def digest(schema, table):
    """The table's rows, all columns, as one md5 (the old tables must be exactly as they were)."""
    return sql("SELECT count(*) || ' ' || md5(coalesce(string_agg(t::text, '|' ORDER BY t::text), '')) FROM %s.%s t"
               % (schema, table))


def staging_schemas():
    return sql("SELECT string_agg(nspname, ',') FROM pg_namespace WHERE nspname LIKE 'qtmv_staging_%'")


def rows(ds, name):
    layer = ds.GetLayerByName(name)
    names = [layer.GetLayerDefn().GetFieldDefn(k).GetName() for k in range(layer.GetLayerDefn().GetFieldCount())]
    out = []
    for f in layer:
        g = f.GetGeometryRef()
        out.append((f.GetFID(), tuple((n, f.GetField(n)) for n in names),
                    bytes(g.ExportToIsoWkb()) if g else None))
    return sorted(out)


def same_as_gpkg(schema, gpkg, layers, what):
    db = gdal.OpenEx(DB + " active_schema=" + schema, gdal.OF_VECTOR)
    ref = gdal.OpenEx(gpkg, gdal.OF_VECTOR)
    for name in layers.split(","):
        a, b = rows(db, name), rows(ref, name)
        empty = sum(1 for r in b if r[2] is not None and ogr.CreateGeometryFromWkb(r[2]).IsEmpty())
        worst, same = 0.0, len(a) == len(b) > 0
        for x, y in zip(a, b):
            same = same and x[0] == y[0] and x[2] == y[2] and [n for n, _ in x[1]] == [n for n, _ in y[1]]
            for (_, u), (_, v) in zip(x[1], y[1]):
                if isinstance(u, float) and isinstance(v, float) and u != v:
                    worst = max(worst, abs(u - v) / max(abs(u), abs(v)))
                else:
                    same = same and u == v
        check(same and worst <= 1e-12, "%s: layer %s: %d rows (%d empty geometries) equal to the GeoPackage's %d "
              "(geometries byte for byte; Reals to %.1g)" % (what, name, len(a), empty, len(b), worst))


sql("CREATE EXTENSION IF NOT EXISTS postgis")
with tempfile.TemporaryDirectory() as work:
    gpkg5, gpkg4 = os.path.join(work, "l5.gpkg"), os.path.join(work, "l4.gpkg")
    for level, path in (("5", gpkg5), ("4", gpkg4)):
        rc, err = run(["-level", level, "-layers", ALL] + centres + [path])
        if rc != 0:
            sys.exit("GeoPackage output failed: " + err)

    # Written, and read back equal to the GeoPackage (level 5: 10 sites without a cell).
    sql("CREATE TABLE public.notes (id integer, note text); INSERT INTO public.notes VALUES (1, 'the user''s')")
    rc, err = run(["-level", "5", "-layers", ALL] + centres + [DB])
    check(rc == 0, "first run into %s: exit %d %s" % (DB, rc, err.strip()[-300:]))
    same_as_gpkg("public", gpkg5, ALL, "PG")
    geometry_columns = sql("SELECT string_agg(f_table_name || ':' || type || ':' || srid, ',' ORDER BY f_table_name) "
                           "FROM geometry_columns WHERE f_table_schema = 'public'")
    check(geometry_columns == "boundary_cells:POLYGON:4326,cells:POLYGON:4326,regions:MULTIPOLYGON:4326,"
          "voronoi_edges:MULTILINESTRING:4326", "geometry_columns: " + geometry_columns)
    # PostGIS reads the regions as geography (geodesic edges) with the tool's areas.
    worst = float(sql("SELECT max(abs(ST_Area(wkb_geometry::geography) - area_m2) / area_m2) FROM public.regions "
                      "WHERE NOT ST_IsEmpty(wkb_geometry)"))
    check(worst < 1e-9, "PostGIS geography's ST_Area of the regions against area_m2: at most %.1g apart" % worst)
    old = {t: digest("public", t) for t in ALL.split(",")}
    objects = "SELECT string_agg(n.nspname || '.' || c.relname, ',' ORDER BY n.nspname, c.relname) FROM pg_class c JOIN pg_namespace n " \
              "ON n.oid = c.relnamespace WHERE c.relname LIKE 'regions%' OR c.relname LIKE 'cells%'"
    first_objects = sql(objects)
    notes = digest("public", "notes")

    # An existing table without -overwrite: refused before any work, nothing touched.
    rc, err = run(["-level", "4", "-layers", "regions"] + centres + [DB])
    check(rc == 1 and "public.regions exist: use -overwrite" in err, "existing table without -overwrite: %d %s"
          % (rc, err.strip()))
    check(digest("public", "regions") == old["regions"], "the existing table untouched")

    # A bad option found only at the write (the driver's -lco): the old tables as they were.
    rc, err = run(["-level", "4", "-overwrite", "-layers", ALL, "-lco", "GEOM_TYPE=nonsense"] + centres + [DB])
    check(rc == 1 and "GEOM_TYPE" in err, "a bad -lco found at the write: %d %s" % (rc, err.strip()[-300:]))
    check(all(digest("public", t) == old[t] for t in old), "... the old tables as they were")
    check(staging_schemas() == "", "... no staging schema left")

    # SIGINT while the cells layer is written (level 8: 524 288 rows): the old tables as they were.
    p = start(["-level", "8", "-overwrite", "-layers", ALL] + centres + [DB])
    deadline = time.time() + 120
    while time.time() < deadline and p.poll() is None:
        if sql("SELECT count(*) FROM pg_tables WHERE schemaname LIKE 'qtmv_staging_%' AND tablename = 'cells'") == "1":
            break
        time.sleep(0.05)
    time.sleep(0.5)
    p.send_signal(signal.SIGINT)
    out, err = p.communicate(timeout=60)
    check(p.returncode == 1 and "interrupted by SIGINT" in err, "SIGINT while writing the cells table: %d %s"
          % (p.returncode, err.strip()[-200:]))
    check(all(digest("public", t) == old[t] for t in old), "... the old tables as they were")
    check(staging_schemas() == "", "... no staging schema left")

    # -overwrite of two layers: those replaced (level 4), the third layer of the first run and
    # the user's table kept.
    rc, err = run(["-level", "4", "-overwrite", "-layers", "regions,cells"] + centres + [DB])
    check(rc == 0, "-overwrite of regions and cells: exit %d %s" % (rc, err.strip()[-300:]))
    same_as_gpkg("public", gpkg4, "regions,cells", "-overwrite")
    check(digest("public", "voronoi_edges") == old["voronoi_edges"] and
          digest("public", "boundary_cells") == old["boundary_cells"], "... the layers not written kept")
    check(digest("public", "notes") == notes, "... the user's table kept")
    check(sql(objects) == first_objects, "... the same tables, sequences and indexes as before, and no other: " +
          first_objects)

    # -overwrite never drops a view on an old table: refused before any work.
    sql("CREATE VIEW public.big_regions AS SELECT * FROM public.regions")
    rc, err = run(["-level", "5", "-overwrite", "-layers", "regions"] + centres + [DB])
    check(rc == 1 and "view big_regions depends on table public.regions" in err,
          "-overwrite with a view on the table: %d %s" % (rc, err.strip()))

    # Two runs at once without -overwrite into one schema: one writes, the other fails naming
    # the table, and the tables are one run's whole output.
    sql("CREATE SCHEMA race")
    runs = [start(["-level", "7", "-layers", "regions,cells", "-lco", "SCHEMA=race"] + centres + [DB]) for _ in range(2)]
    results = [(p.wait(timeout=300), p.stderr.read()) for p in runs]
    codes = sorted(r[0] for r in results)
    loser = [r[1] for r in results if r[0] != 0]
    check(codes == [0, 1] and "table race.cells appeared while this run was writing" in loser[0],
          "two runs at once: exits %s, the other: %s" % (codes, loser[0].strip() if loser else ""))
    gpkg7 = os.path.join(work, "l7.gpkg")
    run(["-level", "7", "-layers", "regions,cells"] + centres + [gpkg7])
    same_as_gpkg("race", gpkg7, "regions,cells", "the race's winner")
    check(staging_schemas() == "", "... no staging schema left")

for f in failures:
    print("FAILED: " + f)
sys.exit(1 if failures else 0)
