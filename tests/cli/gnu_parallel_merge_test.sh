#!/usr/bin/env bash
# examples/tiles_gnu_parallel.sh as a user runs it: tile jobs on the CPU through GNU parallel,
# then the merge; its outputs (CSV layers) must equal one whole run's byte for byte, for points
# and polygons; the parts form's index, dissolved by site_fid, the whole run's regions; a failing
# tile job must fail the script and leave no destination.
#   gnu_parallel_merge_test.sh QTMVORONOI TESTDATA_DIR
set -euo pipefail
tool=$1 data=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
export QTMVORONOI=$tool JOBS=2

check() {  # name level tiles source [reading options...]
  local name=$1 level=$2 tiles=$3 source=$4
  shift 4
  "$tool" -q -level "$level" -device cpu "$@" -of CSV -layers regions,voronoi_edges,boundary_cells \
    "$source" "$work/$name-whole"
  examples/tiles_gnu_parallel.sh "$level" "$tiles" "$source" "$work/$name-merged" -device cpu "$@" \
    -- -q -of CSV -layers regions,voronoi_edges,boundary_cells
  for f in regions voronoi_edges boundary_cells; do
    cmp "$work/$name-whole/$f.csv" "$work/$name-merged/$f.csv"
    [ -s "$work/$name-whole/$f.csv" ]
  done
  echo "$name: level $level, $tiles tiles merged = whole run"
}

# rows DATASET SQL: the rows of an SQLite-dialect query as CSV.
rows() { ogr2ogr -f CSV /vsistdout/ -dialect sqlite -sql "$2" "$1"; }

# The parts form: the parts' index, dissolved by site_fid, holds the whole run's regions (cells per
# site, areas to 1e-9 relative) and its boundary cells.
check_parts() {  # name level tiles source [reading options...]
  local name=$1 level=$2 tiles=$3 source=$4
  shift 4
  "$tool" -q -level "$level" -device cpu "$@" -layers regions,boundary_cells "$source" "$work/$name-whole.gpkg"
  FORM=parts examples/tiles_gnu_parallel.sh "$level" "$tiles" "$source" "$work/$name.vrt" -device cpu "$@" \
    -- -layers regions,boundary_cells
  [ "$(find "$work/${name}_parts" -name '*.gpkg' | wc -l)" -eq "$tiles" ]
  paste -d, <(rows "$work/$name-whole.gpkg" "SELECT site_fid, cells, area_m2 FROM regions WHERE cells > 0 ORDER BY site_fid") \
    <(rows "$work/$name.vrt" "SELECT site_fid, SUM(cells), SUM(area_m2), COUNT(*) FROM regions GROUP BY site_fid ORDER BY site_fid") |
    awk -F, 'NR > 1 { gsub(/"/, ""); n++; if ($1 != $4 || $2 != $5 || ($3 - $6) ^ 2 > (1e-9 * $3) ^ 2) { print "site " $1 ": " $0; bad++ }
                      if ($7 > 1) cut++ }
             END { if (bad || n < 10 || !cut) { print n " sites, " bad " differ, " cut " cut" > "/dev/stderr"; exit 1 } }'
  cmp <(rows "$work/$name-whole.gpkg" "SELECT code, site_fid FROM boundary_cells ORDER BY code") \
      <(rows "$work/$name.vrt" "SELECT code, site_fid FROM boundary_cells ORDER BY code")
  echo "$name: level $level, $tiles parts and their index = whole run (dissolved by site_fid)"
}

# A raster in parts: the index read through GDAL is the whole run's raster, pixel for pixel.
check_raster_parts() {  # name level tiles source [reading options...] -- [raster options...]
  local name=$1 level=$2 tiles=$3 source=$4
  shift 4
  local reading=()
  while [ "$1" != -- ]; do reading+=("$1"); shift; done
  shift
  "$tool" -q -level "$level" -device cpu "${reading[@]}" "$@" "$source" "$work/$name-whole.tif"
  FORM=parts examples/tiles_gnu_parallel.sh "$level" "$tiles" "$source" "$work/$name.vrt" -device cpu "${reading[@]}" \
    -- "$@"
  [ "$(find "$work/${name}_parts" -name '*.tif' | wc -l)" -eq "$tiles" ]
  gdal_translate -q -of ENVI -co INTERLEAVE=BSQ "$work/$name-whole.tif" "$work/$name-whole.bin"
  gdal_translate -q -of ENVI -co INTERLEAVE=BSQ "$work/$name.vrt" "$work/$name-index.bin"
  cmp "$work/$name-whole.bin" "$work/$name-index.bin"
  echo "$name: level $level, $tiles raster parts and their index = whole raster"
}

centres=(-oo X_POSSIBLE_NAMES=lon -oo Y_POSSIBLE_NAMES=lat -s_srs EPSG:4326)
check points 9 8 "$data/country_centres.csv" "${centres[@]}" -where "lon > -100"
check polygons 8 4 "$data/world_atlas_countries_110m.gpkg"
check_parts points 8 6 "$data/country_centres.csv" "${centres[@]}"
check_parts polygons 7 4 "$data/world_atlas_countries_110m.gpkg"
check_raster_parts raster 7 5 "$data/country_centres.csv" "${centres[@]}" -- -q -raster lonlat

# A tile job that fails (a bad -where) fails the whole script, and the merge never runs.
if examples/tiles_gnu_parallel.sh 6 4 "$data/country_centres.csv" "$work/failed" "${centres[@]}" \
     -where "no_such_column > 1" -- -of CSV 2> "$work/failed.err"; then
  echo "a failing tile job did not fail the script" >&2
  exit 1
fi
grep -q "no_such_column" "$work/failed.err" || { cat "$work/failed.err" >&2; exit 1; }
[ ! -e "$work/failed" ] || { echo "a destination was written after a failed tile job" >&2; exit 1; }
echo "a failing tile job fails the script, nothing written"
