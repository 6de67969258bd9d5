#!/usr/bin/env bash
# A single-node Slurm cluster on this machine, started for the run and
# stopped after it: the recipe fsw-docs/eval/cluster (vtsm-eval.sbatch as a
# 3-task array, merge.sbatch after it, both submitted by submit.sh) runs a
# test-profile campaign, and the merged trials.csv must equal a
# single-process run's in every column but time_s. Then part 1 is made a
# killed task's (part.json and half of its journal removed) and the same
# submission must keep the other parts, resume part 1 and merge the same
# trials again; and task 1 submitted alone without VTSM_SHARDS must be
# refused. A failure prints the daemons' logs and the jobs' outputs.
#
# Installs Debian's munge, slurmctld, slurmd and slurm-client when missing.
# Everything else lives in a temporary directory: slurm.conf, the munge key
# and socket, state, spool, logs, parts. The daemons (munged, slurmctld,
# slurmd) are started here, on their own ports and socket, so a Slurm or
# munge already running on the machine is not touched, and are stopped by
# PID on exit, success or not; the directory is then removed.
#
# Environment: VTSM (default target/debug/vtsm, built with the test profile
# as the flight-path step builds it), VTSM_SLURM_TIMEOUT (seconds for the
# jobs, default 600), VTSM_SLURM_KEEP=1 keeps the temporary directory.
# The campaign (default: paper suite, test profile, flagstone and cfa6 at
# Δ0 h and Δ3 h, 3 trials per group = 12 trials, 3 shards, seed 5) can be
# changed for a larger measurement: VTSM_SLURM_TRIALS, VTSM_SLURM_SHARDS,
# VTSM_SLURM_SEED, VTSM_SLURM_EXTRA (further `vtsm eval` arguments).
set -u
cd "$(dirname "$0")/.." || exit 1
root=$PWD
timeout_s=${VTSM_SLURM_TIMEOUT:-600}
trials=${VTSM_SLURM_TRIALS:-3}
extra=${VTSM_SLURM_EXTRA---terrains flagstone,cfa6 --hours 0,3}
shards=${VTSM_SLURM_SHARDS:-3}
seed=${VTSM_SLURM_SEED:-5}

tmp=
pids=()
policy_added=

say() { echo "slurm: $*"; }

dump() {
    # The logs and job outputs, for a failure.
    local f
    [ -n "$tmp" ] || return 0
    for f in "$tmp"/log/*.log "$tmp"/parts/log/*; do
        [ -f "$f" ] || continue
        case "$f" in
            */time-*.txt) echo "----- ${f#"$tmp"/}: $(grep -E 'Maximum resident|Elapsed|Exit status' "$f" | xargs)" ;;
            *) echo "----- ${f#"$tmp"/} (last 40 lines)"; tail -n 40 "$f" ;;
        esac
    done
    command -v squeue >/dev/null && [ -f "$tmp/slurm.conf" ] && squeue -a 2>&1 | head -n 20
}

fail() {
    echo "!!! slurm: $*"
    dump
    exit 1
}

stop_daemons() {
    # Jobs first (so no slurmstepd outlives slurmd), then each daemon by PID.
    if [ -f "$tmp/slurm.conf" ] && [ -f "$tmp/run/slurmctld.pid" ] && command -v scancel >/dev/null; then
        scancel --user="$(id -un)" >/dev/null 2>&1 || true
        local i
        for ((i = 0; i < 30; i++)); do
            [ -z "$(squeue -h 2>/dev/null)" ] && break
            sleep 1
        done
    fi
    local pid f i
    for f in slurmd slurmctld munged; do
        [ -f "$tmp/run/$f.pid" ] && pids+=("$(cat "$tmp/run/$f.pid")")
    done
    for pid in "${pids[@]}"; do
        [ -n "$pid" ] && kill -TERM "$pid" 2>/dev/null
    done
    for pid in "${pids[@]}"; do
        for ((i = 0; i < 20; i++)); do
            kill -0 "$pid" 2>/dev/null || break
            sleep 0.5
        done
        if kill -0 "$pid" 2>/dev/null; then
            echo "slurm: PID $pid did not stop on TERM; KILL"
            kill -KILL "$pid" 2>/dev/null
        fi
    done
}

