#!/usr/bin/env bash
# On the GPU machine, after a change that must keep every byte (a restructuring): builds the
# core-only tree for sm_90 and runs all its tests (the CUDA ones run there), then runs
# bench/output_digests.sh with -device cuda for two builds of the tool and diffs them.
#   bash bench/gpu_same_outputs.sh NEW_BUNDLE.tar.xz OLD_QTMVORONOI[.xz] OUTDIR
# NEW_BUNDLE: scripts/make_bundle.sh's bundle of the change; OLD_QTMVORONOI: the tool built before
# it, run with the bundle's libraries (the same system packages).
set -uo pipefail
bundle=$1 old=$2 out=${3:-/tmp/out}
mkdir -p "$out"
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader
cmake -S . -B build-gpu -G Ninja -DQTMV_WITH_GDAL=OFF -DCMAKE_CUDA_ARCHITECTURES=90 -DCMAKE_BUILD_TYPE=Release >/dev/null || exit 1
cmake --build build-gpu -j"$(nproc)" 2>&1 | grep -E "error|warning: |FAILED"
ctest --test-dir build-gpu --output-on-failure -j8 > "$out/ctest.log" 2>&1
echo "ctest: $(grep -E 'tests passed|tests failed' "$out/ctest.log")"
grep -E "\*\*\*Failed|Not Run|Timeout" "$out/ctest.log" | head -20
skipped=$(grep -c "Skipped" "$out/ctest.log"); echo "ctest: $skipped skipped"
work=$(mktemp -d)
tar -C "$work" -xJf "$bundle"
case "$old" in *.xz) xz -dc "$old" > "$work/old-qtmvoronoi" ;; *) cp "$old" "$work/old-qtmvoronoi" ;; esac
chmod +x "$work/old-qtmvoronoi"
printf '#!/bin/sh\nexec "%s/qtmvoronoi/bin/qtmv-env" "%s/old-qtmvoronoi" "$@"\n' "$work" "$work" > "$work/old"
chmod +x "$work/old"
bash bench/output_digests.sh "$work/qtmvoronoi/bin/qtmvoronoi" cuda > "$out/digests-new-cuda.txt" 2>"$out/digests-new.err"
bash bench/output_digests.sh "$work/old" cuda > "$out/digests-old-cuda.txt" 2>"$out/digests-old.err"
bash bench/output_digests.sh "$work/qtmvoronoi/bin/qtmvoronoi" cpu > "$out/digests-new-cpu.txt" 2>>"$out/digests-new.err"
echo "digests: $(wc -l < "$out/digests-new-cuda.txt") outputs; cuda new vs old:"
diff "$out/digests-old-cuda.txt" "$out/digests-new-cuda.txt" && echo "  identical"
echo "cuda vs cpu (new):"
diff "$out/digests-new-cpu.txt" "$out/digests-new-cuda.txt" && echo "  identical"
