#!/usr/bin/env bash
# The read of a CSV of points by thread count (issue 37: "reading at the disk's speed, never
# slower with more threads"): the read-only run (-level 6, almost no labelling or writing) at each
# thread count, with the split read (several GDAL datasets at once, src/sites/split_read) and
# without it (QTMV_READ_SPLIT=NO: GDAL's one reading thread, as before), REPEAT times each,
# alternating; prints the read trace's "features read" and "whole read" and the wall per run.
#   bench/read_bench.sh TOOL POINTS.csv [THREADS...]      (default threads: 1 4 16)
#   REPEAT=3 (default) runs of each; the output goes to a temporary directory.
# POINTS.csv: lon,lat columns (bench/end_to_end.py's points, e.g. 1 000 000 of them).
set -euo pipefail
tool=$(realpath "$1")
points=$(realpath "$2")
shift 2
threads=("$@")
[ ${#threads[@]} -gt 0 ] || threads=(1 4 16)
repeat=${REPEAT:-3}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
printf '%-8s %-6s %-4s %10s %10s %8s  %s\n' threads split run "read (s)" "whole (s)" "wall (s)" "how"
for t in "${threads[@]}"; do
  for r in $(seq 1 "$repeat"); do
    for split in YES NO; do
      start=$(date +%s.%N)
      "$tool" -overwrite -device cpu -level 6 -layers regions -threads "$t" -oo X_POSSIBLE_NAMES=lon \
        -oo Y_POSSIBLE_NAMES=lat --config QTMV_TRACE read --config QTMV_READ_SPLIT "$split" \
        "$points" "$work/out.gpkg" 2> "$work/err" > /dev/null || { cat "$work/err"; exit 1; }
      end=$(date +%s.%N)
      read_s=$(sed -n 's/.*features read \([0-9.]*\) s.*/\1/p' "$work/err" | head -1)
      whole_s=$(sed -n 's/.*whole read \([0-9.]*\) s.*/\1/p' "$work/err" | head -1)
      how=$(sed -n 's/.*: \(split read: .*\|read on one thread: .*\)/\1/p' "$work/err" | head -1)
      printf '%-8s %-6s %-4s %10s %10s %8.2f  %s\n' "$t" "$split" "$r" "$read_s" "$whole_s" \
        "$(awk "BEGIN{print $end - $start}")" "$how"
    done
  done
done
