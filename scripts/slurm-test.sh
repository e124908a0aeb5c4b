#!/usr/bin/env bash
# The Slurm test: on a one-node cluster (scripts/slurm-up.sh), deploy/slurm-array.sh submits
# paper_50 (oracle perception) as a 4-shard job array plus its merge job; the merged
# trials.jsonl must equal an unsharded run's byte for byte (timing fields aside) and the
# merged report.json likewise. Any failure -- packages, daemons, a task that cannot be
# scheduled, a job that fails, a differing byte -- exits non-zero; nothing is skipped.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup.sh

fail() {
    echo "slurm-test: FAIL: $*" >&2
    exit 1
}

started=$SECONDS
bash scripts/slurm-up.sh
# TWINCELL_BIN: test this binary instead of building one (where several checkouts share one
# target directory, a copy taken right after the build).
if [ -n "${TWINCELL_BIN:-}" ]; then
    bin="$TWINCELL_BIN"
else
    cargo build --release --locked
    bin="$CARGO_TARGET_DIR/release/twincell"
fi
work=$(mktemp -d /tmp/twincell-slurm.XXXXXX)

echo "slurm-test: unsharded reference run" >&2
# The same gate as the merge below, so that report.json compares whole.
"$bin" run scenarios/paper_50.toml --perception oracle --jobs 2 --min-success 0 \
    --out "$work/unsharded" >/dev/null

echo "slurm-test: submitting 4 shards and the merge" >&2
launch=$(SCENARIO=scenarios/paper_50.toml PERCEPTION=oracle SHARDS=4 CPUS_PER_TASK=1 MEM=1G \
    MIN_SUCCESS=0 RESULTS="$work/results" TWINCELL="$bin" bash deploy/slurm-array.sh)
echo "$launch" >&2
array_id=$(sed -n 's/.*job array \([0-9]*\).*/\1/p' <<<"$launch")
merge_id=$(sed -n 's/.*merge: job \([0-9]*\).*/\1/p' <<<"$launch")
[ -n "$array_id" ] && [ -n "$merge_id" ] || fail "could not read the job ids from: $launch"

# Wait for the array and the merge to leave the queue. A job pending for a reason that no
# wait will cure (more CPUs or memory than the node has, a dependency that cannot be met)
# fails the test at once and names the reason.
while :; do
    queue=$(squeue -h -j "$array_id,$merge_id" -o '%i %T %r' 2>/dev/null || true)
    [ -n "$queue" ] || break
    if grep -E 'PartitionConfig|ReqNodeNotAvail|PartitionNodeLimit|DependencyNeverSatisfied|BadConstraints|Resources.*never' <<<"$queue" >&2; then
        scancel "$array_id" "$merge_id" || true
        fail "a job can never run (above)"
    fi
    sleep 2
done

job_state() {
    scontrol -o show job "$1" | tr ' ' '\n' | sed -n 's/^JobState=//p'
}
# Every array task and the merge completed (exit 0).
states=$(scontrol -o show job "$array_id" | tr ' ' '\n' | sed -n 's/^JobState=//p' | sort | uniq -c)
echo "slurm-test: array task states: $(tr '\n' ' ' <<<"$states")" >&2
tasks_done=$(scontrol -o show job "$array_id" | grep -c 'JobState=COMPLETED' || true)
[ "$tasks_done" = 4 ] || fail "$tasks_done of 4 array tasks completed; see $work/results/shard-*.out"
[ "$(job_state "$merge_id")" = COMPLETED ] || fail "merge job is $(job_state "$merge_id"); see $work/results/merge-$merge_id.out"

python3 scripts/same_records.py "$work/unsharded" "$work/results/merged" 50 >&2 \
    || fail "merged files differ from the unsharded run's"
echo "slurm-test: PASS in $((SECONDS - started)) s (results in $work)" >&2
