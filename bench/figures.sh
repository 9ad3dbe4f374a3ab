#!/bin/bash
# The qtmv_bench runs behind the docs' figures (the paper's Figures 5 and 6) and Table 3, then
# bench/plot_figures.py on them. For the GPU machine; about a minute on one H200, most of it
# the brute-force rows with 100 000 and 135 000 sites.
# Usage, from the repository root, after a core-only CUDA build such as bench/label_device_run.sh makes:
#   bash bench/figures.sh OUT.csv        (writes OUT.csv, OUT.png, and prints Table 3)
# QTMV_BENCH=path picks another qtmv_bench binary; CHECK=N the size of each row's reference sample.
set -u -o pipefail
csv=${1:?usage: bash bench/figures.sh OUT.csv}
B=${QTMV_BENCH:-build-dev/tools/bench/qtmv_bench}
C=testdata/country_centres.csv
U="uniform:1000;uniform:10000;uniform:100000;uniform:135000"
# Labels are checked against float64 brute force on 10 000 random cells a row, not the benchmark's
# 1 000 000, to keep the run short: these rows are for drawing; label_device_run.sh does the full check.
CHECK=${CHECK:-10000}
[ -f "$C" ] || { echo "figures.sh: no $C (run from the repository root)" >&2; exit 1; }
[ -x "$B" ] || { echo "figures.sh: no $B (build qtmv_bench first, or set QTMV_BENCH)" >&2; exit 1; }

: >"$csv" || exit 1
header=
fail=0
run() {
  echo "figures.sh: qtmv_bench $*" >&2
  "$B" --csv $header --check "$CHECK" "$@" >>"$csv" || fail=1
  header=--no-header  # one header line in the file
}
# Figure 5: time against level, 241 country centres, both algorithms on the GPU, hier on all CPU cores.
run --sites "$C" --level 5,6,7,8,9,10,11,12,13 --device cuda --repeat 5
run --sites "$C" --level 5,6,7,8,9,10,11,12,13 --device cuda --repeat 3 --algorithm brute
run --sites "$C" --level 5,6,7,8,9,10,11 --device cpu --repeat 3
# Figure 6: time against site count at level 11. GPU brute force takes ~5 s a run at 135 000
# sites (plus an untimed warm-up run), hence one repetition.
run --sites "$U" --level 11 --device cuda --repeat 5
run --sites "$U" --level 11 --device cuda --repeat 1 --algorithm brute
run --sites "$U" --level 11 --device cpu --repeat 1
# Table 3: one CPU thread at levels 5 to 9 (brute ~1.2 s at level 9), against the GPU rows above.
run --sites "$C" --level 5,6,7,8,9 --device cpu --threads 1 --repeat 3
run --sites "$C" --level 5,6,7,8,9 --device cpu --threads 1 --repeat 1 --algorithm brute
[ $fail = 0 ] || echo "figures.sh: a qtmv_bench run failed or found mismatches (above)" >&2

# Debian's python3-matplotlib is in /usr/bin/python3, which a python3 earlier on PATH may hide.
for py in python3 /usr/bin/python3; do
  if "$py" -c "import matplotlib" 2>/dev/null; then
    "$py" bench/plot_figures.py --out "${csv%.csv}" "$csv" || fail=1
    exit $fail
  fi
done
echo "figures.sh: no matplotlib here: Table 3 only; draw later with bench/plot_figures.py $csv" >&2
python3 bench/plot_figures.py --no-plot "$csv" || fail=1
exit $fail
