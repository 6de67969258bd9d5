#!/usr/bin/env bash
# Physical (distorted, unrectified, OpenCV-calibrated) vs ideal rectified pairs of the
# same captures: `vtsm scene export [--physical]` then `vtsm relocalize`, errors of the
# reported world_from_left against truth.json (paper §V-A metric). Writes the table to
# stdout. Usage: bash fsw-docs/eval/physical.sh [VTSM] [WORKDIR] [PROFILE]
set -euo pipefail
VTSM=${1:-target/release/vtsm}
WORK=${2:-/tmp/vtsm-physical-eval}
PROFILE=${3:-demo}
TERRAIN=flagstone
SEED=1
mkdir -p "$WORK"
err() { # result.json truth.json -> "t_mm r_deg status inliers"
  python3 - "$1" "$2" <<'PY'
import json, math, sys
r = json.load(open(sys.argv[1])); t = json.load(open(sys.argv[2]))["world_from_left"]
def rot(q):
    w, x, y, z = q
    return [[1-2*(y*y+z*z), 2*(x*y-w*z), 2*(x*z+w*y)],
            [2*(x*y+w*z), 1-2*(x*x+z*z), 2*(y*z-w*x)],
            [2*(x*z-w*y), 2*(y*z+w*x), 1-2*(x*x+y*y)]]
e = r["world_from_left"]
if e is None:
    print("- - %s %d" % (r["status"], r["inliers"])); sys.exit()
rt, re = rot(t["q"]), rot(e["q"])
d = [e["t"][i] - t["t"][i] for i in range(3)]
# (T_true)^-1 T_est: translation R_true^T d, rotation R_true^T R_est
dt = math.sqrt(sum(sum(rt[k][i] * d[k] for k in range(3)) ** 2 for i in range(3)))
tr = sum(sum(rt[k][i] * re[k][i] for k in range(3)) for i in range(3))
ang = math.degrees(math.acos(max(-1.0, min(1.0, (tr - 1) / 2))))
print("%.1f %.3f %s %d" % (dt * 1e3, ang, r["status"], r["inliers"]))
PY
}
echo "| stop | look at | rectified: error mm | deg | inliers | physical: error mm | deg | inliers |"
echo "|---|---|---|---|---|---|---|---|"
for view in "0 0" "8 1" "15 1" "23 0"; do
  set -- $view
  row="| $1 | $2 |"
  for form in rectified physical; do
    d="$WORK/$PROFILE-$1-$2-$form"
    flag=""; [ "$form" = physical ] && flag="--physical"
    "$VTSM" scene export --terrain $TERRAIN --hours am --profile "$PROFILE" --stop "$1" \
      --look-at "$2" --seed $SEED --out "$d" --force $flag > /dev/null
    "$VTSM" relocalize --mesh "$d/map.obj" --mask "$d/mask.obj" --calib "$d/calib.json" \
      --left "$d/left.png" --right "$d/right.png" --prior "$d/prior.json" --seed $SEED \
      --out "$d/result.json" --force || true
    read -r t r s n < <(err "$d/result.json" "$d/truth.json")
    [ "$s" = ok ] || t="$t ($s)"
    row="$row $t | $r | $n |"
  done
  echo "$row"
done
