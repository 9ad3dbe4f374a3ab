#!/usr/bin/env python3
"""Alternating runs of several commands, for comparing binaries on a noisy shared machine.

    python3 bench/alternate.py REPEAT LABEL=COMMAND [LABEL=COMMAND ...]

Each COMMAND is split as a shell would split it; its last argument is its output, removed (and the
disk synced) before each timed run, outside the timing. The commands run in turn, REPEAT rounds,
with QTMV_TRACE=write. Each run's line: exit status, wall time (process start to exit), peak
resident memory, qtmvoronoi's stage summary and the write trace's steps (seconds); then the median
wall time and the largest peak of each label.
"""
import os
import re
import shlex
import statistics
import subprocess
import sys
import time


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    repeat = int(sys.argv[1])
    cases = [a.split("=", 1) for a in sys.argv[2:]]
    results = {label: [] for label, _ in cases}
    for r in range(repeat):
        for label, command in cases:
            argv = shlex.split(command)
            if os.path.exists(argv[-1]):
                os.remove(argv[-1])
            os.sync()
            env = dict(os.environ, QTMV_TRACE="write")
            start = time.monotonic()
            child = subprocess.Popen(argv, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, env=env, text=True)
            err = child.stderr.read()
            _, status, usage = os.wait4(child.pid, 0)
            wall = time.monotonic() - start
            rc = os.waitstatus_to_exitcode(status)
            steps = {m.group(1).strip(): float(m.group(2)) / 1000
                     for m in re.finditer(r"trace: write (.*?)\s+([0-9.]+) ms", err)}
            summary = re.search(r"read ([0-9.]+) s.*?label ([0-9.]+) s.*?write ([0-9.]+) s", err)
            peak_mb = usage.ru_maxrss / 1024
            results[label].append((wall, peak_mb))
            print("%s run %d: rc %d wall %.2f s peak %.0f MB %s | %s" %
                  (label, r, rc, wall, peak_mb, summary.group(0) if summary else "",
                   " ".join("%s=%.2f" % (k[:24], v) for k, v in steps.items())), flush=True)
            if rc != 0:
                print(err[-2000:])
    for label, runs in results.items():
        print("MEDIAN %s: wall %.2f s, peak %.0f MB" %
              (label, statistics.median(w for w, _ in runs), max(p for _, p in runs)))


if __name__ == "__main__":
    main()
