#!/usr/bin/env bash
# The Debian package (`cpack -G DEB` in the build directory): its control fields, its files, its
# dependencies against the libraries the tools load, apt's view of installing it on this system,
# and the packaged tool, unpacked into a root of its own, against the build's tool.
#
#   deb_package_test.sh BUILD_DIR TESTDATA_DIR
set -euo pipefail
build=$1 testdata=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
trap 'echo "FAIL: line $LINENO: $BASH_COMMAND" >&2' ERR

cpack -G DEB --config "$build/CPackConfig.cmake" -B "$work/out" > "$work/cpack.log" 2>&1 || { cat "$work/cpack.log"; fail "cpack"; }
deb=$(ls "$work"/out/qtmvoronoi_*_*.deb)
echo "package: $(basename "$deb")"
[ "$(dpkg-deb -f "$deb" Package)" = qtmvoronoi ] || fail "Package is not qtmvoronoi"
[ "$(dpkg-deb -f "$deb" Architecture)" = "$(dpkg --print-architecture)" ] || fail "Architecture"
depends=$(dpkg-deb -f "$deb" Depends)
echo "Depends: $depends"

# No pipe here ends before its writer does (`head`, `grep -q`, awk's `exit`): under pipefail the
# writer's SIGPIPE would fail the test at random.

# The files a user expects.
contents=$(dpkg-deb -c "$deb" | awk '{print $6}')
for f in ./usr/bin/qtmvoronoi ./usr/bin/qtmcell ./usr/share/man/man1/qtmvoronoi.1.gz \
         ./usr/share/man/man1/qtmcell.1.gz ./usr/share/doc/qtmvoronoi/README.md \
         ./usr/share/qgis/python/plugins/qtmvoronoi_processing/metadata.txt \
         ./usr/share/qgis/python/plugins/qtmvoronoi_processing/algorithms.py; do
  grep -qx -- "$f" <<<"$contents" || fail "the package lacks $f"
done
dpkg-deb -x "$deb" "$work/root"

# Every library a packaged tool links directly comes from a package the .deb depends on.
depends_names=$(tr ',' '\n' <<<"$depends" | sed 's/^ *//; s/ .*//; s/:.*//')
for tool in qtmvoronoi qtmcell; do
  bin=$work/root/usr/bin/$tool
  for soname in $(objdump -p "$bin" | awk '$1 == "NEEDED" {print $2}'); do
    # "libx.so.1 => /path (addr)", or "/lib64/ld-linux-x86-64.so.2 (addr)" for the loader.
    path=$(ldd "$bin" | awk -v s="$soname" '!found && $1 == s {print $3; found = 1} !found && $1 ~ "/" s "$" {print $1; found = 1}')
    [ -n "$path" ] || fail "$tool: $soname is not found on this system"
    owner=""
    for p in "$path" "$(readlink -f "$path")" "${path/#\/lib\//\/usr\/lib\/}" "${path/#\/usr\/lib\//\/lib\/}"; do
      owner=$(dpkg -S "$p" 2>/dev/null | awk -F: 'NR == 1 {print $1}') && [ -n "$owner" ] && break
    done
    [ -n "$owner" ] || fail "$tool: no package owns $path"
    grep -qx -- "$owner" <<<"$depends_names" || fail "$tool needs $soname of package $owner, which Depends lacks"
  done
done

# apt would install it here: every dependency can be met.
apt-get -s install "$deb" > "$work/apt.log" 2>&1 || { cat "$work/apt.log"; fail "apt-get -s install"; }
grep -q "^Inst qtmvoronoi" "$work/apt.log" || { cat "$work/apt.log"; fail "apt-get would not install the package"; }

# The man page is the tool's, and man reads it.
# (Outputs are read whole before grep: `grep -q` in a pipe under pipefail can fail the pipe.)
page=$(zcat "$work/root/usr/share/man/man1/qtmvoronoi.1.gz")
grep -q '^\.TH QTMVORONOI 1' <<<"$page" || fail "qtmvoronoi.1.gz is not its man page"
if command -v man > /dev/null; then
  shown=$(MANWIDTH=80 man -l "$work/root/usr/share/man/man1/qtmvoronoi.1.gz" 2> /dev/null || true)
  grep -q -- "-vertices" <<<"$shown" || fail "man cannot show the page"
fi

# The packaged tool does the main job as the build's does.
packaged=$work/root/usr/bin/qtmvoronoi
version_line=$("$packaged" --version)
grep -q "qtmvoronoi" <<<"$version_line" || fail "--version"
csv=(-oo X_POSSIBLE_NAMES=lon -oo Y_POSSIBLE_NAMES=lat -s_srs EPSG:4326)
"$packaged" -q -level 7 -device cpu -of CSV -layers regions "${csv[@]}" "$testdata/country_centres.csv" "$work/packaged.csv"
"$build/tools/qtmvoronoi/qtmvoronoi" -q -level 7 -device cpu -of CSV -layers regions "${csv[@]}" \
  "$testdata/country_centres.csv" "$work/built.csv"
cmp -s "$work/packaged.csv" "$work/built.csv" || fail "the packaged tool's regions differ from the build's"
[ "$(wc -l < "$work/packaged.csv")" -gt 200 ] || fail "too few regions"

# The Python package, where the build has it: in Debian python3's own dist-packages, with its
# python3 and numpy dependencies, and the packaged module's regions are the packaged tool's.
if [ -d "$build/python/qtmvoronoi" ]; then
  site=/usr/lib/python3/dist-packages
  module=$(ls "$build"/python/qtmvoronoi/_qtmvoronoi*.so)
  for f in __init__.py conversions.py run.py dask.py "$(basename "$module")"; do
    grep -qx -- ".$site/qtmvoronoi/$f" <<<"$contents" || fail "the package lacks $site/qtmvoronoi/$f"
  done
  grep -qx "python3" <<<"$depends_names" || fail "Depends lacks python3"
  grep -qx "python3-numpy" <<<"$depends_names" || fail "Depends lacks python3-numpy"
  if /usr/bin/python3 -c "import geopandas, osgeo.ogr" 2> /dev/null; then
    PYTHONPATH=$work/root$site /usr/bin/python3 - "$work/root" "$testdata/country_centres.csv" "$work/built.csv" <<'PY' || fail "the packaged Python package"
import sys
import geopandas as gpd
import qtmvoronoi
root, centres, built = sys.argv[1:]
assert qtmvoronoi.__file__.startswith(root), qtmvoronoi.__file__
assert qtmvoronoi.lonlat_to_code(0.0, 90.0, 0) == 0
regions = qtmvoronoi.voronoi(centres, 7, device="cpu", open_options=["X_POSSIBLE_NAMES=lon", "Y_POSSIBLE_NAMES=lat"], s_srs="EPSG:4326")
tool = gpd.read_file(built)
assert regions.site_fid.tolist() == tool.site_fid.astype(int).tolist()
assert regions.cells.tolist() == tool.cells.astype(int).tolist()
PY
  fi
fi
echo "ok"
