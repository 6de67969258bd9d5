#!/usr/bin/env bash
# Priors 0.6 and 0.8 m off in six directions (±x, ±y, ±z of the world frame,
# z up) that state 1.0 m / 1.5°, on one exported demo-profile scene (flagstone,
# stop 3, seed 1), relocalized by each binary given; one line per run.
#   bash fsw-docs/eval/far-priors.sh DIR BIN [BIN ...]
# DIR is created (scene, priors, results). Two runs at a time (xargs -P2).
set -eu
dir="${1:?output directory}"; shift
[ "$#" -ge 1 ] || { echo "give at least one vtsm binary" >&2; exit 2; }
mkdir -p "$dir"
"$1" scene export --terrain flagstone --hours 9.5 --stop 3 --profile demo --out "$dir/scene" --force >/dev/null
python3 - "$dir" <<'PY'
import json, sys
d = sys.argv[1]
t = json.load(open(f"{d}/scene/truth.json"))["world_from_left"]
q = json.load(open(f"{d}/scene/prior.json"))["world_from_left"]["q"]
axes = {"+x": (1, 0, 0), "-x": (-1, 0, 0), "+y": (0, 1, 0), "-y": (0, -1, 0), "+z": (0, 0, 1), "-z": (0, 0, -1)}
for name, v in axes.items():
    for m in (0.6, 0.8):
        p = {"world_from_left": {"t": [t["t"][i] + m * v[i] for i in range(3)], "q": q},
             "uncertainty": {"t_m": 1.0, "r_deg": 1.5}}
        json.dump(p, open(f"{d}/prior{name}{m}.json", "w"))
PY
run() {
    local bin="$1" tag="$2" prior="$3" s e
    s=$(date +%s.%N)
    "$bin" relocalize --mesh "$dir/scene/map.obj" --mask "$dir/scene/mask.obj" --calib "$dir/scene/calib.json" \
        --left "$dir/scene/left.png" --right "$dir/scene/right.png" --prior "$dir/$prior" \
        --out "$dir/result-$tag-$prior" --force >/dev/null 2>&1 || true
    e=$(date +%s.%N)
    python3 - "$dir" "$tag" "$prior" "$s" "$e" <<'PY'
import json, math, sys
d, tag, prior, s, e = sys.argv[1:]
r = json.load(open(f"{d}/result-{tag}-{prior}"))
t = json.load(open(f"{d}/scene/truth.json"))["world_from_left"]["t"]
err = 1000 * math.dist(t, r["world_from_left"]["t"]) if r.get("world_from_left") else float("nan")
st = r["stats"]
print(f"{tag} {prior[5:-5]:6s} {r['status']:6s} {str(r.get('failure')):26s} error {err:7.1f} mm "
      f"attempts {st['attempts']:6d} rounds {st['rounds']:3d} focused {st.get('focused_rounds', '-')} "
      f"wall {float(e) - float(s):5.1f} s")
PY
}
export -f run
export dir
k=0
for bin in "$@"; do
    for p in "$dir"/prior*.json; do echo "$bin bin$k $(basename "$p")"; done
    k=$((k + 1))
done | xargs -P2 -L1 bash -c 'run "$0" "$1" "$2"'
