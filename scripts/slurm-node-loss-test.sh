#!/usr/bin/env bash
# The node-loss test: on a cluster of slurmctld and three slurmd nodes, each in its own network
# namespace (scripts/slurm-cluster-up.sh), deploy/slurm-array.sh runs paper_50 (oracle
# perception) as a 6-shard job array plus its merge. As soon as a task has written part of its
# shard, the test kills that task's node: SIGKILL to every process in the node's namespace
# (its slurmd, the slurmstepd and the twincell of the task). Then it checks that
#
# - slurmctld found the node dead by itself (no answer within SlurmdTimeout), set it DOWN and
#   requeued the lost task, which ran again on another node;
# - the requeued task resumed its shard: the records the killed attempt left are still the
#   first bytes of the shard's trials.jsonl, timing included (a rerun from scratch would have
#   written other wall times);
# - every task and the merge completed, and the merged trials.jsonl and report.json equal an
#   unsharded run's (timing aside).
#
# A machine where the namespaces cannot be made fails it with the reason; nothing is skipped.
# TWINCELL_BIN: test this binary instead of building one. KEEP_CLUSTER=1 leaves the cluster up.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup.sh
SHARDS=6

fail() {
    echo "slurm-node-loss-test: FAIL: $*" >&2
    exit 1
}
say() {
    echo "slurm-node-loss-test: $*" >&2
}

started=$SECONDS
# What a machine that cannot make the namespaces gets: without CAP_NET_ADMIN and CAP_SYS_ADMIN
# the script must stop, non-zero, saying which step the kernel refused, not fall back.
if refusal=$(setpriv --inh-caps=-net_admin,-sys_admin --bounding-set=-net_admin,-sys_admin \
    bash scripts/slurm-cluster-up.sh 2>&1 >/dev/null); then
    fail "scripts/slurm-cluster-up.sh succeeded without CAP_NET_ADMIN and CAP_SYS_ADMIN"
fi
grep -q 'cannot make .* on this machine: .*Operation not permitted' <<<"$refusal" \
    || fail "without CAP_NET_ADMIN, scripts/slurm-cluster-up.sh said: $refusal"
say "without CAP_NET_ADMIN it stops with: $(tail -n 1 <<<"$refusal" | cut -c 1-120)..."

up=$(bash scripts/slurm-cluster-up.sh) || fail "could not bring up the multi-node cluster (the reason is above)"
export SLURM_CONF="${up#export SLURM_CONF=}"
[ "${KEEP_CLUSTER:-0}" = 1 ] || trap 'bash scripts/slurm-cluster-up.sh --down' EXIT

if [ -n "${TWINCELL_BIN:-}" ]; then
    bin="$TWINCELL_BIN"
else
    cargo build --release --locked
    bin="$CARGO_TARGET_DIR/release/twincell"
fi
work=$(mktemp -d /tmp/twincell-node-loss.XXXXXX)

say "unsharded reference run"
"$bin" run scenarios/paper_50.toml --perception oracle --jobs 2 --min-success 0 \
    --out "$work/unsharded" >/dev/null

say "submitting $SHARDS shards and the merge to 3 nodes of 1 CPU"
launch=$(SCENARIO=scenarios/paper_50.toml PERCEPTION=oracle SHARDS=$SHARDS CPUS_PER_TASK=1 \
    MEM=1G MIN_SUCCESS=0 RESULTS="$work/results" TWINCELL="$bin" bash deploy/slurm-array.sh)
say "$launch"
array_id=$(sed -n 's/.*job array \([0-9]*\).*/\1/p' <<<"$launch")
merge_id=$(sed -n 's/.*merge: job \([0-9]*\).*/\1/p' <<<"$launch")
[ -n "$array_id" ] && [ -n "$merge_id" ] || fail "could not read the job ids from: $launch"

# Complete records (newline-ended lines) in a shard's trials.jsonl; 0 while there is none.
records() {
    local file="$1/trials.jsonl"
    [ -f "$file" ] || { echo 0; return; }
    tr -cd '\n' <"$file" | wc -c
}

