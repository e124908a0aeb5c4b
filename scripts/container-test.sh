#!/usr/bin/env bash
# The container test: deploy/container/build.sh builds localhost/twincell:latest from Debian's
# packages (no registry pull), deploy/container/run.sh runs the smoke scenario in it (camera
# perception: Mesa's llvmpipe inside the image), and its trials.jsonl and report.json must
# equal the same run's on the host, timing aside. Any failure -- a package, the base, the
# build, an engine that cannot run containers here, a differing byte -- exits non-zero with
# the engine's message; nothing is skipped.
# TWINCELL_BIN: test this binary instead of building one.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup.sh

fail() {
    echo "container-test: FAIL: $*" >&2
    exit 1
}

started=$SECONDS
if [ -z "${TWINCELL_BIN:-}" ]; then
    cargo build --release --locked
    export TWINCELL_BIN="$CARGO_TARGET_DIR/release/twincell"
fi
bash deploy/container/build.sh || fail "the image was not built (the reason is above)"

# Both runs write under out/ in this checkout, which run.sh mounts at the same path.
out=out/container-test
rm -rf "$out"
mkdir -p "$out"
echo "container-test: smoke on the host" >&2
"$TWINCELL_BIN" run scenarios/smoke.toml --out "$out/host" >/dev/null
echo "container-test: smoke in the container" >&2
bash deploy/container/run.sh run scenarios/smoke.toml --out "$out/container" >/dev/null \
    || fail "twincell in the container failed (above)"
python3 scripts/same_records.py "$out/host" "$out/container" 4 >&2 \
    || fail "the container's records differ from the host's"
echo "container-test: PASS in $((SECONDS - started)) s" >&2
