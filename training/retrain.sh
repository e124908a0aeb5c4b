#!/usr/bin/env bash
# The documented retrain: renders the data, trains from scratch, exports and scores on the
# held-out sets. Deterministic on one torch thread (fixed seeds). The shipped
# assets/models/detector.onnx was trained with THREADS=2 DEADLINE_S=2100 on a 2-core CPU, which
# stopped after epoch 29 of 30 (its card records the command and the data's digest).
#
# Usage: training/retrain.sh [MODEL_DIR]   (default assets/models; give another directory to
#        retrain beside the shipped model and compare)
# Environment: DATA (default ~/.cache/twincell/detdata), TWINCELL (the release binary; default
# $CARGO_TARGET_DIR/release/twincell or target/release/twincell), TWINCELL_VENV, PYTHON (a
# Python with torch, onnx and onnxruntime instead of the venv), DEVICE, THREADS, DEADLINE_S
# (stop training after the epoch that ends past this many seconds), PARALLEL and OCCLUDE
# (make_data.sh).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(dirname "$here")"
models="${1:-$root/assets/models}"
# The card records data paths as $DATA/SET (training/common.py, project_path).
export DATA="${DATA:-$HOME/.cache/twincell/detdata}"
data="$DATA"
venv="${TWINCELL_VENV:-$HOME/.cache/twincell/venv}"
[ -n "${PYTHON:-}" ] || "$here/setup.sh"
"$here/make_data.sh" "$data" all
mkdir -p "$models"
# Relative to training/ (where the scripts run), so the card's recorded command names no checkout.
models="$(realpath --relative-to="$here" "$models")"
py="${PYTHON:-$venv/bin/python}"
# DEVICE=cuda trains on a GPU (the augmentation noise then comes from torch's generator on the
# device, so the weights differ from the CPU run's); the default, the CPU on one thread, repeats
# bit for bit. THREADS sets torch's CPU threads (default 1).
device="${DEVICE:-cpu}"
threads="${THREADS:-1}"
export OMP_NUM_THREADS=1 OMP_WAIT_POLICY=passive
cd "$here"
nice -n 10 "$py" train.py --data "$data/train_f_7401" "$data/train_f_7402" \
    "$data/train_f_7403_harsh" "$data/train_f_7404_harsh" "$data/train_f_7405_clutter" \
    --out "$models/detector.pt" --epochs 30 --batch 32 --lr 3e-3 --input 320 256 --seed 6 \
    --threads "$threads" --eval-every 10 --device "$device" ${DEADLINE_S:+--deadline-s "$DEADLINE_S"}
"$py" export.py --weights "$models/detector.pt" --out "$models/detector.onnx"
"$py" evaluate.py --model "$models/detector.onnx" --data "$data/heldout_f_9101" \
    "$data/heldout_f_9102_harsh" "$data/heldout_f_9111" "$data/heldout_f_9112_harsh" \
    "$data/heldout_f_9121_clutter"
