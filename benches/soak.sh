#!/usr/bin/env bash
# Soak benchmark (not run in CI): a long batch, sampling the process's resident memory, open
# file descriptors and threads once a second against the number of trials written.
#
#   bash benches/soak.sh [PERCEPTION] [TRIALS] [JOBS] [SCENARIO]
#   bash benches/soak.sh oracle 1000 2
#   bash benches/soak.sh camera 1000 2
#
# Writes out/soak-PERCEPTION/samples.csv (seconds, trials, rss_kb, fds, threads) and prints
# RSS, fds and threads at the first sample with at least 100 trials and at the last one, and
# the relative RSS change between them (the goal: within 5 %).
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup.sh

perception="${1:-oracle}"
trials="${2:-1000}"
jobs="${3:-2}"
scenario="${4:-scenarios/smoke.toml}"
out="out/soak-$perception"
# TWINCELL_BIN: soak this binary instead of building one.
if [ -n "${TWINCELL_BIN:-}" ]; then
    bin="$TWINCELL_BIN"
else
    cargo build --release --locked
    bin="$CARGO_TARGET_DIR/release/twincell"
fi
rm -rf "$out"
mkdir -p "$out"
samples="$out/samples.csv"
echo "seconds,trials,rss_kb,fds,threads" >"$samples"

"$bin" run "$scenario" --perception "$perception" --trials "$trials" --jobs "$jobs" \
    --out "$out/batch" >"$out/stdout.txt" 2>"$out/stderr.txt" &
pid=$!
start=$SECONDS
while kill -0 "$pid" 2>/dev/null; do
    # Any read may fail while the process starts or ends (no trials file yet, /proc gone).
    rss=$(awk '/^VmRSS:/ {print $2}' "/proc/$pid/status" 2>/dev/null || true)
    threads=$(awk '/^Threads:/ {print $2}' "/proc/$pid/status" 2>/dev/null || true)
    fds=$( (ls "/proc/$pid/fd" 2>/dev/null || true) | wc -l)
    done_trials=$( (cat "$out/batch/trials.jsonl" 2>/dev/null || true) | wc -l)
    [ -z "$rss" ] || echo "$((SECONDS - start)),$done_trials,$rss,$fds,$threads" >>"$samples"
    sleep 1
done
wait "$pid" || echo "soak: twincell exited with $? (a gate or a failure; see $out/stderr.txt)" >&2

python3 - "$samples" "$perception" "$trials" <<'PY'
import csv, sys
rows = [r for r in csv.DictReader(open(sys.argv[1]))]
at100 = next((r for r in rows if int(r["trials"]) >= 100), None)
last = rows[-1]
peak = max(int(r["rss_kb"]) for r in rows)
if at100 is None:
    sys.exit("soak: fewer than 100 trials were written")
a, b = int(at100["rss_kb"]), int(last["rss_kb"])
print(f"soak {sys.argv[2]}, {sys.argv[3]} trials, {len(rows)} samples over {last['seconds']} s")
for name, r in (("at trial >= 100", at100), ("at the end", last)):
    print(f"  {name:16} trial {r['trials']:>5}: RSS {int(r['rss_kb'])/1024:7.1f} MB, "
          f"{r['fds']} fds, {r['threads']} threads")
print(f"  RSS change {100.0 * (b - a) / a:+.1f} %, peak {peak/1024:.1f} MB")
PY
