#!/bin/bash
# The labeller's device run: build (core-only, sm_90), all tests, then the benchmarks of
# issue 4. Usage on the GPU machine: bash bench/label_device_run.sh OUTDIR
set -o pipefail
out=${1:-/tmp/out}
mkdir -p "$out"
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader
cmake -S . -B build-dev -G Ninja -DQTMV_WITH_GDAL=OFF -DCMAKE_CUDA_ARCHITECTURES=90 >/dev/null || exit 1
cmake --build build-dev -j16 2>&1 | grep -E "error|warning: |FAILED" ; test ${PIPESTATUS[0]} -eq 0 || exit 1
ctest --test-dir build-dev --output-on-failure -j8 2>&1 | tail -15
B=build-dev/tools/bench/qtmv_bench
C=testdata/country_centres.csv
{
$B --csv --sites "$C" --level 9,13 --device cuda --repeat 7
$B --csv --no-header --sites "$C" --level 5,6,7,8,9 --device cuda --repeat 7
$B --csv --no-header --sites "$C" --level 5,6,7,8,9 --device cpu --threads 1 --repeat 3
$B --csv --no-header --sites "$C" --level 5,6,7,8,9 --device cpu --threads 1 --repeat 1 --algorithm brute
$B --csv --no-header --sites "$C" --level 9 --device cpu --threads 2 --repeat 7
$B --csv --no-header --sites "uniform:135000" --level 11 --device cpu --threads 2 --repeat 3
$B --csv --no-header --sites "uniform:135000" --level 11,13 --device cuda --repeat 5
$B --csv --no-header --sites "uniform:135000" --level 11 --device cuda --repeat 3 --algorithm brute
$B --csv --no-header --sites "uniform:1000;uniform:10000;uniform:100000" --level 11 --device cuda --repeat 5
$B --csv --no-header --sites "arcs:1000" --level 12 --device cuda --repeat 3
$B --csv --no-header --sites "$C" --level 13 --device cuda --repeat 3 --distance
timeout 240 $B --csv --no-header --sites "uniform:135000" --level 15 --device cuda --repeat 3
} 2>&1 | tee "$out/bench.csv"
# The docs' figures and Table 3 (bench/figures.sh): CSV, PNG where matplotlib is installed.
QTMV_BENCH=$B bash bench/figures.sh "$out/figures.csv" 2>&1 | tail -20
