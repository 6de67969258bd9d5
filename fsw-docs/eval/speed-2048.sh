#!/usr/bin/env bash
# Time per relocalization on 2048×1366 rectified pairs, two `vtsm` binaries
# on the same inputs in one run (fsw-docs/eval/speed-2048.md).
#
# The pairs: the paper camera (5472×3648) of `vtsm scene export --profile
# paper`, box-filtered down to 2048×1366 with the intrinsics scaled per axis
# (python3 with Pillow), one stop per terrain and lighting change (map at
# 9.5 h, pair at 9.5 / 12.5 / 15.5 h). Each binary builds its own map product
# with `vtsm map build` (defaults) and relocalizes every pair with `--map`;
# NEW runs once with `--threads 1` and once with `--threads 2`. Every run is
# repeated REPS times, interleaved; the table takes each one's fastest.
# Usage: bash fsw-docs/eval/speed-2048.sh OLD_VTSM NEW_VTSM [OUT] [REPS]
set -euo pipefail
OLD=$1
NEW=$2
OUT=${3:-/tmp/speed-2048}
REPS=${4:-2}
mkdir -p "$OUT/res"
cd "$OUT"
cat > scale.py <<'EOF'
import json, shutil, sys
from PIL import Image
src, dst = sys.argv[1], sys.argv[2]
c = json.load(open(f"{src}/calib.json"))
W, H = 2048, 1366
sx, sy = W / c["width"], H / c["height"]
for s in ("left", "right"):
    Image.open(f"{src}/{s}.png").resize((W, H), Image.Resampling.BOX).save(f"{dst}/{s}.png")
# Pixel centres: x' + 0.5 = (x + 0.5) sx.
json.dump(dict(c, width=W, height=H, fx=c["fx"] * sx, fy=c["fy"] * sy,
               cx=(c["cx"] + 0.5) * sx - 0.5, cy=(c["cy"] + 0.5) * sy - 0.5),
          open(f"{dst}/calib.json", "w"))
for f in ("prior.json", "truth.json", "scene.json"):
    shutil.copy(f"{src}/{f}", f"{dst}/{f}")
EOF
TERRAINS=(flagstone cfa6 cfa2)
HOURS=(9.5 12.5 15.5)
stop_of() { case $1 in 9.5) echo 3 ;; 12.5) echo 8 ;; *) echo 12 ;; esac; }
for t in "${TERRAINS[@]}"; do
  for h in "${HOURS[@]}"; do
    d=in-$t-$h
    [ -e "$d/calib.json" ] && continue
    "$NEW" scene export --terrain "$t" --hours "$h" --profile paper --stop "$(stop_of "$h")" \
      --seed 1 --out "src-$t-$h" --force > /dev/null
    mkdir -p "$d"
    python3 scale.py "src-$t-$h" "$d"
    if [ ! -d "map-$t" ]; then
      mkdir "map-$t"
      mv "src-$t-$h"/map.obj "src-$t-$h"/mask.obj "src-$t-$h"/map.mtl "src-$t-$h"/map_texture.png "map-$t/"
    fi
    rm -rf "src-$t-$h"
  done
done
: > time.log
for t in "${TERRAINS[@]}"; do
  for b in old new; do
    bin=$OLD; [ $b = new ] && bin=$NEW
    /usr/bin/time -f "mapbuild $b $t %e s %M KB" -a -o time.log "$bin" map build \
      --mesh "map-$t/map.obj" --mask "map-$t/mask.obj" --out "map-$t/$b.vmap" --force > /dev/null
  done
done
for rep in $(seq "$REPS"); do
  for t in "${TERRAINS[@]}"; do
    for h in "${HOURS[@]}"; do
      d=in-$t-$h
      for b in old new1 new2; do
        case $b in
          old) cmd=("$OLD" relocalize); mp=map-$t/old.vmap ;;
          new1) cmd=("$NEW" relocalize --threads 1); mp=map-$t/new.vmap ;;
          new2) cmd=("$NEW" relocalize --threads 2); mp=map-$t/new.vmap ;;
        esac
        /usr/bin/time -f "reloc $b $t $h $rep %e s %M KB" -a -o time.log "${cmd[@]}" --map "$mp" \
          --calib "$d/calib.json" --left "$d/left.png" --right "$d/right.png" \
          --prior "$d/prior.json" --seed 1 --out "res/$b-$t-$h.json" --force > /dev/null
      done
    done
  done
done
python3 - <<'EOF'
import collections, json, math, re
best = collections.defaultdict(lambda: math.inf)
for line in open("time.log"):
    m = re.match(r"reloc (\S+) (\S+) (\S+) \d+ ([\d.]+) s", line)
    if m:
        k = (m[1], m[2], m[3])
        best[k] = min(best[k], float(m[4]))
def outcome(b, t, h):
    r = json.load(open(f"res/{b}-{t}-{h}.json"))
    truth = json.load(open(f"in-{t}-{h}/truth.json"))["world_from_left"]["t"]
    w = r.get("world_from_left")
    err = f"{math.dist(w['t'], truth) * 1000:.1f}" if w else (r.get("failure") or "?")
    return err, r["stats"]["attempts"]
print("| terrain | Δ | old (s) | new, 1 thread (s) | ratio | new, 2 threads (s) | ratio "
      "| attempts old / new | error old / new (mm) |")
print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
tot = collections.Counter()
for t in ("flagstone", "cfa6", "cfa2"):
    for h, dh in (("9.5", 0), ("12.5", 3), ("15.5", 6)):
        o, n1, n2 = (best[(b, t, h)] for b in ("old", "new1", "new2"))
        tot["o"] += o; tot["n1"] += n1; tot["n2"] += n2
        eo, ao = outcome("old", t, h)
        en, an = outcome("new1", t, h)
        print(f"| {t} | {dh} h | {o:.2f} | {n1:.2f} | {n1 / o:.2f} | {n2:.2f} | {n2 / o:.2f} "
              f"| {ao} / {an} | {eo} / {en} |")
print(f"| all | | {tot['o']:.1f} | {tot['n1']:.1f} | {tot['n1'] / tot['o']:.2f} "
      f"| {tot['n2']:.1f} | {tot['n2'] / tot['o']:.2f} | | |")
EOF
