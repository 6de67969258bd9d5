#!/usr/bin/env python3
"""The `uncertainty50` table of `fsw-docs/eval/uncertainty50.md` from one run.

Usage: python3 fsw-docs/eval/u50table.py DIR

DIR is a `vtsm eval --suite uncertainty50` output directory (its trials.csv).
Per group: successes, mean initial error, median and largest final error of
the successful trials, mean attempts, mean rounds focused (VTSM-RELOC-040;
"—" for a run without that column), mean time, and the group's mean time over
its terrain's `ref 10-20cm` mean time from the same run.
"""
import csv
import statistics
import sys


def main(path):
    groups = {}
    with open(path + "/trials.csv", newline="") as f:
        for r in csv.DictReader(f):
            groups.setdefault(r["group"], []).append(r)
    ref = {
        g.split()[0]: statistics.mean(float(r["time_s"]) for r in rows)
        for g, rows in groups.items()
        if "ref" in g
    }
    print(
        "| group | success | initial error (mm, mean) | final error (mm, median) "
        "| final error (mm, max) | attempts (mean) | focused rounds (mean) "
        "| time (s, mean) | time / reference |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for g, rows in groups.items():
        ok = [r for r in rows if r["success"] == "true"]
        fin = [float(r["final_t_mm"]) for r in ok]
        mean = lambda k: statistics.mean(float(r[k]) for r in rows)
        t = mean("time_s")
        focused = "%.1f" % mean("focused_rounds") if "focused_rounds" in rows[0] else "—"
        print(
            "| %s | %d/%d | %.0f | %s | %s | %.0f | %s | %.2f | %.2f |"
            % (
                g,
                len(ok),
                len(rows),
                mean("init_t_mm"),
                "%.1f" % statistics.median(fin) if fin else "—",
                "%.1f" % max(fin) if fin else "—",
                mean("attempts"),
                focused,
                t,
                t / ref[g.split()[0]],
            )
        )


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    main(sys.argv[1])
