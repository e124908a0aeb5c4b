#!/usr/bin/env bash
# Checks (and where possible installs) what twincell needs on a fresh machine: a Rust toolchain.
# Sourced by scripts/run.sh and scripts/test.sh.
set -euo pipefail

if ! command -v cargo >/dev/null 2>&1; then
    echo "twincell: cargo not found. Install a Rust toolchain (1.95 or newer), e.g. from rustup, then re-run." >&2
    exit 1
fi
rust_minor=$(rustc --version | sed -E 's/^rustc 1\.([0-9]+).*/\1/')
if [ "${rust_minor:-0}" -lt 95 ]; then
    echo "twincell: rustc $(rustc --version) is older than 1.95, which the pinned dependencies need." >&2
    exit 1
fi

# Keep build outputs outside the clone so repeated runs are incremental.
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/twincell/target}"
mkdir -p "$CARGO_TARGET_DIR"
