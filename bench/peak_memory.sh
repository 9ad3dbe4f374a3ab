#!/bin/bash
# Peak host memory (RSS) of qtmvoronoi runs, with the outline cells' count and the stages' times:
#   bench/peak_memory.sh TOOL POINTS.csv DEVICE LEVEL... [-- extra options]
# e.g. bench/peak_memory.sh build/tools/qtmvoronoi/qtmvoronoi points1m.csv cuda:0 14 16
# One line per level: level, device, peak MB (GNU time's maximum resident set), outline cells,
# and the run's summary (read / label / write); then the write stage's steps, each with the
# process's resident memory at its end and the peak so far (a tool that traces them: since
# session 23), so that the step whose buffers make the peak shows (a peak so far at the first
# write step equal to the run's: the peak was reached before the write, in the read or the
# label stage). With RSS_EVERY=SECONDS the resident memory is also sampled that often and the
# largest sample printed per stage. Writes its outputs in a temporary directory.
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
  rm -f "$work/out.gpkg" "$work/rss.txt"
  /usr/bin/time -f "peak_kb %M" "$tool" -overwrite -device "$device" -level "$level" -layers regions \
    -oo X_POSSIBLE_NAMES=lon -oo Y_POSSIBLE_NAMES=lat --config QTMV_TRACE label,write "$@" "$points" "$work/out.gpkg" > "$log" 2>&1 &
  timer=$!
  if [ -n "${RSS_EVERY:-}" ]; then
    # The tool's process (GNU time's child): its VmRSS (MB) every RSS_EVERY seconds, with the
    # number of trace lines written so far (which stage it is in).
    sleep 0.05
    pid=$(pgrep -P "$timer" | head -1 || true)
    while [ -n "$pid" ] && kill -0 "$timer" 2>/dev/null; do
      rss=$(awk '/^VmRSS/{print int($2 * 1024 / 1e6)}' "/proc/$pid/status" 2>/dev/null || true)
      [ -n "$rss" ] && echo "$rss $(grep -c 'trace: write' "$log" || true) $(grep -c 'trace: label outline cells' "$log" || true)" >> "$work/rss.txt"
      sleep "$RSS_EVERY"
    done
  fi
  wait "$timer"
  peak=$(awk '/^peak_kb/{print int($2 * 1024 / 1e6)}' "$log")
  outline=$(grep -o "outline cells [0-9]*" "$log" | awk '{print $3}')
  summary=$(grep -o "read [0-9.]* s.*total [0-9.]* s" "$log")
  echo "level $level $device: peak ${peak} MB, ${outline} outline cells; $summary"
  if [ -s "$work/rss.txt" ]; then
    awk '{ stage = $2 > 0 ? "write" : ($3 > 0 ? "after-label" : "read+label"); if ($1 > max[stage]) max[stage] = $1 }
         END { printf "  sampled max RSS (MB):"; n = split("read+label after-label write", order, " ")
               for (k = 1; k <= n; ++k) if (order[k] in max) printf " %s %d", order[k], max[order[k]]; printf "\n" }' "$work/rss.txt"
  fi
  grep -o "trace: write .*" "$log" | sed 's/^trace: /  /' || true
done
