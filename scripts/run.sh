#!/usr/bin/env bash
# The main job: builds twincell (release) and runs the paper's 50-trial sorting scenario headless.
# Extra arguments go to `twincell run` (e.g. --seed 1, --jobs 2, --min-success 0.9).
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup.sh
cargo build --release --locked
# Camera perception (the default): each trial renders the pick station on the software adapter,
# runs the shipped detector and the metrology, and sorts by what they find.
"$CARGO_TARGET_DIR/release/twincell" run scenarios/paper_50.toml --out out/paper_50 "$@"