# Kill the node of the first running task that has written at least `kill_at` records of its
# shard and has at least two to go (so that the kill lands mid-shard, not after its last
# record). kill_at is drawn from 1 to 4 (a shard holds 8 or 9 trials, so every task leaves a
# window of at least three records to be caught in) so that runs cut shards at different
# places; NODE_LOSS_SEED repeats a run's draw.
seed="${NODE_LOSS_SEED:-$(date +%s)}"
RANDOM=$seed
kill_at=$((1 + RANDOM % 4))
say "killing a node once a task has $kill_at records (NODE_LOSS_SEED=$seed)"
victim=""
deadline=$((SECONDS + 120))
while [ -z "$victim" ]; do
    [ "$SECONDS" -lt "$deadline" ] || fail "no task was caught mid-shard within 120 s"
    running=$(squeue -h -j "$array_id" -t R -o '%K %N' 2>/dev/null || true)
    if [ -z "$running" ] && [ -z "$(squeue -h -j "$array_id" 2>/dev/null || true)" ]; then
        fail "the array ended before a task could be caught mid-shard"
    fi
    while read -r task node; do
        [ -n "$task" ] || continue
        shard_size=$(( (50 - task + SHARDS - 1) / SHARDS ))
        done_now=$(records "$work/results/shard-$task")
        if [ "$done_now" -ge "$kill_at" ] && [ "$done_now" -le $((shard_size - 2)) ]; then
            victim=$node victim_task=$task
            nodes_at_kill=$(tr '\n' ' ' <<<"$running")
            # The node's every process: slurmd, slurmstepd, the batch shell's twincell.
            pids=$(ip netns pids "$node")
            kill -9 $pids 2>/dev/null || true
            killed_at=$SECONDS
            break
        fi
    done <<<"$running"
    [ -n "$victim" ] || sleep 0.1
done
sleep 0.5
left=$(ip netns pids "$victim" | tr '\n' ' ')
[ -z "$left" ] || fail "processes $left survived SIGKILL on $victim"
shard_dir="$work/results/shard-$victim_task"
kept=$(records "$shard_dir")
head -n "$kept" "$shard_dir/trials.jsonl" >"$work/kept.jsonl"
say "killed $victim ($(wc -w <<<"$pids") processes) while array task $victim_task had $kept of its $shard_size records; running then (task node): $nodes_at_kill"

# Wait for the array and the merge to leave the queue; the lost task first waits for slurmctld
# to declare its node dead (SlurmdTimeout) and for its credential to expire.
deadline=$((SECONDS + 240))
down_seen=""
while :; do
    queue=$(squeue -h -j "$array_id,$merge_id" -o '%i %T %r' 2>/dev/null || true)
    [ -n "$queue" ] || break
    if [ -z "$down_seen" ] && sinfo -h -n "$victim" -o '%T' | grep -q '^down'; then
        down_seen=$SECONDS
        say "slurmctld set $victim DOWN $((down_seen - killed_at)) s after the kill"
    fi
    [ "$SECONDS" -lt "$deadline" ] || { echo "$queue" >&2; fail "jobs still queued 240 s after the kill"; }
    sleep 1
done

field() { # field JOB KEY: KEY's value in `scontrol show job JOB`
    scontrol -o show job "$1" | tr ' ' '\n' | sed -n "s/^$2=//p"
}
sinfo -h -n "$victim" -o '%T %E' | grep -q '^down' \
    || fail "$victim is $(sinfo -h -n "$victim" -o '%T'), not down: slurmctld did not notice the loss"
states=$(field "$array_id" JobState | sort | uniq -c | tr -s ' \n' ' ')
say "array task states:$states"
tasks_done=$(scontrol -o show job "$array_id" | grep -c 'JobState=COMPLETED' || true)
[ "$tasks_done" = "$SHARDS" ] || fail "$tasks_done of $SHARDS array tasks completed; see $work/results/shard-*.out"
victim_job="${array_id}_$victim_task"
restarts=$(field "$victim_job" Restarts)
rerun_on=$(field "$victim_job" BatchHost)
[ "${restarts:-0}" -ge 1 ] || fail "task $victim_task was not requeued (Restarts=$restarts)"
[ "$rerun_on" != "$victim" ] || fail "task $victim_task ran again on the dead node $victim"
cmp -s "$work/kept.jsonl" <(head -c "$(stat -c %s "$work/kept.jsonl")" "$shard_dir/trials.jsonl") \
    || fail "shard $victim_task's records from before the kill were not kept: it did not resume"
[ "$(field "$merge_id" JobState)" = COMPLETED ] \
    || fail "merge job is $(field "$merge_id" JobState); see $work/results/merge-$merge_id.out"
say "task $victim_task: requeued $restarts time(s), resumed on $rerun_on keeping the $kept record(s) the killed attempt wrote"

python3 scripts/same_records.py "$work/unsharded" "$work/results/merged" 50 >&2 \
    || fail "merged files differ from the unsharded run's"
say "PASS in $((SECONDS - started)) s (results in $work)"
