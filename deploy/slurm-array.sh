#!/usr/bin/env bash
# twincell on Slurm: a job array runs the scenario's shards, one task per shard, then a
# merge job that depends on the whole array. See deploy/README.md.
#
# Submit both from a login node (this script submits itself as the array):
#   SCENARIO=scenarios/sorting.toml SEED=42 TRIALS=1000 SHARDS=8 bash deploy/slurm-array.sh
# Results land in $RESULTS/shard-I and the merged files in $RESULTS/merged.
#
# The #SBATCH lines below apply when Slurm runs this file as the array. --array on the
# command line (set from SHARDS) overrides the default 0-7 here; keep them in step if you
# submit with `sbatch deploy/slurm-array.sh` directly: --array=0-(N-1) for N shards.
#SBATCH --job-name=twincell-shard
#SBATCH --array=0-7
#SBATCH --cpus-per-task=4
#SBATCH --mem=4G
#SBATCH --time=02:00:00
#SBATCH --output=twincell-shard-%A_%a.out
# SIGTERM to the batch shell (which execs twincell) 120 s before the time limit: twincell
# stops launching trials, finishes the running ones and writes its reports.
#SBATCH --signal=B:TERM@120
set -euo pipefail

SCENARIO="${SCENARIO:-scenarios/sorting.toml}"
SEED="${SEED:-42}"
TRIALS="${TRIALS:-1000}"
SHARDS="${SHARDS:-8}"
RESULTS="${RESULTS:-$PWD/twincell-results}"   # must be on a file system all nodes share
MIN_SUCCESS="${MIN_SUCCESS:-0.95}"
TWINCELL="${TWINCELL:-twincell}"              # path to the binary on the compute nodes

if [ -n "${SLURM_ARRAY_TASK_ID:-}" ]; then
    # One array task: shard SLURM_ARRAY_TASK_ID of SHARDS.
    exec "$TWINCELL" run "$SCENARIO" \
        --seed "$SEED" --trials "$TRIALS" --perception camera \
        --shard "$SLURM_ARRAY_TASK_ID/$SHARDS" \
        --jobs "${SLURM_CPUS_PER_TASK:-1}" \
        --out "$RESULTS/shard-$SLURM_ARRAY_TASK_ID"
fi

# Launcher: submit the array, then the merge job that waits for all of it.
mkdir -p "$RESULTS"
export SCENARIO SEED TRIALS SHARDS RESULTS TWINCELL
array_id=$(sbatch --parsable --export=ALL --array="0-$((SHARDS - 1))" "$0")
array_id="${array_id%%;*}"   # --parsable prints "id" or "id;cluster"
# afterany: merge even when a shard failed, so the partial result is on record; merge then
# exits 1 (trials missing) or 2 (a shard left no report), which marks the merge job failed.
merge_id=$(sbatch --parsable --export=ALL \
    --job-name=twincell-merge --dependency="afterany:$array_id" \
    --cpus-per-task=1 --mem=1G --time=00:15:00 \
    --output="$RESULTS/merge-%j.out" \
    --wrap="\"$TWINCELL\" merge \"$RESULTS\"/shard-* --out \"$RESULTS/merged\" --min-success $MIN_SUCCESS")
echo "shards: job array $array_id ($SHARDS tasks); merge: job $merge_id -> $RESULTS/merged"