cleanup() {
    local rc=$?
    [ -n "$policy_added" ] && rm -f /usr/sbin/policy-rc.d
    if [ -n "$tmp" ]; then
        stop_daemons
        if [ "${VTSM_SLURM_KEEP:-}" = 1 ]; then
            say "kept $tmp"
        else
            rm -rf "$tmp"
        fi
    fi
    exit "$rc"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

install() {
    # Debian packages, each when missing; no daemon is started by the
    # installation (policy-rc.d refuses it while installing, if there is none).
    local pkg missing=()
    for pkg in munge slurm-client slurmctld slurmd; do
        dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q 'install ok installed' || missing+=("$pkg")
    done
    [ ${#missing[@]} -eq 0 ] && return 0
    command -v apt-get >/dev/null || fail "missing ${missing[*]} and no apt-get"
    [ "$(id -u)" = 0 ] || fail "missing ${missing[*]}; installing needs root"
    say "installing ${missing[*]}"
    if [ ! -e /usr/sbin/policy-rc.d ]; then
        printf '#!/bin/sh\nexit 101\n' > /usr/sbin/policy-rc.d && chmod 755 /usr/sbin/policy-rc.d \
            && policy_added=1
    fi
    apt-get update -qq >/dev/null 2>&1 || fail "apt-get update failed"
    for pkg in "${missing[@]}"; do
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "$pkg" >/dev/null 2>&1 \
            || fail "cannot install $pkg"
    done
    if [ -n "$policy_added" ]; then rm -f /usr/sbin/policy-rc.d; policy_added=; fi
}

# A free TCP port from $1 on (the default 6817/6818 may belong to a Slurm of the machine).
free_port() {
    local p=$1
    while (echo >"/dev/tcp/127.0.0.1/$p") 2>/dev/null; do p=$((p + 1)); done
    echo "$p"
}

write_conf() {
    local host node ctld_port slurmd_port
    host=$(hostname -s)
    node=$(slurmd -C 2>/dev/null | grep '^NodeName=') || fail "slurmd -C printed no node line"
    ctld_port=$(free_port 16817)
    slurmd_port=$(free_port $((ctld_port + 1)))
    cat > "$tmp/slurm.conf" <<CONF
ClusterName=vtsmci
SlurmctldHost=$host
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=$(id -un)
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$tmp/run/munge.socket
StateSaveLocation=$tmp/state
SlurmdSpoolDir=$tmp/spool
SlurmctldPidFile=$tmp/run/slurmctld.pid
SlurmdPidFile=$tmp/run/slurmd.pid
SlurmctldLogFile=$tmp/log/slurmctld.log
SlurmdLogFile=$tmp/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SwitchType=switch/none
MpiDefault=none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
MaxArraySize=100001
SchedulerParameters=batch_sched_delay=0,sched_min_interval=0
ReturnToService=2
MinJobAge=3600
KillWait=5
$node State=UNKNOWN
PartitionName=ci Nodes=ALL Default=YES MaxTime=INFINITE State=UP
CONF
}

start_daemons() {
    # munged on a private key and socket, then slurmctld and slurmd (both
    # daemonize and write their PID files).
    local munged
    munged=$(command -v munged || echo /usr/sbin/munged)
    ( umask 077; dd if=/dev/urandom of="$tmp/run/munge.key" bs=1024 count=1 status=none ) \
        || fail "cannot write a munge key"
    "$munged" --key-file="$tmp/run/munge.key" --socket="$tmp/run/munge.socket" \
        --pid-file="$tmp/run/munged.pid" --seed-file="$tmp/run/munge.seed" \
        --log-file="$tmp/log/munged.log" --force 2>>"$tmp/log/munged.log" \
        || fail "munged did not start"
    munge -S "$tmp/run/munge.socket" -n </dev/null | unmunge -S "$tmp/run/munge.socket" >/dev/null \
        || fail "munge credential round trip failed"
    slurmctld -f "$tmp/slurm.conf" || fail "slurmctld did not start"
    slurmd -f "$tmp/slurm.conf" || fail "slurmd did not start"
    local i state=
    for ((i = 0; i < 60; i++)); do
        state=$(sinfo -h -N -o '%t' 2>/dev/null | head -n 1)
        [ "$state" = idle ] && return 0
        sleep 1
    done
    fail "node not idle after 60 s (sinfo: '${state}')"
}

# trials.csv without its time_s column.
without_time() {
    awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) if ($i == "time_s") t = i }
        { s = ""; sep = ""; for (i = 1; i <= NF; i++) if (i != t) { s = s sep $i; sep = "," } print s }' "$1"
}

# Seconds since the epoch time $1, to 0.1 s.
elapsed() {
    awk -v a="$1" -v b="$(date +%s.%N)" 'BEGIN { printf "%.1f", b - a }'
}

# Per array task: start and end (from the job output, seconds after
# submission), run time, peak memory. Then the scheduling cost: the delay
# from submission to the first tasks' start, and from a task's end to the
# start of the task that takes its CPU (tasks in order of start, CPUs freed
# in order of end); and the array's wall time against the tasks' run time
# spread over the node's CPUs.
timeline() {
    local k f start end rss cpus
    cpus=$(sinfo -h -N -o '%c' | head -n 1)
    for ((k = 0; k < shards; k++)); do
        f=$(find "$tmp/parts/log" -name "eval-${array}_$k.out")
        [ -n "$f" ] || continue
        start=$(sed -n 's/^vtsm-eval: shard .* start //p' "$f")
        end=$(sed -n 's/^vtsm-eval: shard .* end //p' "$f")
        rss=$(sed -n 's/.*Maximum resident set size (kbytes): //p' "$tmp/parts/log/time-$k.txt" 2>/dev/null)
        echo "$k $start $end ${rss:-0}"
    done | awk -v s="$submitted" -v cpus="$cpus" '
        function sort(a, n,   i, j, t) { for (i = 2; i <= n; i++) for (j = i; j > 1 && a[j - 1] > a[j]; j--) { t = a[j]; a[j] = a[j - 1]; a[j - 1] = t } }
        { n++; st[n] = $2 - s; en[n] = $3 - s; run += en[n] - st[n]; if (en[n] > last) last = en[n]
          if ($4 > rss) rss = $4
          printf "slurm: task %s: start %.1f s, end %.1f s, %.1f s, max RSS %d KB\n", $1, st[n], en[n], en[n] - st[n], $4 }
        END {
            if (!n) exit
            sort(st, n); sort(en, n)
            for (i = 1; i <= n; i++) { g = (i <= cpus) ? st[i] : st[i] - en[i - cpus]; gap += g; if (g > gmax) gmax = g }
            printf "slurm: %d tasks on %d CPUs: delay to start %.2f s per task (mean; max %.2f s) after submission or a CPU freed; array wall %.1f s, run time %.1f s / %d CPUs = %.1f s; max RSS %d KB\n",
                n, cpus, gap / n, gmax, last, run, cpus, run / cpus, rss }'
}

job_state() {
    scontrol -o show job "$1" 2>/dev/null | tr ' ' '\n' | sed -n 's/^JobState=//p' | sort | uniq -c | xargs
}

install
tmp=$(mktemp -d /tmp/vtsm-slurm.XXXXXX) || fail "mktemp"
chmod 755 "$tmp"
mkdir -p "$tmp"/{run,state,spool,log,parts} || fail "mkdir"
export SLURM_CONF=$tmp/slurm.conf

if [ -z "${VTSM:-}" ]; then
    cargo build --profile test -p vtsm-sim --bin vtsm || fail "cannot build vtsm"
    VTSM=$root/target/debug/vtsm
fi
[ -x "$VTSM" ] || fail "VTSM=$VTSM is not an executable"
say "$(slurmctld -V), vtsm $VTSM"

write_conf
start_daemons
say "node $(sinfo -h -N -o '%N %c CPUs %t')"

# The same campaign in one process (all CPUs), with its peak memory.
t0=$(date +%s.%N)
# shellcheck disable=SC2086 # extra is a word list
/usr/bin/time -f 'max RSS %M KB' -o "$tmp/log/single-time.log" \
    "$VTSM" eval --suite paper --profile test --trials "$trials" --seed "$seed" $extra --quiet \
    --out "$tmp/single" >"$tmp/log/single.log" 2>&1 || fail "single-process run failed: $(tail -n 5 "$tmp/log/single.log")"
say "single process: $(elapsed "$t0") s wall, $(cat "$tmp/log/single-time.log"); $(grep '^setup' "$tmp/log/single.log")"

# submit_and_wait: submit.sh with the campaign, wait for the array and the
# merge; both must complete and the merged trials.csv must equal the single
# run's but for time_s. Sets array and merge (job ids).
submit_and_wait() {
    local ids a m t0=$SECONDS
    submitted=$(date +%s.%N)
    ids=$(VTSM=$VTSM VTSM_PARTS=$tmp/parts VTSM_SHARDS=$shards VTSM_TRIALS=$trials VTSM_SEED=$seed \
        VTSM_EXTRA=$extra VTSM_OUT=$tmp/merged fsw-docs/eval/cluster/submit.sh 2>&1) \
        || fail "submit.sh failed: $ids"
    array=$(sed -n 's/^array //p' <<<"$ids")
    merge=$(sed -n 's/^merge //p' <<<"$ids")
    if [ -z "$array" ] || [ -z "$merge" ]; then fail "submit.sh printed no job ids: $ids"; fi
    say "array job $array ($shards tasks), merge job $merge"
    while [ -n "$(squeue -h -j "$array,$merge" 2>/dev/null)" ]; do
        [ $((SECONDS - t0)) -lt "$timeout_s" ] || fail "jobs not finished after $timeout_s s"
        sleep 1
    done
    say "array and merge: $(elapsed "$submitted") s wall from submission"
    a=$(job_state "$array"); m=$(job_state "$merge")
    [ "$a" = "$shards COMPLETED" ] || fail "array tasks: $a (want $shards COMPLETED)"
    [ "$m" = "1 COMPLETED" ] || fail "merge job: $m"
    [ -f "$tmp/merged/trials.csv" ] || fail "no merged trials.csv"
    if ! diff <(without_time "$tmp/single/trials.csv") <(without_time "$tmp/merged/trials.csv") >"$tmp/log/diff.log"; then
        head -n 20 "$tmp/log/diff.log"
        fail "merged trials.csv differs from the single run's (other than time_s)"
    fi
    say "merged trials.csv equals the single run's but for time_s ($(($(wc -l <"$tmp/merged/trials.csv") - 1)) trials)"
}

submit_and_wait
timeline

# A rerun after a failure, as vtsm-eval.sbatch documents it: part 1 loses its
# part.json and half of its journal records (a task killed after writing its
# tables, before its part.json); submitting again with the same settings
# leaves the complete parts alone and runs only part 1's missing trials.
[ "$shards" -ge 2 ] || { say "one shard: no rerun check"; exit 0; }
p=$tmp/parts/part-1
mapfile -t recs < <(find "$p/part.d" -name '[0-9]*.json' | sort)
[ ${#recs[@]} -ge 2 ] || fail "part 1 journal holds ${#recs[@]} trials"
rm -rf "$p/part.json" "${recs[@]:0:$((${#recs[@]} / 2))}" "$tmp/merged"
want=$((${#recs[@]} - ${#recs[@]} / 2))
first_array=$array
submit_and_wait
grep -q "^vtsm-eval: resuming $p ($want trials recorded)" "$tmp/parts/log/eval-${array}_1.out" \
    || fail "task 1 of the rerun did not resume from its $want recorded trials"
for ((k = 0; k < shards; k++)); do
    [ "$k" = 1 ] && continue
    grep -q "part $k complete, not run again" "$tmp/parts/log/eval-${array}_$k.out" \
        || fail "task $k of the rerun ran a complete part again"
done
say "rerun (array job $array after $first_array): complete parts kept, part 1 resumed from $want of ${#recs[@]} recorded trials"

# A resubmission of some tasks only, without VTSM_SHARDS: N cannot be taken
# from the array (its task count is 1), so the task must refuse to run.
t0=$SECONDS
one=$(env -u VTSM_SHARDS VTSM="$VTSM" VTSM_PARTS="$tmp/parts" sbatch --parsable --array=1 \
    --output="$tmp/parts/log/eval-%A_%a.out" fsw-docs/eval/cluster/vtsm-eval.sbatch) || fail "sbatch --array=1 failed"
one=${one%%;*}
while [ -n "$(squeue -h -j "$one" 2>/dev/null)" ]; do
    [ $((SECONDS - t0)) -lt 60 ] || fail "job $one not finished after 60 s"
    sleep 1
done
[ "$(job_state "$one")" = "1 FAILED" ] || fail "array task 1 alone ran without VTSM_SHARDS: $(job_state "$one")"
grep -q 'set VTSM_SHARDS=N' "$tmp/parts/log/eval-${one}_1.out" || fail "job $one: no message naming VTSM_SHARDS"
say "an array of task 1 alone without VTSM_SHARDS is refused: $(grep -h 'vtsm-eval.sbatch:' "$tmp/parts/log/eval-${one}_1.out")"
