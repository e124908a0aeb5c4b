#!/usr/bin/env bash
# twincell on Slurm: a job array runs the scenario's shards, one task per shard, then a
# merge job that depends on the whole array. See deploy/README.md.
#
# Submit both from a login node (this script submits itself as the array):
#   SCENARIO=scenarios/paper_50.toml SEED=42 TRIALS=1000 SHARDS=8 bash deploy/slurm-array.sh
# Results land in $RESULTS/shard-I and the merged files in $RESULTS/merged.
#
# The #SBATCH lines below apply when Slurm runs this file as the array without the launcher;
# the launcher passes --array, --cpus-per-task, --mem and --output on the command line, which
# override them. Ask no more CPUs or memory than one node has, or the tasks stay pending
# forever (reason PartitionConfig): the defaults fit a 2-CPU node.
#SBATCH --job-name=twincell-shard
#SBATCH --array=0-7
#SBATCH --cpus-per-task=2
#SBATCH --mem=2G
#SBATCH --time=02:00:00
#SBATCH --output=twincell-shard-%A_%a.out
#SBATCH --open-mode=append
# A task that loses its node (or is preempted) goes back in the queue, and its shard resumes
# from the records already on disk instead of starting over.
#SBATCH --requeue
# SIGTERM to the batch shell (which execs twincell) 120 s before the time limit: twincell
# stops launching trials, finishes the running ones and writes its reports.
#SBATCH --signal=B:TERM@120
set -euo pipefail

SCENARIO="${SCENARIO:-scenarios/paper_50.toml}"
SEED="${SEED:-}"                              # empty: the scenario file's seed
TRIALS="${TRIALS:-}"                          # empty: the scenario file's trial count
SHARDS="${SHARDS:-8}"
PERCEPTION="${PERCEPTION:-camera}"            # camera (the product) or oracle (diagnosis)
CPUS_PER_TASK="${CPUS_PER_TASK:-2}"           # threads per shard; at most one node's CPUs
MEM="${MEM:-2G}"                              # per shard; a camera shard peaks near 400 MB
RESULTS="${RESULTS:-$PWD/twincell-results}"   # must be on a file system all nodes share
MIN_SUCCESS="${MIN_SUCCESS:-0.95}"
TWINCELL="${TWINCELL:-twincell}"              # path to the binary on the compute nodes

if [ -n "${SLURM_ARRAY_TASK_ID:-}" ]; then
    # One array task: shard SLURM_ARRAY_TASK_ID of SHARDS. --resume continues what an
    # earlier attempt of this task left (a requeue after a node failure), or starts afresh.
    overrides=()
    [ -z "$SEED" ] || overrides+=(--seed "$SEED")
    [ -z "$TRIALS" ] || overrides+=(--trials "$TRIALS")
    exec "$TWINCELL" run "$SCENARIO" "${overrides[@]}" \
        --perception "$PERCEPTION" \
        --shard "$SLURM_ARRAY_TASK_ID/$SHARDS" \
        --jobs "${SLURM_CPUS_PER_TASK:-1}" \
        --resume "$RESULTS/shard-$SLURM_ARRAY_TASK_ID"
fi

# Launcher: submit the array, then the merge job that waits for all of it.
mkdir -p "$RESULTS"
export SCENARIO SEED TRIALS SHARDS PERCEPTION RESULTS TWINCELL
array_id=$(sbatch --parsable --export=ALL --array="0-$((SHARDS - 1))" \
    --cpus-per-task="$CPUS_PER_TASK" --mem="$MEM" \
    --output="$RESULTS/shard-%A_%a.out" "$0")
array_id="${array_id%%;*}"   # --parsable prints "id" or "id;cluster"
# afterany: merge even when a shard failed, so the partial result is on record; merge then
# exits 1 (trials missing) or 2 (a shard left no files), which marks the merge job failed.
merge_id=$(sbatch --parsable --export=ALL \
    --job-name=twincell-merge --dependency="afterany:$array_id" \
    --cpus-per-task=1 --mem=1G --time=00:15:00 \
    --output="$RESULTS/merge-%j.out" \
    --wrap="\"$TWINCELL\" merge \"$RESULTS\"/shard-*/ --out \"$RESULTS/merged\" --min-success $MIN_SUCCESS")
merge_id="${merge_id%%;*}"
echo "shards: job array $array_id ($SHARDS tasks); merge: job $merge_id -> $RESULTS/merged"
