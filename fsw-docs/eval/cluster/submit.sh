#!/usr/bin/env bash
# Submit a sharded vtsm eval campaign to Slurm: an array of VTSM_SHARDS tasks
# (vtsm-eval.sbatch) and the merge (merge.sbatch) after all of them succeeded.
# Prints `array <job id>` and `merge <job id>`.
#
#   VTSM=target/release/vtsm VTSM_PARTS=/shared/run1 VTSM_SHARDS=8 VTSM_TRIALS=112 \
#     fsw-docs/eval/cluster/submit.sh [sbatch options for both jobs, e.g. --partition=cpu]
#
# Environment: as vtsm-eval.sbatch and merge.sbatch; VTSM_SHARDS defaults to 8;
# VTSM_ARRAY_LIMIT caps the array tasks running at once (sbatch --array=...%L).
# Submitting again with the same settings resumes: complete parts are kept,
# killed ones run only their missing trials (the merge directory must not
# hold a result yet).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
die() { echo "submit.sh: $*" >&2; exit 2; }

: "${VTSM:?set VTSM to the vtsm binary}"
: "${VTSM_PARTS:?set VTSM_PARTS to a parts directory every node sees}"
VTSM=$(readlink -f "$VTSM")
[ -x "$VTSM" ] || die "VTSM=$VTSM is not an executable"
command -v sbatch >/dev/null || die "sbatch not found (Slurm client commands)"
export VTSM
VTSM_PARTS=$(readlink -m "$VTSM_PARTS")
export VTSM_PARTS
export VTSM_SHARDS=${VTSM_SHARDS:-8}
[[ "$VTSM_SHARDS" =~ ^[1-9][0-9]*$ ]] || die "VTSM_SHARDS=$VTSM_SHARDS is not a positive count"
export VTSM_OUT=${VTSM_OUT:-$VTSM_PARTS/merged}
VTSM_OUT=$(readlink -m "$VTSM_OUT")
if [ -n "$(ls -A "$VTSM_OUT" 2>/dev/null)" ]; then
    die "$VTSM_OUT already holds a merged result; choose another VTSM_OUT"
fi
mkdir -p "$VTSM_PARTS/log"

array=$(sbatch --parsable --array="0-$((VTSM_SHARDS - 1))${VTSM_ARRAY_LIMIT:+%$VTSM_ARRAY_LIMIT}" \
    --output="$VTSM_PARTS/log/eval-%A_%a.out" "$@" "$here/vtsm-eval.sbatch")
array=${array%%;*}
# A failed array task cancels the merge instead of leaving it pending forever.
merge=$(sbatch --parsable --dependency="afterok:$array" --kill-on-invalid-dep=yes \
    --output="$VTSM_PARTS/log/merge-%j.out" "$@" "$here/merge.sbatch")
merge=${merge%%;*}
echo "array $array"
echo "merge $merge"
