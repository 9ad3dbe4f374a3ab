#!/usr/bin/env bash
# Configures and builds qtmvoronoi in build/ (Ninja, Release). Extra arguments go to CMake.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release "$@"
cmake --build build -j "$(nproc)"
