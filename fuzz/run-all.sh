#!/usr/bin/env bash
# Runs every fuzz target for SECONDS each (default 600), PARALLEL at a time (default 2), each
# on its committed corpus, then minimises each corpus and prints, per target: the seconds run,
# the executions, the corpus before and after (files, bytes) and the crashes found. Not run in CI
# (CI replays the corpora through tests/fuzz_corpora.rs).
#
#   bash fuzz/run-all.sh [SECONDS] [PARALLEL] [TARGET...]
#
# Needs cargo-fuzz (`cargo install cargo-fuzz`); the stable toolchain runs it with
# RUSTC_BOOTSTRAP=1. The instrumented build goes to $FUZZ_TARGET_DIR (default
# ~/.cache/twincell/fuzz-target); on 2 cores its first build takes about an hour.
set -euo pipefail
cd "$(dirname "$0")"
seconds="${1:-600}"
parallel="${2:-2}"
shift $(($# < 2 ? $# : 2))
targets=("$@")
[ ${#targets[@]} -gt 0 ] || mapfile -t targets < <(ls fuzz_targets | sed 's/\.rs$//')
export RUSTC_BOOTSTRAP=1
export CARGO_TARGET_DIR="${FUZZ_TARGET_DIR:-$HOME/.cache/twincell/fuzz-target}"
command -v cargo-fuzz >/dev/null || {
    echo "fuzz/run-all.sh: cargo-fuzz is missing: cargo install cargo-fuzz" >&2
    exit 2
}
cargo fuzz build -s none
logs="$CARGO_TARGET_DIR/fuzz-logs"
mkdir -p "$logs" artifacts

corpus_size() { echo "$(find "corpus/$1" -type f | wc -l) files, $(du -sb "corpus/$1" | cut -f1) bytes"; }

declare -A before
for t in "${targets[@]}"; do before[$t]="$(corpus_size "$t")"; done

running=0
for t in "${targets[@]}"; do
    echo "fuzz: $t for $seconds s"
    # -jobs=1 keeps one process a target; a crash stops that target, its input in artifacts/.
    (cargo fuzz run "$t" -s none "corpus/$t" -- -max_total_time="$seconds" -timeout=20 \
        -rss_limit_mb=4096 -print_final_stats=1 >"$logs/$t.log" 2>&1 &&
        echo ok >"$logs/$t.rc" || echo "exit $?" >"$logs/$t.rc") &
    running=$((running + 1))
    if [ "$running" -ge "$parallel" ]; then
        wait -n
        running=$((running - 1))
    fi
done
wait

status=0
for t in "${targets[@]}"; do
    cargo fuzz cmin "$t" -s none "corpus/$t" >"$logs/$t.cmin.log" 2>&1 || true
    execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$logs/$t.log" | grep -o '[0-9]*$' || echo "?")
    crashes=$(find "artifacts/$t" -type f 2>/dev/null | wc -l)
    echo "$t: $(cat "$logs/$t.rc"), $execs executions in $seconds s; corpus ${before[$t]} -> $(corpus_size "$t"); $crashes crash inputs in fuzz/artifacts/$t"
    [ "$crashes" -eq 0 ] || status=1
done
exit "$status"
