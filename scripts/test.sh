#!/usr/bin/env bash
# The test suite: everything in release mode (physics is ~150x slower unoptimised).
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/setup.sh
# The report page's browser test (tests/report_page.rs) loads report.html in headless Chromium
# through scripts/browser_check.py; without it that test fails, so install it here or stop.
if ! command -v "${TWINCELL_CHROMIUM:-chromium}" >/dev/null 2>&1; then
    apt_install "the report page's browser test needs headless Chromium" chromium
fi
cargo test --release --locked "$@"
# The Python package (python/): built and installed by scripts/python-setup.sh, then its pytest,
# which compares its functions with the twincell binary cargo test just built.
source scripts/python-setup.sh
TWINCELL_BIN="$CARGO_TARGET_DIR/release/twincell" "$TWINCELL_PYTHON" -m pytest python/tests -q
