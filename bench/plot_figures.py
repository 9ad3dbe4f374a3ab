#!/usr/bin/env python3
"""Draw the paper's Figures 5 and 6 from qtmv_bench --csv output and print its Table 3.

Figure 5: time against level, one series per (device, algorithm, sites). Figure 6: time against
site count, the uniform:N rows at one level. Solid lines are label_ms (the per-cell pass), dashed
lines label_ms + prepare_ms (candidates and tree too). Table 3 (Markdown, to stdout): the
country-centre rows at levels 5 to 9, one CPU thread against the GPU.

Input: one or more CSV files (or - for stdin) as qtmv_bench --csv writes them, several runs
concatenated, with or without repeated header lines. Lines with fewer than 10 fields (build
output, nvidia-smi, error messages) are skipped. Rows that repeat a case are merged by
their median. The CSV does not say whether --distance was given: do not mix such runs.
"""
import argparse
import csv
import os
import statistics
import sys
from collections import defaultdict

COLUMNS = ("sites_spec,sites,pieces,site_cells,level,cells,algorithm,rule,device,threads,repeat,prepare_ms,"
           "label_ms,copy_ms,cells_per_s,mean_candidates,tree_nodes,memory_bytes,checked,mismatches").split(",")
INTS = {"sites", "level", "cells", "threads", "mismatches"}
FLOATS = {"prepare_ms", "label_ms"}
NEEDED = INTS | FLOATS | {"sites_spec", "algorithm", "rule", "device"}
COUNTRIES = "country_centres.csv"


def read_rows(paths):
    """Rows as dicts; qtmv_bench's own column order unless a header line says otherwise."""
    rows = []
    for path in paths:
        columns = COLUMNS
        try:
            handle = sys.stdin if path == "-" else open(path, newline="")
        except OSError as e:
            sys.exit(f"plot_figures: cannot read {path}: {e.strerror}")
        name = "<stdin>" if path == "-" else path
        with handle:
            # Line by line, so that a stray quote in build output cannot swallow the lines after it.
            for number, line in enumerate(handle, 1):
                fields = next(csv.reader([line]), [])
                if fields and fields[0] == "sites_spec":
                    columns = fields
                    if missing := NEEDED - set(columns):
                        sys.exit(f"plot_figures: {name}:{number}: header lacks {', '.join(sorted(missing))}")
                    continue
                if len(fields) < 10:  # not a CSV row: build output and the like
                    continue
                if len(fields) != len(columns):
                    sys.exit(f"plot_figures: {name}:{number}: {len(fields)} fields, expected {len(columns)}")
                row = dict(zip(columns, fields))
                try:
                    for key in INTS:
                        row[key] = int(row[key])
                    for key in FLOATS:
                        row[key] = float(row[key])
                except ValueError:
                    sys.exit(f"plot_figures: {name}:{number}: {key} is not a number: {row[key]!r}")
                if row["mismatches"]:
                    print(f"plot_figures: warning: {name}:{number}: {row['mismatches']} mismatches", file=sys.stderr)
                rows.append(row)
    return rows


def merge(rows):
    """One row per case: the median of label_ms and of prepare_ms over the runs that repeat it."""
    groups = defaultdict(list)
    for r in rows:
        groups[(r["device"], r["algorithm"], r["rule"], r["sites_spec"], r["level"])].append(r)
    merged = []
    for same in groups.values():
        row = dict(same[0])
        for key in FLOATS:
            row[key] = statistics.median(r[key] for r in same)
        merged.append(row)
    return merged


def device_name(row):
    """'cuda:0 NVIDIA H200' -> 'NVIDIA H200'; 'cpu (1 threads)' -> 'CPU 1 thread'."""
    if row["device"].startswith("cuda"):
        return row["device"].partition(" ")[2] or row["device"]
    return f"CPU {row['threads']} thread{'s' if row['threads'] != 1 else ''}"


def series_name(row, with_sites=True):
    name = f"{device_name(row)} {row['algorithm']}"
    if row["rule"] != "exact":
        name += f" ({row['rule']} rule)"
    return f"{name}, {os.path.basename(row['sites_spec'])}" if with_sites else name


