#!/usr/bin/env bash
# A batch of 20 pairs against one map load: exports stops 0..19 of one simulated
# depot (flagstone, seed 1, 12.5 h, demo profile; the same map in each export),
# builds the map product once, writes pairs.jsonl and runs `vtsm relocalize --pairs`
# under /usr/bin/time -v (peak memory), then prints the batch summary line and the
# per-pair error and time spread from results.jsonl.
# Usage: bash fsw-docs/eval/batch20.sh [VTSM] [OUT]
set -euo pipefail
VTSM=${1:-target/release/vtsm}
OUT=${2:-/tmp/b20}
mkdir -p "$OUT"
for s in $(seq 0 19); do
  [ -e "$OUT/s$s/left.png" ] || "$VTSM" scene export --terrain flagstone --hours 12.5 --profile demo \
    --stop "$s" --out "$OUT/s$s" > /dev/null
  cmp -s "$OUT/s0/map.obj" "$OUT/s$s/map.obj" || { echo "stop $s: another map" >&2; exit 1; }
done
"$VTSM" map build --mesh "$OUT/s0/map.obj" --mask "$OUT/s0/mask.obj" --out "$OUT/map.vmap" --force > /dev/null
for s in $(seq 0 19); do
  echo "{\"left\": \"s$s/left.png\", \"right\": \"s$s/right.png\", \"prior\": \"s$s/prior.json\", \"truth\": \"s$s/truth.json\"}"
done > "$OUT/pairs.jsonl"
echo "load average at start: $(cut -d' ' -f1-3 /proc/loadavg)"
rc=0
/usr/bin/time -v "$VTSM" relocalize --map "$OUT/map.vmap" --calib "$OUT/s0/calib.json" \
  --pairs "$OUT/pairs.jsonl" --out "$OUT/results.jsonl" --force 2> "$OUT/time.txt" || rc=$?
echo "load average at end: $(cut -d' ' -f1-3 /proc/loadavg)"
grep -E "^vtsm: batch|Maximum resident|Elapsed|User time" "$OUT/time.txt"
python3 - "$OUT/results.jsonl" <<'PY'
import json, sys
r = [json.loads(l) for l in open(sys.argv[1])]
e = sorted(x["error_t_mm"] for x in r if x["status"] == "ok")
t = sorted(x["time_s"] for x in r)
print("%d pairs, %d ok; error median %.1f mm, max %.1f mm; time per pair min %.2f, median %.2f, max %.2f s"
      % (len(r), len(e), e[len(e) // 2], e[-1], t[0], t[len(t) // 2], t[-1]))
PY
exit $rc
