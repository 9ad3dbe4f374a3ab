#!/usr/bin/env bash
# Builds everything and runs the whole test suite (CTest). CUDA tests skip on a machine without a GPU.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/build.sh
ctest --test-dir build --output-on-failure -j "$(nproc)"
