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

# The camera renders headless with wgpu: on a GPU when there is one, else on Mesa's software
# adapter (llvmpipe through EGL/GL). Make sure the EGL loader and Mesa's drivers are there.
shared_libs=$(ldconfig -p 2>/dev/null || true)
if ! grep -q 'libEGL_mesa.so.0' <<<"$shared_libs"; then
    echo "twincell: Mesa EGL (llvmpipe) not found; installing libegl1 libegl-mesa0 libgl1-mesa-dri" >&2
    if command -v apt-get >/dev/null 2>&1 && { [ "$(id -u)" = 0 ] || command -v sudo >/dev/null 2>&1; }; then
        sudo_cmd=""
        [ "$(id -u)" = 0 ] || sudo_cmd="sudo"
        if ! { $sudo_cmd apt-get update -qq && $sudo_cmd apt-get install -y -qq libegl1 libegl-mesa0 libgl1-mesa-dri; }; then
            echo "twincell: could not install Mesa EGL; the camera needs a GPU or Mesa's llvmpipe (packages libegl1 libegl-mesa0 libgl1-mesa-dri)" >&2
            exit 1
        fi
    else
        echo "twincell: the camera needs a GPU or Mesa's llvmpipe: install libegl1 libegl-mesa0 libgl1-mesa-dri (or your system's Mesa EGL packages)" >&2
        exit 1
    fi
fi
