#!/usr/bin/env bash
# Issue 38's goal on a GPU host: TILES tile jobs over GPUS GPUs (PER_GPU at a time on each, tile K
# on cuda:((K-1) % GPUS)), in both forms, against the whole run on one GPU, end to end:
#   whole     one run on cuda:0, the regions in one GeoPackage
#   one-file  the tile jobs' tile products, then the merge into one GeoPackage
#   parts     the tile jobs' parts (-tile K/N -part), then their index (-merge -of VRT)
# Prints each form's wall seconds and its ratio to the whole run, and checks the parts' index:
# its regions' cells add up to the level's, and their areas to the whole run's (1e-9).
#
#   partitioned_tiles.sh QTMVORONOI LEVEL TILES GPUS SOURCE [READING OPTIONS...]
#
# Environment: PER_GPU (tile jobs at once per GPU, default 2), THREADS (each tile job's -threads,
# default the host's cores over the jobs at once: a job's default, every core, would put that many
# threads on each core), LAYERS (default regions), WORK
# (a directory for the outputs, default a temporary one, removed at the end), CPU_ONLY=1 (every
# run on the CPU: to try the script on a host without a GPU).
# Example (1M points at level 16, 8 tiles over 4 GPUs):
#   bench/partitioned_tiles.sh build/tools/qtmvoronoi/qtmvoronoi 16 8 4 points1m.csv \
#     -oo X_POSSIBLE_NAMES=lon -oo Y_POSSIBLE_NAMES=lat
set -euo pipefail
[ $# -ge 5 ] || { sed -n '10,16p' "$0" >&2; exit 2; }
tool=$1 level=$2 tiles=$3 gpus=$4 source=$5
shift 5
reading=("$@")
per_gpu=${PER_GPU:-2} layers=${LAYERS:-regions}
cores=$(nproc)
threads=${THREADS:-$((cores / (per_gpu * gpus) > 0 ? cores / (per_gpu * gpus) : 1))}
if [ -n "${WORK:-}" ]; then
  work=$WORK
  mkdir -p "$work"
else
  work=$(mktemp -d)
  trap 'rm -rf "$work"' EXIT
fi
export tool level tiles gpus source work layers threads CPU_ONLY
now() { date +%s.%N; }
# Arithmetic and the sums by awk and Python's sqlite3 (a GeoPackage is SQLite): the GPU machine has
# neither bc nor GDAL's tools.
calc() { awk "BEGIN { printf \"%.6f\", $1 }"; }
# tile_jobs EXTRA SUFFIX: every tile job, PER_GPU * GPUS at a time; each names its device.
tile_jobs() {
  local extra=$1 suffix=$2
  seq "$tiles" | xargs -P $((per_gpu * gpus)) -I{} bash -c '
    k={}; device=cuda:$(( (k - 1) % gpus )); [ -n "${CPU_ONLY:-}" ] && device=cpu
    "$tool" -q -overwrite -level "$level" -device "$device" -threads "$threads" -tile "$k/$tiles" '"$extra"' "$@" "$source" \
      "$work/tiles/$k'"$suffix"'"' _ "${reading[@]}"
}

t0=$(now)
"$tool" -q -overwrite -level "$level" -device "$([ -n "${CPU_ONLY:-}" ] && echo cpu || echo cuda:0)" "${reading[@]}" -layers "$layers" "$source" "$work/whole.gpkg"
t1=$(now)
whole=$(calc "$t1 - $t0")

rm -rf "$work/tiles" && mkdir -p "$work/tiles"
t0=$(now)
tile_jobs "" .qtmt
t1=$(now)
"$tool" -q -overwrite -level "$level" -merge "$work/tiles" "${reading[@]}" -layers "$layers" "$source" "$work/merged.gpkg"
t2=$(now)
one_tiles=$(calc "$t1 - $t0") one_merge=$(calc "$t2 - $t1")

rm -rf "$work/tiles" && mkdir -p "$work/tiles"
t0=$(now)
tile_jobs "-part -layers $layers" .gpkg
t1=$(now)
"$tool" -q -overwrite -merge "$work/tiles" -of VRT "$work/index.vrt"
t2=$(now)
part_tiles=$(calc "$t1 - $t0") part_index=$(calc "$t2 - $t1")

printf 'level %s, %s tiles over %s GPUs (%s at a time each, %s threads each)\n' "$level" "$tiles" "$gpus" "$per_gpu" "$threads"
printf '  whole run (cuda:0)        %8.2f s\n' "$whole"
printf '  one-file: tiles %6.2f + merge %6.2f = %8.2f s (%.2fx faster than the whole run)\n' "$one_tiles" "$one_merge" \
  "$(calc "$one_tiles + $one_merge")" "$(calc "$whole / ($one_tiles + $one_merge)")"
printf '  parts:    tiles %6.2f + index %6.2f = %8.2f s (%.2fx faster than the whole run)\n' "$part_tiles" "$part_index" \
  "$(calc "$part_tiles + $part_index")" "$(calc "$whole / ($part_tiles + $part_index)")"
# sums FILE...: the regions' cells and area_m2 summed over the GeoPackages given, "CELLS,AREA".
sums() {
  python3 -c 'import sqlite3, sys
cells = area = 0
for f in sys.argv[1:]:
    c, a = sqlite3.connect(f).execute("SELECT SUM(cells), SUM(area_m2) FROM regions").fetchone()
    cells, area = cells + c, area + a
print("%d,%r" % (cells, area))' "$@"
}
IFS=, read -r whole_cells whole_area < <(sums "$work/whole.gpkg")
IFS=, read -r part_cells part_area < <(sums "$work"/tiles/*.gpkg)
echo "  cells: whole $whole_cells, parts $part_cells; area_m2: whole $whole_area, parts $part_area"
[ "$whole_cells" = "$part_cells" ] || { echo "the parts' cells differ from the whole run's" >&2; exit 1; }
awk -v a="$whole_area" -v b="$part_area" 'BEGIN { exit !((a - b) ^ 2 <= (1e-9 * a) ^ 2) }' ||
  { echo "the parts' areas differ from the whole run's" >&2; exit 1; }
