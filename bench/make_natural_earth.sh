#!/usr/bin/env bash
# Makes the end-to-end benchmark's polygon inputs (bench/end_to_end.py --data): Natural Earth's
# 50m countries (241 polygons) and 10m land (public domain, world-atlas 2.0.2) as GeoPackages.
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
echo "$out/countries50.gpkg $out/land10.gpkg"
