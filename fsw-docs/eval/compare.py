#!/usr/bin/env python3
"""Per-group side-by-side table of `vtsm eval` runs of the same trials.

Usage: python3 fsw-docs/eval/compare.py LABEL=DIR[+DIR ...] [LABEL=DIR[+DIR ...] ...]

Each DIR is a `vtsm eval` output directory (its trials.csv); DIR+DIR pools
several runs under one label (e.g. two seeds; trials pair by position in the
list and trial index). Groups are those of
the first run; a group missing from a run is left out for it. The paired
difference is against the first run, over the trials both solved (same group
and trial index: same capture, prior and seed), with how many of them the run
solved with the lower translation error and the two-sided p of the exact sign
test on those differences (ties left out): a small p says the two runs differ
in that group beyond what the trials' scatter explains. A last group "all"
pools every group. Quantiles as vtsm_sim::eval::quantile (linear); "inside
95 %" counts d² ≤ χ²₃(0.95).
"""
import csv
import math
import sys

CHI2_3_95 = 7.814727903251178


def quantile(v, q):
    if not v:
        return float("nan")
    v = sorted(v)
    pos = q * (len(v) - 1)
    lo = int(pos)
    hi = min(lo + 1, len(v) - 1)
    return v[lo] + (v[hi] - v[lo]) * (pos - lo)


def sign_test(diffs):
    """Two-sided p of the exact sign test (ties dropped), 1.0 without data."""
    lo, hi = sum(x < 0 for x in diffs), sum(x > 0 for x in diffs)
    n = lo + hi
    if n == 0:
        return 1.0
    tail = sum(math.comb(n, k) for k in range(min(lo, hi) + 1)) / 2.0 ** n
    return min(1.0, 2.0 * tail)


def inside(rows, key):
    d2 = [float(r[key]) for r in rows if r.get(key) not in (None, "", "nan", "NaN")]
    return "%d %%" % round(100 * sum(x <= CHI2_3_95 for x in d2) / len(d2)) if d2 else "—"


runs = []
for arg in sys.argv[1:]:
    label, _, paths = arg.partition("=")
    rows = []
    for k, path in enumerate(paths.split("+")):
        for r in csv.DictReader(open(path.rstrip("/") + "/trials.csv")):
            if r["method"] == "vtsm":
                r["trial"] = "%d-%s" % (k, r["trial"])
                rows.append(r)
    runs.append((label, rows))
if not runs:
    sys.exit(__doc__)
first = runs[0][1]
print("| group | run | success | t median (mm) | t p95 | t max | r median (°) | r max | inside 95 %: t | inside 95 %: r | attempts (mean) | paired Δt median (mm) | lower | sign test p |")
print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
groups = list(dict.fromkeys(r["group"] for r in first))
for g in groups + ["all"]:
    pick = (lambda r: True) if g == "all" else (lambda r, g=g: r["group"] == g)
    ref = {(r["group"], r["trial"]): r for r in first if pick(r)}
    for i, (label, rows) in enumerate(runs):
        rows = [r for r in rows if pick(r) and r["group"] in groups]
        if not rows:
            continue
        ok = [r for r in rows if r["success"] == "true"]
        t = [float(r["final_t_mm"]) for r in ok]
        d = [float(r["final_r_deg"]) for r in ok]
        both = [(r, ref[(r["group"], r["trial"])]) for r in ok
                if (r["group"], r["trial"]) in ref and ref[(r["group"], r["trial"])]["success"] == "true"]
        paired = [float(r["final_t_mm"]) - float(q["final_t_mm"]) for r, q in both]
        tail = ("— | — | —" if i == 0 or not paired else "%+.1f | %d/%d | %.2f" % (
            quantile(paired, 0.5), sum(x < 0 for x in paired), len(paired), sign_test(paired)))
        print("| %s | %s | %d/%d | %.1f | %.1f | %.1f | %.3f | %.3f | %s | %s | %.0f | %s |" % (
            g, label, len(ok), len(rows), quantile(t, 0.5), quantile(t, 0.95), quantile(t, 1.0),
            quantile(d, 0.5), quantile(d, 1.0), inside(ok, "cov_d2_t"), inside(ok, "cov_d2_r"),
            sum(float(r["attempts"]) for r in rows) / len(rows), tail))
