#!/usr/bin/env bash
# Builds everything with AddressSanitizer and UndefinedBehaviorSanitizer (CUDA off) in
# build-asan/ and runs the unit tests and the bad-input catalogue there: any report fails.
# The tools the tests start inherit the options below, so a report in qtmvoronoi fails too.
# LeakSanitizer runs too, with no suppression file: it finds no leak, GDAL's and PROJ's included.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/deps.sh
flags="-fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer"
cmake -S . -B build-asan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DQTMV_CUDA=OFF \
  -DCMAKE_CXX_FLAGS="$flags" -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=address,undefined" "$@"
cmake --build build-asan -j "$(nproc)"
# exitcode=86: a report is never mistaken for qtmvoronoi's own exit status 1.
export ASAN_OPTIONS="halt_on_error=1:exitcode=86:detect_leaks=1:detect_stack_use_after_return=1:strict_string_checks=1"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1:exitcode=86"
ctest --test-dir build-asan --output-on-failure -j "$(nproc)" --timeout 1200
