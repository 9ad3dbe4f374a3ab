#!/usr/bin/env bash
# Makes coast50.gpkg, the Natural Earth 50m coastlines (public domain) that the readers'
# benchmark reads: the rings of world-atlas's land-50m as 1 419 MultiLineStrings.
#   bench/make_coastlines.sh [OUTDIR]   (default: build/bench-data)
set -euo pipefail
out=${1:-build/bench-data}
mkdir -p "$out"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
(cd "$work" && npm pack --silent world-atlas@2.0.2 >/dev/null && tar xzf world-atlas-2.0.2.tgz)
ogr2ogr -f GPKG -overwrite "$out/coast50.gpkg" "$work/package/land-50m.json" land -a_srs EPSG:4326 \
  -explodecollections -nlt MULTILINESTRING -nln coastlines
echo "$out/coast50.gpkg"
