#!/usr/bin/env bash
# A qtmvoronoi run split into tile jobs that GNU parallel runs on this machine (all cores, or the
# GPUs one job each). Two forms (FORM):
#   one-file (the default): the tile jobs write tile products, then one merge writes the output,
#     the same as one run's;
#   parts: each tile job writes its part of the output (-tile K/N -part: a GeoPackage, regions cut
#     at the tile's edges; with a raster option among the OUTPUT OPTIONS (-raster, -tr, -ts,
#     -bands, -ot, -co) a GeoTIFF, a band of the raster's rows), then the index of the parts
#     (-merge -of VRT) makes them one data set; DESTINATION is the index (a .vrt).
#
#   tiles_gnu_parallel.sh LEVEL TILES SOURCE DESTINATION [READING OPTIONS...] [-- OUTPUT OPTIONS...]
#
# READING OPTIONS (-l, -where, -s_srs, -oo, -edges, -distance, -device, ...) go to every tile job
# and to the merge; OUTPUT OPTIONS (-of, -layers, -lco, -overwrite, ...) to the merge alone (parts:
# to every tile job; -overwrite to the index too).
# Environment: QTMVORONOI (the tool; default: qtmvoronoi on the PATH), JOBS (tile jobs at once;
# default: parallel's, one per core; each job gets -threads cores/JOBS, or cores/TILES if there
# are fewer tiles, unless the READING OPTIONS give -threads: a job's default, every core, would
# put JOBS threads on each core), TILE_DIR
# (where the tile products go; default: a temporary directory, removed at the end; parts: where
# the parts go, default DESTINATION less .vrt, plus _parts), FORM (one-file or parts).
#
# Example: 8 tiles of level 12, 2 at a time, regions as a GeoPackage
#   JOBS=2 examples/tiles_gnu_parallel.sh 12 8 sites.gpkg voronoi.gpkg -l sites -- -layers regions
# The same as 8 parts and their index voronoi.vrt (the parts in voronoi_parts/)
#   FORM=parts JOBS=2 examples/tiles_gnu_parallel.sh 12 8 sites.gpkg voronoi.vrt -l sites -- -layers regions
# A lon/lat raster in 8 parts (GeoTIFFs) and their index, which GDAL reads as the whole raster
#   FORM=parts examples/tiles_gnu_parallel.sh 10 8 sites.gpkg voronoi.vrt -l sites -- -raster lonlat
set -euo pipefail

if [ $# -lt 4 ]; then
  sed -n '11,21p' "$0" >&2
  exit 2
fi
level=$1 tiles=$2 source=$3 destination=$4
shift 4
reading=()
while [ $# -gt 0 ] && [ "$1" != "--" ]; do reading+=("$1"); shift; done
[ $# -gt 0 ] && shift  # the --
output=("$@")

tool=${QTMVORONOI:-qtmvoronoi}
command -v parallel > /dev/null || { echo "$0: GNU parallel is missing (Debian: apt install parallel)" >&2; exit 1; }
# Each tile job's share of the cores: the jobs at once are JOBS (parallel's default: one per core)
# or the tiles, if fewer; parallel's other forms of -j (50%, +2, 0) are left to a -threads of the
# user's.
cores=$(nproc) at_once=
case ${JOBS:-} in
  '') at_once=$((tiles < cores ? tiles : cores)) ;;
  *[!0-9]* | 0) ;;
  *) at_once=$((JOBS < tiles ? JOBS : tiles)) ;;
esac
threads=()
[ -n "$at_once" ] && [ "$at_once" -gt 0 ] && threads=(-threads $((cores / at_once > 0 ? cores / at_once : 1)))
for o in ${reading[@]+"${reading[@]}"}; do [ "$o" = -threads ] && threads=(); done

if [ "${FORM:-one-file}" = parts ]; then
  part_dir=${TILE_DIR:-${destination%.vrt}_parts}
  mkdir -p "$part_dir"
  index=() part=gpkg
  for o in ${output[@]+"${output[@]}"}; do
    case $o in
      -overwrite) index+=(-overwrite) ;;
      -raster | -tr | -ts | -bands | -ot | -co) part=tif ;;  # a raster's parts: GeoTIFFs
    esac
  done
  parallel --will-cite --quote --halt now,fail=1 ${JOBS:+-j "$JOBS"} \
    "$tool" -q -overwrite -level "$level" -tile {}/"$tiles" -part ${threads[@]+"${threads[@]}"} "${reading[@]}" ${output[@]+"${output[@]}"} \
    "$source" "$part_dir"/{}."$part" ::: $(seq "$tiles")
  exec "$tool" ${index[@]+"${index[@]}"} -merge "$part_dir" -of VRT "$destination"
fi
[ "${FORM:-one-file}" = one-file ] || { echo "$0: FORM is one-file or parts, not '$FORM'" >&2; exit 2; }
if [ -n "${TILE_DIR:-}" ]; then
  mkdir -p "$TILE_DIR"
  tile_dir=$TILE_DIR
else
  tile_dir=$(mktemp -d)
  trap 'rm -rf "$tile_dir"' EXIT
fi

# One tile job per tile; --quote passes the options as they are (a -where with spaces), and
# --halt now,fail=1 stops the others at the first failure, whose message parallel passes on.
parallel --will-cite --quote --halt now,fail=1 ${JOBS:+-j "$JOBS"} \
  "$tool" -q -overwrite -level "$level" -tile {}/"$tiles" ${threads[@]+"${threads[@]}"} "${reading[@]}" "$source" "$tile_dir"/{}.qtmt \
  ::: $(seq "$tiles")
"$tool" -level "$level" -merge "$tile_dir" "${reading[@]}" "${output[@]}" "$source" "$destination"
