#!/usr/bin/env bash
# A PostgreSQL/PostGIS destination written all or nothing (postgis_destination_test.py), on a
# throwaway cluster that pg_virtualenv (postgresql-common) starts for the test and drops after.
# Skipped (77) without pg_virtualenv, a PostgreSQL server or PostGIS (scripts/test.sh installs
# postgresql and postgresql-15-postgis-3). -t: the cluster in a temporary directory even as root
# (as root pg_virtualenv would otherwise make it in /etc/postgresql, where a cluster left by
# a killed run, or another run's, stops it: "Cluster 15/regress exists").
#   postgis_destination_test.sh QTMVORONOI TESTDATA
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
if ! command -v pg_virtualenv >/dev/null; then
  echo "skipped: no pg_virtualenv (Debian's postgresql-common): the PostGIS destination is not tested" >&2
  exit 77
fi
if ! ls /usr/lib/postgresql/*/bin/initdb >/dev/null 2>&1; then
  echo "skipped: no PostgreSQL server (Debian's postgresql): the PostGIS destination is not tested" >&2
  exit 77
fi
if ! ls /usr/share/postgresql/*/extension/postgis.control >/dev/null 2>&1; then
  echo "skipped: no PostGIS (Debian's postgresql-15-postgis-3): the PostGIS destination is not tested" >&2
  exit 77
fi
if ! /usr/bin/python3 -c "import osgeo" 2>/dev/null; then
  echo "skipped: no python3-gdal: the PostGIS destination is not tested" >&2
  exit 77
fi
cd "${TMPDIR:-/tmp}"
exec pg_virtualenv -t /usr/bin/python3 "$here/postgis_destination_test.py" "$1" "$2"
