#!/usr/bin/env bash
# examples/slurm_tiles.sh on a real Slurm: Debian's slurm-wlm and munge, started here as a one-node
# cluster on localhost (its own slurm.conf, munge key and socket, ports, spool and state in a
# temporary directory; every daemon stopped on exit). Two runs of the example, unchanged:
#  1. the job array of tile jobs, then the merge after afterok: the merged CSV equals one whole run's;
#  2. one task fails (its tile's path is taken by a directory): the merge stays pending with
#     DependencyNeverSatisfied; it is cancelled, the failed index is rerun (sbatch --array=K of the
#     array's own job script), then the merge's own job script after it: again the whole run;
#  3. FORM=parts: the tasks write parts, the job after them their index; dissolved by site_fid,
#     the index's regions are the whole run's.
# scripts/test.sh installs slurm-wlm and munge; without them, or not as root (slurmd must be
# root to start jobs), the test is skipped (exit 77) with a warning.
#   slurm_example_test.sh QTMVORONOI TESTDATA_DIR
set -euo pipefail
tool=$1 data=$2
skip() { echo "qtmvoronoi: warning: $1; the real-Slurm test of examples/slurm_tiles.sh is skipped" >&2; exit 77; }
for p in slurmctld slurmd sbatch squeue scontrol munged python3; do
  command -v "$p" > /dev/null || skip "$p is not installed (scripts/test.sh installs slurm-wlm and munge)"
done
[ "$(id -u)" -eq 0 ] || skip "not root (slurmd starts jobs only as root)"

