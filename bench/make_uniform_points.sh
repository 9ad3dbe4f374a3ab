#!/usr/bin/env bash
# Makes the end-to-end benchmark's input (issue 5): N points uniform on the sphere (seeded, so
# every run gets the same points), a GeoPackage of layer `cities` with fields id and name.
#   bench/make_uniform_points.sh [N] [OUT]   (default: 135000 /tmp/cities135k.gpkg)
set -euo pipefail
n=${1:-135000}
out=${2:-/tmp/cities135k.gpkg}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
python3 - "$n" > "$work/cities.csv" <<'PY'
import math, random, sys
n = int(sys.argv[1])
rng = random.Random(135000)
print("id,name,lon,lat")
for k in range(n):
    lon = rng.uniform(-180.0, 180.0)
    lat = math.degrees(math.asin(rng.uniform(-1.0, 1.0)))  # uniform in area
    print(f"{k},city {k},{lon:.7f},{lat:.7f}")
PY
ogr2ogr -f GPKG "$work/cities.gpkg" "$work/cities.csv" -nln cities -a_srs EPSG:4326 \
  -oo X_POSSIBLE_NAMES=lon -oo Y_POSSIBLE_NAMES=lat -oo KEEP_GEOM_COLUMNS=NO -oo AUTODETECT_TYPE=YES
mv "$work/cities.gpkg" "$out"
echo "$out"
