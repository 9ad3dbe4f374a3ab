#!/usr/bin/env bash
# Makes a relocatable bundle of qtmvoronoi for machines without GDAL (GPU clusters, the project's
# GPU test machine): libexec/ the binaries, lib/ the shared libraries ldd lists for them (less
# glibc's own and the CUDA driver, which the machine provides), share/proj/proj.db, share/gdal/,
# and bin/ wrappers that set LD_LIBRARY_PATH, PROJ_DATA and GDAL_DATA. The target needs glibc
# 2.36 or newer (Debian 12's) and, for CUDA, an NVIDIA driver.
#
#   scripts/make_bundle.sh BUILD_DIR OUT.tar.xz [EXTRA_BINARY...]
#
# BUILD_DIR's tools/qtmvoronoi/qtmvoronoi and tools/qtmcell/qtmcell go in, with any extra binaries
# (test programs, say). On the target: tar xJf OUT.tar.xz; qtmvoronoi/bin/qtmvoronoi ...; or
# qtmvoronoi/bin/qtmv-env PROGRAM ... for another program of the bundle (libexec/ is on its PATH).
set -euo pipefail
[[ $# -ge 2 ]] || { echo "usage: $0 BUILD_DIR OUT.tar.xz [EXTRA_BINARY...]" >&2; exit 2; }
build=$1 out=$2
shift 2
binaries=("$build/tools/qtmvoronoi/qtmvoronoi" "$build/tools/qtmcell/qtmcell" "$@")
for b in "${binaries[@]}"; do [[ -x $b ]] || { echo "$0: '$b' is not an executable" >&2; exit 1; }; done
proj_db=$(find /usr/share/proj -name proj.db -print -quit 2>/dev/null || true)
[[ -n $proj_db && -d /usr/share/gdal ]] || { echo "$0: no proj.db or /usr/share/gdal on this machine" >&2; exit 1; }

stage=$(mktemp -d)
trap 'rm -rf "$stage"' EXIT
root=$stage/qtmvoronoi
mkdir -p "$root/bin" "$root/libexec" "$root/lib" "$root/share/proj"
for b in "${binaries[@]}"; do cp "$b" "$root/libexec/"; done
# The machine provides glibc, the dynamic loader and the CUDA driver; everything else comes along.
system_lib='^(linux-vdso|libc|libm|libdl|libpthread|librt|libutil|libresolv|ld-linux[^ ]*|libcuda)\.so'
for b in "${binaries[@]}"; do
  ldd "$b" | awk '$2 == "=>" && $3 ~ /^\// {print $1, $3}' | while read -r name path; do
    [[ $name =~ $system_lib ]] || cp -nL "$path" "$root/lib/$name"
  done
done
cp "$proj_db" "$root/share/proj/"
cp -r /usr/share/gdal "$root/share/gdal"
cat >"$root/bin/qtmv-env" <<'WRAP'
#!/bin/sh
# Runs a program of this bundle (or any command) with the bundle's libraries and data.
here=$(cd "$(dirname "$0")/.." && pwd)
export LD_LIBRARY_PATH="$here/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
export PROJ_DATA="$here/share/proj" PROJ_LIB="$here/share/proj" GDAL_DATA="$here/share/gdal"
export PATH="$here/libexec:$PATH"
exec "$@"
WRAP
chmod +x "$root/bin/qtmv-env"
for tool in qtmvoronoi qtmcell; do
  printf '#!/bin/sh\nexec "$(dirname "$0")/qtmv-env" "$(dirname "$0")/../libexec/%s" "$@"\n' "$tool" >"$root/bin/$tool"
  chmod +x "$root/bin/$tool"
done
mkdir -p "$(dirname "$out")"
tar -C "$stage" -cJf "$out" qtmvoronoi
echo "$out: $(du -h "$out" | cut -f1), $(ls "$root/lib" | wc -l) libraries"
