#!/usr/bin/env python3
"""Per-group side-by-side table of `vtsm eval` runs of the same trials.

Usage: python3 fsw-docs/eval/compare.py LABEL=DIR [LABEL=DIR ...]

Each DIR is a `vtsm eval` output directory (its trials.csv). Groups are those of
the first run; a group missing from a run is left out for it. The paired
difference is against the first run, over the trials both solved (same group
and trial index: same capture, prior and seed). Quantiles as
vtsm_sim::eval::quantile (linear); "inside 95 %" counts d² ≤ χ²₃(0.95).
"""
import csv
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


def inside(rows, key):
    d2 = [float(r[key]) for r in rows if r.get(key) not in (None, "", "nan", "NaN")]
    return "%d %%" % round(100 * sum(x <= CHI2_3_95 for x in d2) / len(d2)) if d2 else "—"


runs = []
for arg in sys.argv[1:]:
    label, _, path = arg.partition("=")
    rows = [r for r in csv.DictReader(open(path.rstrip("/") + "/trials.csv")) if r["method"] == "vtsm"]
    runs.append((label, rows))
if not runs:
    sys.exit(__doc__)
first = runs[0][1]
print("| group | run | success | t median (mm) | t p95 | t max | r median (°) | r max | inside 95 %: t | inside 95 %: r | attempts (mean) | paired Δt median (mm) |")
print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
for g in dict.fromkeys(r["group"] for r in first):
    ref = {r["trial"]: r for r in first if r["group"] == g}
    for i, (label, rows) in enumerate(runs):
        rows = [r for r in rows if r["group"] == g]
        if not rows:
            continue
        ok = [r for r in rows if r["success"] == "true"]
        t = [float(r["final_t_mm"]) for r in ok]
        d = [float(r["final_r_deg"]) for r in ok]
        paired = [float(r["final_t_mm"]) - float(ref[r["trial"]]["final_t_mm"])
                  for r in ok if r["trial"] in ref and ref[r["trial"]]["success"] == "true"]
        print("| %s | %s | %d/%d | %.1f | %.1f | %.1f | %.3f | %.3f | %s | %s | %.0f | %s |" % (
            g, label, len(ok), len(rows), quantile(t, 0.5), quantile(t, 0.95), quantile(t, 1.0),
            quantile(d, 0.5), quantile(d, 1.0), inside(ok, "cov_d2_t"), inside(ok, "cov_d2_r"),
            sum(float(r["attempts"]) for r in rows) / len(rows),
            "—" if i == 0 else ("%+.1f" % quantile(paired, 0.5) if paired else "—")))
