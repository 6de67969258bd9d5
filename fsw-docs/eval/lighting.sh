#!/usr/bin/env bash
# The paper suite with parts of the sunlight taken out of the simulated depot
# (`vtsm eval --light-model`) or with every map triangle in the sampling mask
# (`--mask all`), side by side with the full model, per group.
# Runs `vtsm eval` into OUT/<variant> unless its summary.json is already there (then
# it is taken as it is) and prints the table (fsw-docs/eval/compare.py).
# Usage: bash fsw-docs/eval/lighting.sh [VTSM] [OUT] [PROFILE] [TRIALS] [TERRAINS] [HOURS]
set -euo pipefail
VTSM=${1:-target/release/vtsm}
OUT=${2:-/tmp/lighting}
PROFILE=${3:-demo}
TRIALS=${4:-10}
TERRAINS=${5:-cfa6}
HOURS=${6:-3,6}
VARIANTS=(full no-cast-shadows no-attached-shading flat mask-all)
for v in "${VARIANTS[@]}"; do
  case $v in
    mask-all) flag="--mask all" ;;
    *) flag="--light-model $v" ;;
  esac
  if [ ! -e "$OUT/$v/summary.json" ]; then
    "$VTSM" eval --suite paper --profile "$PROFILE" --trials "$TRIALS" --seed 1 \
      --terrains "$TERRAINS" --hours "$HOURS" $flag --quiet --out "$OUT/$v" > /dev/null
  fi
done
args=()
for v in "${VARIANTS[@]}"; do args+=("$v=$OUT/$v"); done
python3 "$(dirname "$0")/compare.py" "${args[@]}"
