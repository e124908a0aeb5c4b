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

# Installs Debian packages "$2..." for "$1" (what needs them), or says what to install.
apt_install() {
    local why="$1"
    shift
    echo "twincell: $why: installing $*" >&2
    if command -v apt-get >/dev/null 2>&1 && { [ "$(id -u)" = 0 ] || command -v sudo >/dev/null 2>&1; }; then
        local sudo_cmd=""
        [ "$(id -u)" = 0 ] || sudo_cmd="sudo"
        if { $sudo_cmd apt-get update -qq && $sudo_cmd apt-get install -y -qq "$@"; }; then
            return 0
        fi
        echo "twincell: could not install $* ($why)" >&2
    else
        echo "twincell: install $* (or your system's equivalent): $why" >&2
    fi
    exit 1
}

# The camera renders headless with wgpu: on a GPU when there is one, else on Mesa's software
# adapter (llvmpipe through EGL/GL). Make sure the EGL loader and Mesa's drivers are there.
shared_libs=$(ldconfig -p 2>/dev/null || true)
if ! grep -q 'libEGL_mesa.so.0' <<<"$shared_libs"; then
    apt_install "the camera needs a GPU or Mesa's llvmpipe (EGL)" libegl1 libegl-mesa0 libgl1-mesa-dri
fi

# The recording tests verify their files with the Rerun CLI, which scripts/verify_rrd.sh installs
# from PyPI into a Python virtual environment.
if ! python3 -c 'import ensurepip, venv' >/dev/null 2>&1; then
    apt_install "the Rerun CLI that verifies recordings needs python3 with venv" python3 python3-venv
fi