def draw(ax, groups, xkey):
    """One colour per series: solid = label, dashed = label + prepare."""
    for colour, (name, rows) in enumerate(sorted(groups.items())):
        rows.sort(key=lambda r: r[xkey])
        x = [r[xkey] for r in rows]
        ax.plot(x, [r["label_ms"] for r in rows], "o-", color=f"C{colour % 10}", label=name)
        ax.plot(x, [r["label_ms"] + r["prepare_ms"] for r in rows], "s--", color=f"C{colour % 10}", alpha=0.6)
    # Two grey entries explain the line styles once for all series.
    ax.plot([], [], "-", color="grey", label="label (per-cell pass)")
    ax.plot([], [], "--", color="grey", label="label + prepare (candidates, tree)")
    ax.set_yscale("log")
    ax.set_ylabel("time (ms)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="small")


def short(n):
    """8192 -> '8.2k', 536870912 -> '537M': full counts overlap under the ticks."""
    for unit, scale in (("G", 1e9), ("M", 1e6), ("k", 1e3)):
        if n >= scale:
            return f"{n / scale:.3g}{unit}"
    return str(n)


def plot(rows, level6, out):
    import matplotlib
    matplotlib.use("Agg")  # no display on the GPU machine
    import matplotlib.pyplot as plt

    # Figure 5: a series needs two levels to be a line; single points belong to Figure 6.
    fig5 = defaultdict(list)
    for r in rows:
        fig5[series_name(r)].append(r)
    fig5 = {k: v for k, v in fig5.items() if len({r["level"] for r in v}) > 1}
    fig6 = defaultdict(list)
    for r in rows:
        if r["sites_spec"].startswith("uniform:") and r["level"] == level6:
            fig6[series_name(r, with_sites=False)].append(r)
    panels = [p for p in (fig5, fig6) if p]
    if not panels:
        sys.exit(f"plot_figures: nothing to plot (no series over two levels, no uniform:N rows at level {level6})")
    fig, axes = plt.subplots(1, len(panels), figsize=(7 * len(panels), 5.5), squeeze=False)
    axes = list(axes[0])
    if fig5:
        ax = axes.pop(0)
        draw(ax, fig5, "level")
        levels = sorted({r["level"] for v in fig5.values() for r in v})
        cells = {r["level"]: r["cells"] for v in fig5.values() for r in v}
        ax.set_xticks(levels, [f"{L}\n{short(cells[L])}" for L in levels], fontsize="small")
        ax.set_xlabel("QTM level (above) and cells (below)")
        ax.set_title("Time against level (cf. the paper's Figure 5)")
    if fig6:
        ax = axes.pop(0)
        draw(ax, fig6, "sites")
        ax.set_xscale("log")
        ax.set_xlabel("sites (uniform random points on the sphere)")
        cells = next(iter(fig6.values()))[0]["cells"]
        ax.set_title(f"Time against sites at level {level6}, {cells:,} cells (cf. Figure 6)")
    fig.tight_layout()
    fig.savefig(out + ".png", dpi=120)
    print(f"plot_figures: wrote {out}.png", file=sys.stderr)


def ms(v):
    return f"{v:.0f}" if v >= 100 else f"{v:.1f}" if v >= 10 else f"{v:.2f}" if v >= 1 else f"{v:.3f}"


def table3(rows):
    """The paper's Table 3 as Markdown; a column only where the data has it."""
    rows = [r for r in rows if r["sites_spec"].endswith(COUNTRIES) and 5 <= r["level"] <= 9 and r["rule"] == "exact"]
    pick = lambda keep: {r["level"]: r for r in rows if keep(r)}
    cpu1 = lambda a: pick(lambda r: r["device"].startswith("cpu") and r["threads"] == 1 and r["algorithm"] == a)
    brute = cpu1("brute")
    columns = [("CPU 1 thread brute (ms)", brute, False), ("CPU 1 thread hier (ms, + prepare)", cpu1("hier"), True)]
    speedups = []
    for gpu in sorted({r["device"] for r in rows if r["device"].startswith("cuda")}):
        name = device_name({"device": gpu})
        for algo in ("brute", "hier"):
            columns.append((f"{name} {algo} (ms, + prepare)",
                            pick(lambda r: r["device"] == gpu and r["algorithm"] == algo), True))
        if brute and columns[-1][1]:  # the paper's speed-up: the GPU against one CPU thread's brute force
            speedups.append((name, columns[-1][1]))
    columns = [c for c in columns if c[1]]
    if not columns:
        return None
    cells = {L: r["cells"] for _, by_level, _ in columns for L, r in by_level.items()}
    header = ["level", "cells"]
    body = {L: [str(L), f"{cells[L]:,}".replace(",", " ")] for L in sorted(cells)}
    for title, by_level, with_prepare in columns:
        header.append(title)
        for L, line in body.items():
            r = by_level.get(L)
            line.append("—" if r is None else ms(r["label_ms"]) + (f" + {ms(r['prepare_ms'])}" if with_prepare else ""))
    for name, hier in speedups:
        header.append(f"{name} hier vs CPU brute (x; with prepare)")
        for L, line in body.items():
            b, h = brute.get(L), hier.get(L)
            line.append("—" if not (b and h) else f"{b['label_ms'] / h['label_ms']:,.0f}; "
                        f"{b['label_ms'] / (h['label_ms'] + h['prepare_ms']):,.0f}".replace(",", " "))
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    return "\n".join(lines + ["| " + " | ".join(line) + " |" for line in body.values()])


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("csv", nargs="+", help="qtmv_bench --csv output files (- for stdin)")
    parser.add_argument("--out", default="qtmv_figures", metavar="PREFIX", help="writes PREFIX.png (default %(default)s)")
    parser.add_argument("--level", type=int, metavar="L",
                        help="Figure 6's level (default: the level with the most uniform:N site counts)")
    parser.add_argument("--no-plot", action="store_true", help="print the table only (no matplotlib needed)")
    args = parser.parse_args()

    rows = merge(read_rows(args.csv))
    if not rows:
        sys.exit(f"plot_figures: no qtmv_bench rows in {', '.join(args.csv)}")
    level6 = args.level
    if level6 is None:
        counts = defaultdict(set)
        for r in rows:
            if r["sites_spec"].startswith("uniform:"):
                counts[r["level"]].add(r["sites"])
        level6 = max(counts, key=lambda L: (len(counts[L]), L)) if counts else -1
    if not args.no_plot:
        plot(rows, level6, args.out)
    table = table3(rows)
    print(table if table else f"(no {COUNTRIES} rows at levels 5 to 9 for Table 3)")


if __name__ == "__main__":
    main()