# A short path: the munge socket's must fit in 108 bytes. 0755: munged wants its socket reachable.
work=$(mktemp -d /tmp/qtmv-slurm.XXXXXX)
chmod 755 "$work"
pids=()
stop_cluster() {
  set +e
  [ -n "${SLURM_CONF:-}" ] && scancel --quiet --user=root 2> /dev/null
  # The Slurm daemons first, munged (the first started) last.
  for ((i = ${#pids[@]} - 1; i >= 0; i--)); do kill "${pids[i]}" 2> /dev/null; wait "${pids[i]}" 2> /dev/null; done
  rm -rf "$work"
}
trap stop_cluster EXIT
fail() {
  echo "slurm_example_test: $1" >&2
  squeue -t all -r -o '%i %T %r %E' >&2 || true
  tail -n 20 "$work"/*.log "$work"/*/*.log >&2 2> /dev/null || true
  exit 1
}

# munge: its own key and socket (-f: munged refuses to run as root without it).
dd if=/dev/urandom of="$work/munge.key" bs=1024 count=1 status=none
chmod 400 "$work/munge.key"
# -F: a child of this script, stopped and reaped on exit like the Slurm daemons.
munged -F -f -S "$work/munge.socket" --key-file="$work/munge.key" --pid-file="$work/munged.pid" \
  --log-file="$work/munged.log" --seed-file="$work/munged.seed" > "$work/munged.out" 2>&1 &
pids+=($!)
for _ in $(seq 100); do [ -S "$work/munge.socket" ] && break; sleep 0.1; done

# Two free TCP ports, so that runs side by side do not collide.
read -r ctld_port slurmd_port < <(python3 -c '
import socket
s = [socket.socket() for _ in range(2)]
for x in s: x.bind(("127.0.0.1", 0))
print(*[x.getsockname()[1] for x in s])')
# This machine's CPUs, sockets, cores and RealMemory, as slurmd sees them.
hardware=$(slurmd -C | head -n 1 | sed 's/^NodeName=[^ ]* //')
mkdir "$work/state" "$work/spool"
export SLURM_CONF=$work/slurm.conf
cat > "$SLURM_CONF" << EOF
ClusterName=qtmvtest
SlurmctldHost=localhost(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$work/munge.socket
StateSaveLocation=$work/state
SlurmdSpoolDir=$work/spool
SlurmctldPidFile=$work/slurmctld.pid
SlurmdPidFile=$work/slurmd.pid
SlurmctldLogFile=$work/slurmctld.log
SlurmdLogFile=$work/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MpiDefault=none
SchedulerType=sched/builtin
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
MinJobAge=3600
NodeName=qtmvnode NodeHostname=localhost NodeAddr=127.0.0.1 $hardware State=UNKNOWN
PartitionName=qtmv Nodes=qtmvnode Default=YES MaxTime=INFINITE State=UP
EOF
slurmctld -D -i > "$work/slurmctld.out" 2>&1 &
pids+=($!)
slurmd -D -N qtmvnode > "$work/slurmd.out" 2>&1 &
pids+=($!)
for _ in $(seq 300); do
  [ "$(sinfo -h -n qtmvnode -o %t 2> /dev/null)" = idle ] && break
  sleep 0.2
done
[ "$(sinfo -h -n qtmvnode -o %t 2> /dev/null)" = idle ] || fail "the one-node cluster did not come up"

# wait_for JOB: until none of its tasks is pending or running (3 minutes at most).
wait_for() {
  local states
  for _ in $(seq 900); do
    states=$(squeue -h -t all -r -j "$1" -o %T)
    if [ -n "$states" ] && ! grep -q -E 'PENDING|CONFIGURING|RUNNING|COMPLETING|REQUEUE' <<< "$states"; then
      return 0
    fi
    sleep 0.2
  done
  fail "job $1 did not finish"
}
# run_example TILE_DIR DESTINATION: sets $array and $merge, the example's job ids.
run_example() {
  local said
  said=$(examples/slurm_tiles.sh 9 6 "$data/country_centres.csv" "$2" "$1" "${reading[@]}" \
           -- -of CSV -layers regions,voronoi_edges)
  echo "$said"
  array="" merge=""
  read -r array merge < <(sed -n 's/^tile jobs: array \([0-9]*\) .*merge: job \([0-9]*\) .*/\1 \2/p' <<< "$said") || true
  [ -n "$merge" ] || fail "no job ids in the example's output"
}
same_as_whole() {
  for f in regions voronoi_edges; do
    cmp "$work/whole/$f.csv" "$1/$f.csv" || fail "$1/$f.csv differs from the whole run's"
  done
}

# No GPU in this cluster: no --gpus=1 for the tile jobs. The jobs inherit QTMVORONOI.
export QTMVORONOI=$tool SBATCH_TILE_OPTIONS=""
reading=(-oo X_POSSIBLE_NAMES=lon -oo Y_POSSIBLE_NAMES=lat -s_srs EPSG:4326 -where "lon > -100" -device cpu)
"$tool" -q -level 9 "${reading[@]}" -of CSV -layers regions,voronoi_edges "$data/country_centres.csv" "$work/whole"
[ -s "$work/whole/regions.csv" ] && [ -s "$work/whole/voronoi_edges.csv" ]

# 1. Every task succeeds: the merge runs after them.
run_example "$work/tiles dir" "$work/merged"
wait_for "$array"
wait_for "$merge"
[ "$(squeue -h -t all -r -j "$array,$merge" -o %T | sort | uniq -c | xargs)" = "7 COMPLETED" ] ||
  fail "not every job completed"
same_as_whole "$work/merged"
[ "$(find "$work/tiles dir" -name '*.qtmt' | wc -l)" -eq 6 ] || fail "not 6 tiles"

# 2. Task 3 fails: a directory stands where its tile goes.
mkdir -p "$work/tiles2/3.qtmt"
run_example "$work/tiles2" "$work/merged2"
wait_for "$array"
[ "$(squeue -h -t all -r -j "${array}_3" -o %T)" = FAILED ] || fail "task 3 did not fail"
reason=""
for _ in $(seq 150); do
  reason=$(squeue -h -j "$merge" -o '%T %r')
  [ "$reason" = "PENDING DependencyNeverSatisfied" ] && break
  sleep 0.2
done
[ "$reason" = "PENDING DependencyNeverSatisfied" ] || fail "the merge is '$reason', not held for ever"
[ ! -e "$work/merged2" ] || fail "the merge ran after a failed task"
# The array's and the merge's own job scripts, rerun: the failed index, then the merge after it.
scontrol write batch_script "$array" "$work/tile_job.sh" > /dev/null
scontrol write batch_script "$merge" "$work/merge_job.sh" > /dev/null
scancel "$merge"
rmdir "$work/tiles2/3.qtmt"
rerun=$(sbatch --parsable --array=3 --output="$work/tiles2/tile-%a.log" "$work/tile_job.sh")
merge=$(sbatch --parsable --dependency=afterok:"$rerun" --output="$work/tiles2/merge.log" "$work/merge_job.sh")
wait_for "$merge"
[ "$(squeue -h -t all -r -j "$rerun,$merge" -o %T | xargs)" = "COMPLETED COMPLETED" ] ||
  fail "the rerun or its merge did not complete"
same_as_whole "$work/merged2"

# 3. The parts form: every task writes its part, the job after them their index; dissolved by
# site_fid, the index's regions are the whole run's (cells per site, areas to 1e-9 relative).
rows() { ogr2ogr -f CSV /vsistdout/ -dialect sqlite -sql "$2" "$1"; }
said=$(FORM=parts examples/slurm_tiles.sh 9 6 "$data/country_centres.csv" "$work/parts.vrt" "$work/parts" \
         "${reading[@]}" -- -layers regions)
echo "$said"
read -r array merge < <(sed -n 's/^tile jobs: array \([0-9]*\) .*merge: job \([0-9]*\) .*/\1 \2/p' <<< "$said") || true
[ -n "${merge:-}" ] || fail "no job ids in the example's output (parts)"
wait_for "$array"
wait_for "$merge"
[ "$(squeue -h -t all -r -j "$array,$merge" -o %T | sort | uniq -c | xargs)" = "7 COMPLETED" ] ||
  fail "not every job of the parts form completed"
[ "$(find "$work/parts" -name '*.gpkg' | wc -l)" -eq 6 ] || fail "not 6 parts"
paste -d, <(rows "$work/whole/regions.csv" "SELECT CAST(site_fid AS INTEGER), CAST(cells AS INTEGER),
              CAST(area_m2 AS REAL) FROM regions WHERE CAST(cells AS INTEGER) > 0 ORDER BY 1") \
          <(rows "$work/parts.vrt" "SELECT site_fid, SUM(cells), SUM(area_m2), COUNT(*) FROM regions GROUP BY site_fid
              ORDER BY site_fid") |
  awk -F, 'NR > 1 { gsub(/"/, ""); n++; if ($1 != $4 || $2 != $5 || ($3 - $6) ^ 2 > (1e-9 * $3) ^ 2) bad++; if ($7 > 1) cut++ }
           END { exit (bad || n < 10 || !cut) }' || fail "the parts' regions, dissolved, are not the whole run's"
echo "slurm_tiles.sh on a one-node Slurm: 6 array tasks and the merge = one whole run;" \
     "a failed task holds the merge, and its rerun then the merge complete it;" \
     "6 parts and their index = the whole run's regions"
