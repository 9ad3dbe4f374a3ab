#!/usr/bin/env python3
"""Whether two GeoPackages' regions layers hold the same regions: per FID the same area_m2 and the
same polygons, rings compared as cycles (whatever vertex a ring starts at) and holes in any order.

    python3 bench/same_rings.py A.gpkg B.gpkg    (prints the row counts and how many differ)
"""
import sqlite3
import struct
import sys


def polygons(blob):
    """The polygons of a GeoPackage (Multi)Polygon blob: (shell, sorted holes), each ring as a
    tuple of (lon, lat) starting at its least point, not closed."""
    flags = blob[3]
    wkb = blob[8 + [0, 32, 48, 48, 64][(flags >> 1) & 7]:]
    pos = 0

    def u32():
        nonlocal pos
        value = struct.unpack_from("<I", wkb, pos)[0]
        pos += 4
        return value

    pos += 1
    kind = u32()
    count = 1
    if kind == 6:
        count = u32()
    else:
        pos = 0
    out = []
    for _ in range(count):
        pos += 5
        rings = []
        for _ in range(u32()):
            n = u32()
            points = [struct.unpack_from("<dd", wkb, pos + 16 * i) for i in range(n)][:-1]
            pos += 16 * n
            first = points.index(min(points))
            rings.append(tuple(points[first:] + points[:first]))
        out.append((rings[0], tuple(sorted(rings[1:]))))
    return sorted(out)


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    query = "select fid, geom, area_m2 from regions order by fid"
    a = sqlite3.connect(sys.argv[1]).execute(query).fetchall()
    b = sqlite3.connect(sys.argv[2]).execute(query).fetchall()
    differ = sum(1 for x, y in zip(a, b)
                 if x[0] != y[0] or x[2] != y[2] or (x[1] and polygons(x[1])) != (y[1] and polygons(y[1])))
    print(len(a), len(b), "different", differ + abs(len(a) - len(b)))


if __name__ == "__main__":
    main()
