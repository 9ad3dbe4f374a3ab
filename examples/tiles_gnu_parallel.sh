#!/usr/bin/env bash
# A qtmvoronoi run split into tile jobs that GNU parallel runs on this machine (all cores, or the
# GPUs one job each), then merged: the output is the same as one run's.
#
#   tiles_gnu_parallel.sh LEVEL TILES SOURCE DESTINATION [READING OPTIONS...] [-- OUTPUT OPTIONS...]
#
# READING OPTIONS (-l, -where, -s_srs, -oo, -edges, -distance, -device, ...) go to every tile job
# and to the merge; OUTPUT OPTIONS (-of, -layers, -lco, -overwrite, ...) to the merge alone.
# Environment: QTMVORONOI (the tool; default: qtmvoronoi on the PATH), JOBS (tile jobs at once;
# default: parallel's, one per core), TILE_DIR (where the tile products go; default: a temporary
# directory, removed at the end).
#
# Example: 8 tiles of level 12, 2 at a time, regions as a GeoPackage
#   JOBS=2 examples/tiles_gnu_parallel.sh 12 8 sites.gpkg voronoi.gpkg -l sites -- -layers regions
set -euo pipefail

if [ $# -lt 4 ]; then
  sed -n '5,9p' "$0" >&2
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
  "$tool" -q -overwrite -level "$level" -tile {}/"$tiles" "${reading[@]}" "$source" "$tile_dir"/{}.qtmt \
  ::: $(seq "$tiles")
"$tool" -level "$level" -merge "$tile_dir" "${reading[@]}" "${output[@]}" "$source" "$destination"
