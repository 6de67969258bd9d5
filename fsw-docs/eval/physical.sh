#!/usr/bin/env bash
# The paper suite on ideal rectified pairs and on physical pairs (distorted, rotated,
# OpenCV-calibrated, rectified on the host: `vtsm eval --physical`), same trials, side by
# side per group. Runs `vtsm eval` into OUT/rect and OUT/phys unless their summary.json
# is already there (then it must be of the same profile and trials), and prints the table.
# The physical run is OUT/phys-INTERP (INTERP: the rectification kernel, `--interp`).
# Usage: bash fsw-docs/eval/physical.sh [VTSM] [OUT] [PROFILE] [TRIALS] [INTERP]
set -euo pipefail
VTSM=${1:-target/release/vtsm}
OUT=${2:-/tmp/phys}
PROFILE=${3:-demo}
TRIALS=${4:-6}
INTERP=${5:-lanczos4}
for form in rect "phys-$INTERP"; do
  flag=""; [ "$form" != rect ] && flag="--physical --interp $INTERP"
  if [ ! -e "$OUT/$form/summary.json" ]; then
    "$VTSM" eval --suite paper --profile "$PROFILE" --trials "$TRIALS" --quiet $flag \
      --out "$OUT/$form" > /dev/null
  fi
done
python3 - "$OUT/rect/summary.json" "$OUT/phys-$INTERP/summary.json" "$PROFILE" "$TRIALS" "$INTERP" <<'PY'
import json, sys
rect, phys = (json.load(open(p)) for p in sys.argv[1:3])
profile, trials, interp = sys.argv[3], int(sys.argv[4]), sys.argv[5]
if phys["meta"]["params"].get("rectify_interp", "linear") != interp:
    sys.exit("%s: rectified by %s, not %s" % (sys.argv[2], phys["meta"]["params"].get("rectify_interp"), interp))
for run, physical in ((rect, False), (phys, True)):
    m = run["meta"]
    if (m["suite"], m["profile"], m["trials"], m.get("physical")) != ("paper", profile, trials, physical):
        sys.exit("%s: suite %s, profile %s, %s trials, physical %s: not this comparison"
                 % (m["command"], m["suite"], m["profile"], m["trials"], m.get("physical")))
def quantile(v, q):  # as vtsm_sim::eval::quantile (linear)
    if not v:
        return float("nan")
    v = sorted(v); pos = q * (len(v) - 1); lo = int(pos); hi = min(lo + 1, len(v) - 1)
    return v[lo] + (v[hi] - v[lo]) * (pos - lo)
def cols(rows):
    ok = [r for r in rows if r["success"]]
    t = [r["final_t_mm"] for r in ok]; d = [r["final_r_deg"] for r in ok]
    return ["%d/%d" % (len(ok), len(rows))] + ["%.1f" % quantile(t, q) for q in (0.5, 0.95, 1.0)] \
        + ["%.3f" % quantile(d, 0.5)]
def paired(a, b):
    # Trials both forms solved: median of (physical - rectified) error, and how often physical is lower.
    both = [(x["final_t_mm"], y["final_t_mm"]) for x, y in zip(a, b) if x["success"] and y["success"]]
    if not both:
        return ["—", "—"]
    return ["%+.1f" % quantile([y - x for x, y in both], 0.5),
            "%d/%d" % (sum(y < x for x, y in both), len(both))]
groups = [g["group"] for g in rect["groups"]]
print("| group | success rect. | phys. | t median (mm) rect. | phys. | t p95 rect. | phys. "
      "| t max rect. | phys. | r median (°) rect. | phys. | paired Δt median (mm) | phys. lower |")
print("|---|" + "---:|" * 12)
key = lambda r: (r["group"], r["trial"])
for g in groups + ["all"]:
    a = sorted((r for r in rect["trials"] if g in ("all", r["group"])), key=key)
    b = sorted((r for r in phys["trials"] if g in ("all", r["group"])), key=key)
    assert [key(r) for r in a] == [key(r) for r in b] and all(
        (x["seed"], x["init_t_mm"]) == (y["seed"], y["init_t_mm"]) for x, y in zip(a, b)), g
    ca, cb = cols(a), cols(b)
    row = [v for pair in zip(ca, cb) for v in pair] + paired(a, b)
    print("| %s | %s |" % ("**all**" if g == "all" else g, " | ".join(row)))
PY
