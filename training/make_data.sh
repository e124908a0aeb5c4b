#!/usr/bin/env bash
# Renders the detector's training and held-out sets with `twincell dataset` at the camera's
# 640 x 480 detector resolution. Every set is one of the two part catalogues' scenarios with its
# own `seed` (so its own shot stream): the paper's six axles (scenarios/paper_50.toml) or the
# second catalogue's six sleeves (scenarios/suite/catalogue_b.toml); the detector learns the
# union of their types (training/common.py, union_names). The "harsh" sets add a [sensor]
# section with strong noise, stains, dirt and badly balanced light. Training seeds and held-out
# seeds are disjoint by construction:
#
#   paper_50     train:    seed 731 (the paper's), 1200 images, default sensor realism
#                train:    seed 7311, 400 images, harsh sensor realism
#                held-out: seed 9001, 200 images, default; seed 9002, 200 images, harsh
#   catalogue_b  train:    seed 7321, 800 images, default sensor realism
#                train:    seed 7322, 300 images, harsh sensor realism
#                held-out: seed 9011, 200 images, default; seed 9012, 200 images, harsh
#   (tests/detect.rs renders seeds 4242 and 4243.)
#
# Usage: training/make_data.sh OUT_DIR [train|heldout|all]
# Needs the release binary (cargo build --release --bin twincell) or TWINCELL=path.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(dirname "$here")"
out="${1:?usage: make_data.sh OUT_DIR [train|heldout|all]}"
which="${2:-all}"
bin="${TWINCELL:-${CARGO_TARGET_DIR:-$root/target}/release/twincell}"
[ -x "$bin" ] || { echo "make_data.sh: no twincell binary at $bin (build it or set TWINCELL)" >&2; exit 2; }
mkdir -p "$out"

HARSH='
[sensor]
noise_sigma = 7.0
salt_pepper_fraction = 0.003
illumination_gradient = 0.35
vignetting = 0.45
max_stains = 5
max_dirt = 14
light_jitter_deg = 25.0
intensity_jitter = 0.4
pose_jitter_m = 0.0005
pose_jitter_deg = 0.05
'

paper="$root/scenarios/paper_50.toml"
catalogue_b="$root/scenarios/suite/catalogue_b.toml"

# make_set NAME SCENARIO SEED COUNT HARSH(0|1)
make_set() {
    local name="$1" base="$2" seed="$3" count="$4" harsh="$5"
    local scenario="$out/$name.toml"
    if [ -f "$out/$name/data.yaml" ] && [ "$(find "$out/$name/images" -name '*.png' | wc -l)" = "$count" ]; then
        echo "make_data.sh: $out/$name already has $count images"
        return
    fi
    sed "s/^seed = .*/seed = $seed/" "$base" > "$scenario"
    [ "$harsh" = 1 ] && printf '%s' "$HARSH" >> "$scenario"
    rm -rf "${out:?}/$name"
    "$bin" dataset "$scenario" --count "$count" --out "$out/$name" --resolution 640 480
}

case "$which" in
    train|all)
        make_set train_731 "$paper" 731 1200 0
        make_set train_7311_harsh "$paper" 7311 400 1
        make_set train_b_7321 "$catalogue_b" 7321 800 0
        make_set train_b_7322_harsh "$catalogue_b" 7322 300 1 ;;&
    heldout|all)
        make_set heldout_9001 "$paper" 9001 200 0
        make_set heldout_9002_harsh "$paper" 9002 200 1
        make_set heldout_b_9011 "$catalogue_b" 9011 200 0
        make_set heldout_b_9012_harsh "$catalogue_b" 9012 200 1 ;;
    train) ;;
    *) echo "make_data.sh: unknown set '$which' (train, heldout or all)" >&2; exit 2 ;;
esac
