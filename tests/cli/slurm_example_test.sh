#!/usr/bin/env bash
# examples/slurm_tiles.sh against a stand-in sbatch (tests/cli/fake_slurm/sbatch: it runs each
# array task, then the merge, at once on this machine), so that its job scripts and quoting are
# checked without a cluster: the merged regions must equal one whole run's, byte for byte (CSV).
#   slurm_example_test.sh QTMVORONOI TESTDATA_DIR
set -euo pipefail
tool=$1 data=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
export PATH="$(cd "$(dirname "$0")" && pwd)/fake_slurm:$PATH" QTMVORONOI=$tool
reading=(-oo X_POSSIBLE_NAMES=lon -oo Y_POSSIBLE_NAMES=lat -s_srs EPSG:4326 -where "lon > -100" -device cpu)
"$tool" -q -level 9 "${reading[@]}" -of CSV -layers regions,voronoi_edges "$data/country_centres.csv" "$work/whole"
examples/slurm_tiles.sh 9 6 "$data/country_centres.csv" "$work/merged" "$work/tiles dir" "${reading[@]}" \
  -- -of CSV -layers regions,voronoi_edges
for f in regions voronoi_edges; do
  cmp "$work/whole/$f.csv" "$work/merged/$f.csv"
  [ -s "$work/whole/$f.csv" ]
done
[ "$(ls "$work/tiles dir"/*.qtmt | wc -l)" -eq 6 ]
echo "slurm_tiles.sh: 6 array tasks and the merge = one whole run"
