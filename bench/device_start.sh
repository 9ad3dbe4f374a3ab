#!/bin/bash
# A GPU run's start on a host with several GPUs (issue 37, item 4): a process asked for cuda:0
# should start as fast with every GPU visible as with CUDA_VISIBLE_DEVICES=0, since the tool now
# shows CUDA only the devices it names. Process start to exit (bash's `time`), alternating, the
# median of RUNS each:
#   cuda:0             every GPU visible: the tool restricts CUDA to device 0
#   CVD=0 cuda:0       only GPU 0 visible: the goal (within 0.1 s)
#   cuda:all           every GPU visible and initialised by CUDA (how cuda:0 started before);
#                      the labelling itself still uses GPU 0 only (qtmv_bench's --device without
#                      --outlines labels on the first device named)
# with the labeller's benchmark of a core-only build (-DQTMV_WITH_GDAL=OFF, as on the GPU
# machine), country centres at level 6 (almost no work). Then the GPU tests of the devices'
# mapping (labels, the device used by its PCI id, the user's names) and of auto's estimate.
# With QTMVORONOI=/path/to/qtmvoronoi (a full build or the bundle's), the same three runs of the
# tool itself, `-level 6 -layers regions`, and `-device cpu` / `auto` for reference.
# Usage on the GPU machine: bash bench/device_start.sh [OUTDIR] [RUNS]
set -o pipefail
out=${1:-/tmp/out}
runs=${2:-7}
mkdir -p "$out"
nvidia-smi --query-gpu=index,name,pci.bus_id --format=csv,noheader
last=cuda:$(($(nvidia-smi -L | wc -l) - 1))  # the names kept: runs on the last GPU say so
build=${BUILD:-build-start}
if [ ! -x "$build/tools/bench/qtmv_bench" ]; then
  cmake -S . -B "$build" -G Ninja -DQTMV_WITH_GDAL=OFF -DCMAKE_BUILD_TYPE=Release -DCMAKE_CUDA_ARCHITECTURES=90 >/dev/null || exit 1
  cmake --build "$build" -j16 --target qtmv_bench visible_devices_gpu_test auto_device_test common_test 2>&1 |
    grep -E "error|FAILED"; test ${PIPESTATUS[0]} -eq 0 || exit 1
fi
B=$build/tools/bench/qtmv_bench
C=testdata/country_centres.csv

# wall CASE COMMAND...: one run's seconds, appended to $out/CASE.txt (the command's output to $out/last.log)
wall() {
  local name=$1; shift
  local t0 t1
  t0=$(date +%s.%N)
  "$@" >"$out/last.log" 2>&1 || { echo "$name failed:"; tail -3 "$out/last.log"; }
  t1=$(date +%s.%N)
  awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.3f\n", b - a }' >>"$out/$name.txt"
}
median() { sort -n "$out/$1.txt" | awk '{ v[NR] = $1 } END { printf "%.3f", (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2 }'; }
spread() { sort -n "$out/$1.txt" | awk 'NR == 1 { lo = $1 } { hi = $1 } END { printf "%.3f-%.3f", lo, hi }'; }

rm -f "$out"/bench_*.txt "$out"/tool_*.txt
bench_args=(--sites "$C" --level 6 --repeat 1 --check 1000 --csv)
for ((k = 0; k < runs; ++k)); do
  wall bench_cuda0 "$B" "${bench_args[@]}" --device cuda:0
  wall bench_cvd0 env CUDA_VISIBLE_DEVICES=0 "$B" "${bench_args[@]}" --device cuda:0
  wall bench_all "$B" "${bench_args[@]}" --device cuda:all
done
echo "qtmv_bench, country centres level 6, process wall (s), median of $runs (range):"
for c in bench_cuda0 bench_cvd0 bench_all; do echo "  $c $(median $c) ($(spread $c))"; done | tee "$out/summary.txt"
"$B" "${bench_args[@]}" --device "$last" | tail -1  # its device column names $last

if [ -n "$QTMVORONOI" ]; then
  tool_args=(-q -overwrite -level 6 -layers regions -oo X_POSSIBLE_NAMES=lon -oo Y_POSSIBLE_NAMES=lat "$C" "$out/t.gpkg")
  for ((k = 0; k < runs; ++k)); do
    wall tool_cuda0 "$QTMVORONOI" -device cuda:0 "${tool_args[@]}"
    wall tool_cvd0 env CUDA_VISIBLE_DEVICES=0 "$QTMVORONOI" -device cuda:0 "${tool_args[@]}"
    wall tool_all "$QTMVORONOI" -device cuda:all "${tool_args[@]}"
    wall tool_cpu "$QTMVORONOI" -device cpu "${tool_args[@]}"
    wall tool_auto "$QTMVORONOI" -device auto "${tool_args[@]}"
  done
  echo "qtmvoronoi -level 6 -layers regions, process wall (s), median of $runs (range):"
  for c in tool_cuda0 tool_cvd0 tool_all tool_cpu tool_auto; do echo "  $c $(median $c) ($(spread $c))"; done |
    tee -a "$out/summary.txt"
  # The names kept: the summary line of a run on the last GPU, and the auto choice's reason.
  "$QTMVORONOI" -overwrite -device "$last" -level 6 -layers regions -oo X_POSSIBLE_NAMES=lon -oo Y_POSSIBLE_NAMES=lat \
    "$C" "$out/t.gpkg" 2>&1 | tail -1
  "$QTMVORONOI" -overwrite -level 16 -layers regions -oo X_POSSIBLE_NAMES=lon -oo Y_POSSIBLE_NAMES=lat \
    "$C" "$out/t.gpkg" 2>&1 | tail -1
fi

ctest --test-dir "$build" -R 'VisibleDevices|AutoDevice' --output-on-failure 2>&1 | tail -12
