#!/usr/bin/env bash
# Digests of qtmvoronoi's outputs over a fixed set of runs on the test data, one line per output:
# run the script with two builds and diff the lines to show that a change kept every byte (a
# restructuring, a faster stage). GeoPackages are digested by their tables' rows (sqlite3's
# dump, by Python's sqlite3, with OGR_CURRENT_DATE fixed), other files by their bytes.
#   bench/output_digests.sh BUILD/tools/qtmvoronoi/qtmvoronoi [DEVICE] > digests.txt
# DEVICE: the -device of every run (default cpu; cuda on a GPU host).
set -euo pipefail
tool=$(realpath "$1")
device=${2:-cpu}
here=$(cd "$(dirname "$0")/.." && pwd)
data=$here/testdata
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
export OGR_CURRENT_DATE=2000-01-01T00:00:00.000Z
n=0
digest() {  # digest NAME FILE...
  local name=$1; shift
  for f in "$@"; do
    case "$f" in
      *.gpkg) printf '%s %s\n' "$(python3 -c 'import sqlite3, sys
for line in sqlite3.connect(sys.argv[1]).iterdump(): print(line)' "$f" | md5sum | cut -c1-32)" "$name:$(basename "$f")" ;;
      *) printf '%s %s\n' "$(md5sum < "$f" | cut -c1-32)" "$name:$(basename "$f")" ;;
    esac
  done
}
run() {  # run NAME OUTPUT ARGS...: one run; its outputs digested
  local name=$1 out=$work/$2; shift 2
  n=$((n + 1))
  if ! "$tool" -q -device "$device" "$@" "$out" 2> "$work/err"; then
    echo "FAILED $name: $(cat "$work/err")"; return
  fi
  if [ -d "$out" ]; then digest "$name" $(find "$out" -type f | sort); else digest "$name" "$out"; fi
}
# country_centres.csv is lon,lat,name: GDAL's CSV driver reads the points with these open options.
centres=(-oo X_POSSIBLE_NAMES=lon -oo Y_POSSIBLE_NAMES=lat -s_srs EPSG:4326 "$data/country_centres.csv")
countries=$data/world_atlas_countries_110m.gpkg
run centres-L9 c9.gpkg -level 9 "${centres[@]}"
run centres-L7-all-layers c7.gpkg -level 7 -layers regions,boundary_cells,voronoi_edges,cells "${centres[@]}"
run centres-L12-threads1 c12t1.gpkg -level 12 -threads 1 "${centres[@]}"
run centres-L11-cell-rule c11cell.gpkg -level 11 -distance cell "${centres[@]}"
run centres-L10-vertices-all c10all.gpkg -level 10 -vertices all "${centres[@]}"
run centres-L10-brute c10brute.gpkg -level 10 -algorithm brute "${centres[@]}"
run centres-L8-shapefile c8shp -level 8 -of "ESRI Shapefile" "${centres[@]}"
run centres-L8-csv c8.csv -level 8 -layers regions "${centres[@]}"
run centres-L8-geojson c8.geojson -level 8 -layers regions "${centres[@]}"
run countries-L8 n8.gpkg -level 8 "$countries"
run countries-L10 n10.gpkg -level 10 -layers regions,voronoi_edges "$countries"
run countries-L9-cell-rule n9cell.gpkg -level 9 -distance cell "$countries"
run countries-L9-geodesic-edges n9geo.gpkg -level 9 -edges geodesic "$countries"
run centres-L9-raster-qtm c9.tif -level 9 -raster qtm "${centres[@]}"
run centres-L8-raster-lonlat c8ll.tif -level 8 -raster lonlat -tr 0.5 0.5 "${centres[@]}"
run countries-L9-raster-lonlat n9ll.tif -level 9 -raster lonlat -ts 720 360 -ot Float64 "$countries"
run countries-L8-raster-qtm-int n8.tif -level 8 -raster qtm -ot Int32 "$countries"
# Tile jobs and their merge.
mkdir -p "$work/tiles"
for k in 1 2 3; do "$tool" -q -device "$device" -level 11 -tile $k/3 "${centres[@]}" "$work/tiles/$k.qtmt"; done
digest tiles $(ls "$work"/tiles/*.qtmt)
run centres-L11-merge merged.gpkg -level 11 -merge "$work/tiles" "${centres[@]}"
echo "# $n runs" >&2
