#!/usr/bin/env bash
# The main job: builds twincell (release) and runs the arm demo headless.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup.sh
cargo build --release --locked
"$CARGO_TARGET_DIR/release/twincell" demo "$@"
