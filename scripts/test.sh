#!/usr/bin/env bash
# Builds everything and runs the whole test suite (CTest). CUDA tests skip on a machine without a GPU.
set -euo pipefail
cd "$(dirname "$0")/.."
# QGIS (3.22 on Debian 12) for the test of the QGIS Processing provider: a test dependency only.
# Without it (no package source reachable) that test is left out, with a warning.
scripts/deps.sh qgis python3-qgis qgis-providers ||
  echo "qtmvoronoi: warning: QGIS could not be installed; the QGIS provider's test is left out" >&2
# GDAL's own validators (validate_gpkg.py, the COG validator) and rasterio read the outputs in tests; scipy's
# cKDTree is the lon/lat raster's oracle (tests/cli/ckdtree_oracle_test.py).
scripts/deps.sh python3-gdal python3-scipy python3-rasterio ||
  echo "qtmvoronoi: warning: python3-gdal, python3-scipy or python3-rasterio could not be installed; the validators', rasterio's and the cKDTree oracle's tests are left out" >&2
# The Python package's tests (tests/python/): pytest on Debian's python3, with its GeoPandas, xarray,
# Dask and tqdm, and matplotlib (the README's picture, scripts/python_example.py).
scripts/deps.sh python3-pytest python3-gdal python3-geopandas python3-xarray python3-dask python3-distributed \
  python3-tqdm python3-matplotlib ||
  echo "qtmvoronoi: warning: the Python test packages could not be installed; the Python package's tests are left out" >&2
# Slurm (slurmctld, slurmd, sbatch) and munge for the test of examples/slurm_tiles.sh on a
# one-node cluster that the test starts and stops.
scripts/deps.sh slurm-wlm munge ||
  echo "qtmvoronoi: warning: slurm-wlm and munge could not be installed; the real-Slurm test is left out" >&2
# PostgreSQL 15 and PostGIS for the test of a PostGIS destination (PG:...), on a throwaway cluster
# that pg_virtualenv (postgresql-common) starts for the test.
scripts/deps.sh postgresql postgresql-15-postgis-3 postgresql-common ||
  echo "qtmvoronoi: warning: postgresql and postgresql-15-postgis-3 could not be installed; the PostGIS destination's test is left out" >&2
scripts/build.sh
ctest --test-dir build --output-on-failure -j "$(nproc)"
