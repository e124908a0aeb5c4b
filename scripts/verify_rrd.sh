#!/usr/bin/env bash
# Verifies a Rerun recording with the Rerun CLI of the version twincell records for.
#
#   scripts/verify_rrd.sh [--same-as OTHER.rrd] FILE.rrd [ENTITY[=COLUMN]]...
#
# Runs `rerun rrd verify FILE.rrd` (the file must load and every chunk must decode), then checks
# that each ENTITY (an entity path such as /trials/0000/cell) holds data, and with =COLUMN that
# one of its chunks has that data column (such as Mesh3D:vertex_positions). With --same-as, the
# two recordings must hold the same rows (entity, columns, time and values as `rerun rrd print
# -vvv` shows them), in any order and however they were batched into chunks: row ids and chunk
# boundaries differ from run to run, so `rerun rrd compare --unordered` cannot be used.
# Exits non-zero on any failure.
#
# The CLI comes from the rerun-sdk wheel in a virtual environment at $TWINCELL_RERUN_VENV
# (default ~/.cache/twincell/venv-rerun), created and filled on first use.
set -euo pipefail

RERUN_VERSION=0.36.3
venv="${TWINCELL_RERUN_VENV:-$HOME/.cache/twincell/venv-rerun}"

same_as=""
if [[ "${1:-}" == "--same-as" ]]; then
  same_as="${2:-}"
  shift 2 || true
fi
if [[ $# -lt 1 ]]; then
  echo "usage: $0 [--same-as OTHER.rrd] FILE.rrd [ENTITY[=COLUMN]]..." >&2
  exit 2
fi
file="$1"
shift
if [[ ! -s "$file" ]]; then
  echo "verify_rrd: the recording is missing or empty: $file" >&2
  exit 1
fi

rerun="$venv/bin/rerun"
installed=""
if [[ -x "$rerun" ]]; then
  installed="$("$rerun" --version 2>/dev/null | awk 'NR == 1 {print $2}')"
fi
if [[ "$installed" != "$RERUN_VERSION" ]]; then
  echo "verify_rrd: installing rerun-sdk==$RERUN_VERSION into $venv" >&2
  if ! { [[ -x "$venv/bin/pip" ]] || python3 -m venv "$venv"; } ||
    ! "$venv/bin/pip" install --quiet "rerun-sdk==$RERUN_VERSION"; then
    echo "verify_rrd: cannot install rerun-sdk==$RERUN_VERSION (needs python3 with venv and" \
      "access to PyPI or a wheel in PIP_FIND_LINKS); the recording is NOT verified: $file" >&2
    exit 1
  fi
fi

"$rerun" rrd verify "$file"

# Every row of a recording as "entity columns | time... values", row ids removed, sorted.
rows() {
  "$rerun" rrd print -vvv "$1" 2>/dev/null | awk '
    /^Chunk\(/ { split($0, parts, " - "); entity = parts[2] " " parts[3]; next }
    /row_[0-9A-Fa-f]+/ {
      line = $0
      gsub(/row_[0-9A-Fa-f]+/, "", line)
      gsub(/[│┆ ]+/, " ", line)
      print entity " |" line
    }' | LC_ALL=C sort
}

if [[ -n "$same_as" ]]; then
  expected="$(rows "$same_as")"
  actual="$(rows "$file")"
  if [[ -z "$expected" ]] || [[ "$expected" != "$actual" ]]; then
    echo "verify_rrd: the recordings hold different rows: $same_as $file" >&2
    diff <(echo "$expected") <(echo "$actual") | head -20 >&2 || true
    exit 1
  fi
  echo "verify_rrd: the same $(wc -l <<<"$actual") rows as $same_as"
fi

if [[ $# -gt 0 ]]; then
  # One line per chunk: "Chunk(...) with N rows (...) - /entity/path - data columns: [A:b, C:d]"
  listing="$("$rerun" rrd print "$file" 2>/dev/null | grep '^Chunk(')"
  missing=0
  for want in "$@"; do
    entity="${want%%=*}"
    column=""
    [[ "$want" == *=* ]] && column="${want#*=}"
    lines="$(grep -F -- " - $entity - data columns: [" <<<"$listing" || true)"
    if [[ -z "$lines" ]]; then
      echo "verify_rrd: no data at entity $entity: $file" >&2
      missing=1
    elif [[ -n "$column" ]] && ! grep -qE "[[ ]${column}[] ,]" <<<"$lines"; then
      echo "verify_rrd: entity $entity has no column $column: $file" >&2
      missing=1
    fi
  done
  if [[ $missing -ne 0 ]]; then
    exit 1
  fi
  echo "verify_rrd: all $# expected entities present: $file"
fi
