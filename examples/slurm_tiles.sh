#!/usr/bin/env bash
# A qtmvoronoi run split into tile jobs over a Slurm cluster: a job array of TILES tasks (one GPU
# each, when the partition has them), then one merge job that runs once the whole array succeeded.
# Two forms (FORM):
#   one-file (the default): the tasks write tile products and the merge writes the output, the
#     same as one run's;
#   parts: each task writes its part of the output into TILE_DIR (-tile K/N -part: a GeoPackage,
#     regions cut at the tile's edges; with a raster option among the OUTPUT OPTIONS (-raster,
#     -tr, -ts, -bands, -ot, -co) a GeoTIFF, a band of the raster's rows), so that the nodes write
#     at once; the merge job writes only their index (-merge -of VRT), DESTINATION (a .vrt), which
#     reads them as one data set.
#
#   slurm_tiles.sh LEVEL TILES SOURCE DESTINATION TILE_DIR [READING OPTIONS...] [-- OUTPUT OPTIONS...]
#
# SOURCE and TILE_DIR must be on a file system that every node sees (or a /vsis3/ style GDAL
# path). READING OPTIONS go to every task and to the merge, OUTPUT OPTIONS to the merge alone
# (parts: to every task).
# Extra sbatch options: SBATCH_TILE_OPTIONS (default "--gpus=1"; set it empty on a cluster without
# GPUs), SBATCH_MERGE_OPTIONS.
#
# When a task fails, the merge stays pending (squeue: DependencyNeverSatisfied). Cancel it, mend
# the cause, rerun the failed tasks and then the merge from their own job scripts, e.g. for task 3:
#   scontrol write batch_script ARRAY_ID tile.sh; scontrol write batch_script MERGE_ID merge.sh
#   scancel MERGE_ID; rerun=$(sbatch --parsable --array=3 --output=TILE_DIR/tile-%a.log tile.sh)
#   sbatch --dependency=afterok:$rerun --output=TILE_DIR/merge.log merge.sh
# (tests/cli/slurm_example_test.sh does this on a one-node cluster.)
#
# Example: level 16 in 16 tiles, the regions as a GeoPackage
#   examples/slurm_tiles.sh 16 16 /shared/sites.gpkg /shared/voronoi.gpkg /shared/tiles -- -layers regions
# The same as 16 parts in /shared/parts and their index
#   FORM=parts examples/slurm_tiles.sh 16 16 /shared/sites.gpkg /shared/voronoi.vrt /shared/parts -- -layers regions
set -euo pipefail

if [ $# -lt 5 ]; then
  sed -n '13,19p' "$0" >&2
  exit 2
fi
form=${FORM:-one-file}
[ "$form" = one-file ] || [ "$form" = parts ] || { echo "$0: FORM is one-file or parts, not '$form'" >&2; exit 2; }
level=$1 tiles=$2 source=$3 destination=$4 tile_dir=$5
shift 5
reading=()
while [ $# -gt 0 ] && [ "$1" != "--" ]; do reading+=("$1"); shift; done
[ $# -gt 0 ] && shift
output=("$@")
mkdir -p "$tile_dir"
tool=${QTMVORONOI:-qtmvoronoi}
quoted_reading="" quoted_output=""
[ ${#reading[@]} -gt 0 ] && quoted_reading=$(printf ' %q' "${reading[@]}")
[ ${#output[@]} -gt 0 ] && quoted_output=$(printf ' %q' "${output[@]}")

# Each task labels tile $SLURM_ARRAY_TASK_ID of $tiles; --parsable gives the array's job id. A
# part takes the output options; a tile product none.
if [ "$form" = parts ]; then
  part=gpkg
  for o in ${output[@]+"${output[@]}"}; do
    case $o in -raster | -tr | -ts | -bands | -ot | -co) part=tif ;; esac  # a raster's parts: GeoTIFFs
  done
  task_output=" -part$quoted_output" product="\$SLURM_ARRAY_TASK_ID.$part"
else
  task_output="" product='$SLURM_ARRAY_TASK_ID.qtmt'
fi
array=$(sbatch --parsable --job-name=qtmv-tiles --array=1-"$tiles" ${SBATCH_TILE_OPTIONS---gpus=1} \
  --output="$tile_dir/tile-%a.log" \
  --wrap="$(printf '%q' "$tool") -q -overwrite -level $level -tile \$SLURM_ARRAY_TASK_ID/$tiles$quoted_reading$task_output \
$(printf '%q' "$source") $(printf '%q' "$tile_dir")/$product")
# The merge (or the parts' index) needs no GPU; afterok: only when every task of the array succeeded.
if [ "$form" = parts ]; then
  merge_command="$(printf '%q' "$tool") -merge $(printf '%q' "$tile_dir") -of VRT $(printf '%q' "$destination")"
else
  merge_command="$(printf '%q' "$tool") -level $level -merge $(printf '%q' "$tile_dir")$quoted_reading$quoted_output \
$(printf '%q' "$source") $(printf '%q' "$destination")"
fi
merge=$(sbatch --parsable --job-name=qtmv-merge --dependency=afterok:"$array" ${SBATCH_MERGE_OPTIONS:-} \
  --output="$tile_dir/merge.log" --wrap="$merge_command")
echo "tile jobs: array $array ($tiles tasks); merge: job $merge (after them); logs in $tile_dir"
