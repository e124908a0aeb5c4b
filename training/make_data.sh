#!/usr/bin/env bash
# Renders the detector's training and held-out sets with `twincell dataset --family` at the
# detector's 640 x 480 input resolution. Every image draws its own camera over the camera envelope
# (tilt 0-35 degrees in any direction, 0.35-1.2 m from the pick station, any roll, field of view
# 35-80 degrees) and one to three tubes over the tube family (bores 8-90 mm, outer/bore 1.15-3,
# heights 30-120 mm, steel finishes) in the cell of one of three scenarios, with that scenario's
# bottles as the foreign objects: the paper's (scenarios/paper_50.toml), the second catalogue's
# (scenarios/suite/catalogue_b.toml) or the cluttered cell's (scenarios/suite/clutter.toml: six
# bottles, standing and lying, among the parts). In half of the images one bottle is set down
# between a tube and the camera, hiding up to half of its end face (`twincell dataset --family
# --occlude`, src/render/family_occlusion.rs; OCCLUDE=0 leaves it out, as the detector shipped
# before the evening of 5 December 2026 was trained). Two classes: `tube` and `foreign`. The label
# metadata (labels/SPLIT/STEM.json) records each image's camera and tubes, so evaluate.py bands by
# tilt, bore and the share of the end face in view. The "harsh" sets add a [sensor] section with strong noise, stains, dirt and badly
# balanced light. Training seeds and held-out seeds are disjoint by construction:
#
#   train:    seed 7401 paper_50, 2200 images, default sensor realism
#             seed 7402 catalogue_b, 1000 images, default
#             seed 7403 paper_50, 800 images, harsh
#             seed 7404 catalogue_b, 400 images, harsh
#             seed 7405 clutter, 1000 images, default
#   held-out: seed 9101 paper_50, 250 images, default; seed 9102 paper_50, 250 images, harsh
#             seed 9111 catalogue_b, 150 images, default; seed 9112 catalogue_b, 150, harsh
#             seed 9121 clutter, 200 images, default
#   (tests/detect.rs renders seeds 4242-4247.)
#
# Usage: training/make_data.sh OUT_DIR [train|heldout|all]   (PARALLEL=1 renders the sets at once;
#        OCCLUDE=0 sets no bottle in front of a tube). A set is rendered again unless its
#        directory holds all its images and OUT_DIR/NAME.made records the same command.
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
clutter="$root/scenarios/suite/clutter.toml"

# make_set NAME SCENARIO SEED COUNT HARSH(0|1)
make_set() {
    local name="$1" base="$2" seed="$3" count="$4" harsh="$5"
    local scenario="$out/$name.toml"
    local flags=(--count "$count" --resolution 640 480 --family)
    [ "${OCCLUDE:-1}" = 1 ] && flags+=(--occlude)
    # What the set is made of: the base scenario (by its path in the project), the seed, the
    # sensor and the flags. A set made otherwise (OCCLUDE changed) is rendered again.
    local made
    made="$(printf '%s seed %s harsh %s %s' "${base#"$root"/}" "$seed" "$harsh" "${flags[*]}")"
    if [ -f "$out/$name/data.yaml" ] && [ "$(find "$out/$name/images" -name '*.png' | wc -l)" = "$count" ] \
        && [ "$(cat "$out/$name.made" 2>/dev/null)" = "$made" ]; then
        echo "make_data.sh: $out/$name already has $count images ($made)"
        return
    fi
    # The set's scenario extends the base by its absolute path (the base may extend its own).
    printf 'extends = "%s"\nseed = %s\n' "$base" "$seed" > "$scenario"
    [ "$harsh" = 1 ] && printf '%s' "$HARSH" >> "$scenario"
    rm -rf "${out:?}/$name" "$out/$name.made"
    "$bin" dataset "$scenario" --out "$out/$name" "${flags[@]}"
    printf '%s\n' "$made" > "$out/$name.made"
}

pids=""
# set NAME SCENARIO SEED COUNT HARSH: one set, in the background with PARALLEL=1.
set_() {
    if [ "${PARALLEL:-0}" = 1 ]; then
        make_set "$@" &
        pids="$pids $!"
    else
        make_set "$@"
    fi
}
case "$which" in
    train|all)
        set_ train_f_7401 "$paper" 7401 2200 0
        set_ train_f_7402 "$catalogue_b" 7402 1000 0
        set_ train_f_7403_harsh "$paper" 7403 800 1
        set_ train_f_7404_harsh "$catalogue_b" 7404 400 1
        set_ train_f_7405_clutter "$clutter" 7405 1000 0 ;;&
    heldout|all)
        set_ heldout_f_9101 "$paper" 9101 250 0
        set_ heldout_f_9102_harsh "$paper" 9102 250 1
        set_ heldout_f_9111 "$catalogue_b" 9111 150 0
        set_ heldout_f_9112_harsh "$catalogue_b" 9112 150 1
        set_ heldout_f_9121_clutter "$clutter" 9121 200 0 ;;
    train) ;;
    *) echo "make_data.sh: unknown set '$which' (train, heldout or all)" >&2; exit 2 ;;
esac
for pid in $pids; do
    wait "$pid"
done
