#!/bin/bash
# Peak host memory (RSS) of qtmvoronoi runs, with the outline cells' count and the stages' times:
#   bench/peak_memory.sh TOOL POINTS.csv DEVICE LEVEL... [-- extra options]
# e.g. bench/peak_memory.sh build/tools/qtmvoronoi/qtmvoronoi points1m.csv cuda:0 14 16
# One line per level: level, device, peak MB (GNU time's maximum resident set), outline cells,
# and the run's summary (read / label / write). Writes its outputs in a temporary directory.
set -euo pipefail
tool=$1 points=$2 device=$3
shift 3
levels=()
while [ $# -gt 0 ] && [ "$1" != "--" ]; do levels+=("$1"); shift; done
[ $# -gt 0 ] && shift
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
for level in "${levels[@]}"; do
  log=$work/run.log
  /usr/bin/time -f "peak_kb %M" "$tool" -overwrite -device "$device" -level "$level" -layers regions \
    -oo X_POSSIBLE_NAMES=lon -oo Y_POSSIBLE_NAMES=lat --config QTMV_TRACE label "$@" "$points" "$work/out.gpkg" > "$log" 2>&1
  peak=$(awk '/^peak_kb/{print int($2 / 1024)}' "$log")
  outline=$(grep -o "outline cells [0-9]*" "$log" | awk '{print $3}')
  summary=$(grep -o "read [0-9.]* s.*total [0-9.]* s" "$log")
  echo "level $level $device: peak ${peak} MB, ${outline} outline cells; $summary"
done
