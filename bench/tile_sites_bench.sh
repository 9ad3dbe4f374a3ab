#!/bin/bash
# Tile jobs that read every site (QTMV_TILE_SITES=ALL, as before issue 38) against tile jobs that
# read only the sites near their tile, alternating, REPEAT times: each job's wall time, read
# time (the read trace's "whole read") and sites read; then the medians and their sums.
#
#   bench/tile_sites_bench.sh TOOL SOURCE LEVEL TILES [DEVICE] [REPEAT]
#
# SOURCE: a GeoPackage (a CSV is read whole by either: make one with
#   ogr2ogr -f GPKG /tmp/points1m.gpkg points1m.csv -oo X_POSSIBLE_NAMES=lon -oo Y_POSSIBLE_NAMES=lat -a_srs EPSG:4326).
# The tile products of both ways must merge into the same output: run -merge on each to check.
set -euo pipefail
tool=$1 source=$2 level=$3 tiles=$4 device=${5:-cpu} repeat=${6:-3}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
for rep in $(seq "$repeat"); do
  for k in $(seq "$tiles"); do
    for mode in all near; do
      extra=()
      [ "$mode" = all ] && extra=(--config QTMV_TILE_SITES ALL)
      start=$(date +%s.%N)
      out=$("$tool" -q -overwrite -device "$device" -level "$level" -tile "$k/$tiles" --config QTMV_TRACE read \
            "${extra[@]}" "$source" "$work/$mode-$k.qtmt" 2>&1)
      end=$(date +%s.%N)
      read_s=$(grep -o "whole read [0-9.]*" <<<"$out" | awk '{print $3}')
      sites=$(grep -o "tile's sites: [0-9]*" <<<"$out" | awk '{print $3}' || true)
      echo "$rep $k $mode $(echo "$end - $start" | bc) $read_s ${sites:-all}"
    done
  done
done | python3 -c '
import collections, statistics, sys
runs = collections.defaultdict(list)
for line in sys.stdin:
    rep, k, mode, wall, read, sites = line.split()
    runs[(int(k), mode)].append((float(wall), float(read), sites))
total = collections.defaultdict(lambda: [0.0, 0.0])
for (k, mode), rows in sorted(runs.items()):
    wall = statistics.median(r[0] for r in rows)
    read = statistics.median(r[1] for r in rows)
    total[mode][0] += wall
    total[mode][1] += read
    print(f"tile {k} {mode:4s}: wall {wall:6.2f} s, read {read:6.2f} s, sites {rows[0][2]}")
for mode, (wall, read) in total.items():
    print(f"sum {mode:4s}: wall {wall:6.1f} s, read {read:6.1f} s")
'
