#!/usr/bin/env bash
# Builds the Python package (python/: twincell, compiled with maturin and PyO3 against this
# machine's CPython) and installs it into a virtual environment with what it and its tests need
# from PyPI: maturin, numpy, gymnasium, pytest, pillow (the tests read PNG frames).
#
#   bash scripts/python-setup.sh          # then: ~/.cache/twincell/venv-python/bin/python
#   source scripts/python-setup.sh        # the same, and $TWINCELL_PYTHON names that python
#
# The environment is $TWINCELL_PYTHON_VENV (default ~/.cache/twincell/venv-python), created on
# first use; the build shares $CARGO_TARGET_DIR and Cargo.lock with the crate (scripts/setup.sh).
set -euo pipefail

_twincell_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$_twincell_root/scripts/setup.sh"

TWINCELL_PYTHON_VENV="${TWINCELL_PYTHON_VENV:-$HOME/.cache/twincell/venv-python}"
if [[ ! -x "$TWINCELL_PYTHON_VENV/bin/python" ]]; then
    echo "twincell: creating the Python environment $TWINCELL_PYTHON_VENV" >&2
    if ! python3 -m venv "$TWINCELL_PYTHON_VENV"; then
        echo "twincell: cannot create a virtual environment with $(command -v python3):" \
            "install python3 with venv (Debian: apt-get install python3-venv)" >&2
        exit 1
    fi
fi
export TWINCELL_PYTHON="$TWINCELL_PYTHON_VENV/bin/python"

# Satisfied requirements are not fetched again.
_twincell_requirements=("maturin>=1.9.4,<2" "numpy>=1.26" "gymnasium>=1.0,<2" "pytest>=8" "pillow>=10")
if ! "$TWINCELL_PYTHON" -m pip install --quiet --disable-pip-version-check "${_twincell_requirements[@]}"; then
    echo "twincell: cannot install ${_twincell_requirements[*]} from PyPI into" \
        "$TWINCELL_PYTHON_VENV (no network, or no wheel for $("$TWINCELL_PYTHON" --version));" \
        "the Python package is NOT installed" >&2
    exit 1
fi

echo "twincell: building the Python package (python/) into $TWINCELL_PYTHON_VENV" >&2
if ! (cd "$_twincell_root/python" && VIRTUAL_ENV="$TWINCELL_PYTHON_VENV" \
    "$TWINCELL_PYTHON_VENV/bin/maturin" develop --release --locked --quiet); then
    echo "twincell: the Python package did not build (see above); it is NOT installed" >&2
    exit 1
fi
"$TWINCELL_PYTHON" -c 'import twincell' || {
    echo "twincell: the Python package built but does not import in $TWINCELL_PYTHON" >&2
    exit 1
}
echo "twincell: installed; use $TWINCELL_PYTHON (import twincell)" >&2
