#!/usr/bin/env bash
# Builds everything and runs the main job on the data shipped in testdata/.
# Until the qtmvoronoi tool lands, the main job is qtmcell on a sample of world cities:
# their level 9 cells, those cells' centres, and their polygons as WKT.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/build.sh
qtmcell=build/tools/qtmcell/qtmcell
level=9
echo "== cells of testdata/sample_cities.txt at level $level (lon lat -> code)"
cut -d' ' -f1,2 testdata/sample_cities.txt | "$qtmcell" encode -level $level | tee build/sample_codes.txt
echo "== decode: code octant row col centre_lon centre_lat"
"$qtmcell" decode -level $level < build/sample_codes.txt
echo "== the first cell's polygon, its neighbours and its parent"
first=$(head -n 1 build/sample_codes.txt)
"$qtmcell" polygon -level $level "$first" -f wkt
"$qtmcell" neighbours -level $level "$first"
"$qtmcell" parent -level $level "$first"
