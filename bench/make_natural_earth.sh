#!/usr/bin/env bash
# Makes the benchmarks' Natural Earth inputs (public domain, world-atlas 2.0.2) as GeoPackages:
#   countries50.gpkg  50m countries, 241 polygons   (bench/end_to_end.py --data)
#   land10.gpkg       10m land, one multipolygon    (bench/end_to_end.py --data)
#   coast50.gpkg      the rings of 50m land as 1 419 MultiLineStrings (sites_bench's lines)
#   bench/make_natural_earth.sh [OUTDIR]   (default: build/bench-data)
set -euo pipefail
out=${1:-build/bench-data}
mkdir -p "$out"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
(cd "$work" && npm pack --silent world-atlas@2.0.2 >/dev/null && tar xzf world-atlas-2.0.2.tgz)
ogr2ogr -f GPKG -overwrite "$out/countries50.gpkg" "$work/package/countries-50m.json" countries -a_srs EPSG:4326 \
  -nln countries
ogr2ogr -f GPKG -overwrite "$out/land10.gpkg" "$work/package/land-10m.json" land -a_srs EPSG:4326 -nln land
ogr2ogr -f GPKG -overwrite "$out/coast50.gpkg" "$work/package/land-50m.json" land -a_srs EPSG:4326 \
  -explodecollections -nlt MULTILINESTRING -nln coastlines
echo "$out/countries50.gpkg $out/land10.gpkg $out/coast50.gpkg"
