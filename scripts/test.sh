#!/usr/bin/env bash
# The test suite: everything in release mode (physics is ~150x slower unoptimised).
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup.sh
cargo test --release --locked "$@"
