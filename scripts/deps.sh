#!/usr/bin/env bash
# Installs the Debian 12 packages that qtmvoronoi needs to build and test, and any named as
# arguments, when they are missing.
# CUDA is not among them: the build finds nvcc (/usr/local/cuda/bin) when it is there.
set -euo pipefail

# parallel: GNU parallel, for the test of the tile jobs' example (examples/tiles_gnu_parallel.sh).
# dpkg-dev and file: cpack's Debian package (dpkg-shlibdeps finds its dependencies).
# python3-dev, python3-numpy, pybind11-dev: the Python package (python/; left out without them).
packages=(cmake ninja-build g++ pkg-config perl parallel dpkg-dev file
          libgdal-dev libgeos-dev libsqlite3-dev libgeographiclib-dev libgtest-dev libbenchmark-dev
          python3-dev python3-numpy pybind11-dev)

# Arguments: more packages a script needs (the demo: gdal-bin, for its picture).
packages+=("$@")

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done
[ ${#missing[@]} -eq 0 ] && exit 0

echo "qtmvoronoi: installing missing Debian packages: ${missing[*]}" >&2
sudo=""
if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -q
$sudo apt-get install -y -q --no-install-recommends "${missing[@]}"
