#!/usr/bin/env bash
# The documented retrain: renders the data, trains from scratch, exports and scores on the
# held-out sets. Deterministic (fixed seeds, one torch thread): it reproduces the shipped
# assets/models/detector.onnx.
#
# Usage: training/retrain.sh [MODEL_DIR]   (default assets/models; give another directory to
#        retrain beside the shipped model and compare)
# Environment: DATA (default ~/.cache/twincell/detdata), TWINCELL (the release binary; default
# $CARGO_TARGET_DIR/release/twincell or target/release/twincell), TWINCELL_VENV.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(dirname "$here")"
models="${1:-$root/assets/models}"
# The card records data paths as $DATA/SET (training/common.py, project_path).
export DATA="${DATA:-$HOME/.cache/twincell/detdata}"
data="$DATA"
venv="${TWINCELL_VENV:-$HOME/.cache/twincell/venv}"
"$here/setup.sh"
"$here/make_data.sh" "$data" all
mkdir -p "$models"
# Relative to training/ (where the scripts run), so the card's recorded command names no checkout.
models="$(realpath --relative-to="$here" "$models")"
py="$venv/bin/python"
export OMP_NUM_THREADS=1 OMP_WAIT_POLICY=passive
cd "$here"
nice -n 10 "$py" train.py --data "$data/train_f_7401" "$data/train_f_7402" \
    "$data/train_f_7403_harsh" "$data/train_f_7404_harsh" \
    --out "$models/detector.pt" --epochs 10 --batch 16 --lr 3e-3 --input 320 256 --seed 6 \
    --threads 1 --eval-every 5
"$py" export.py --weights "$models/detector.pt" --out "$models/detector.onnx"
"$py" evaluate.py --model "$models/detector.onnx" --data "$data/heldout_f_9101" \
    "$data/heldout_f_9102_harsh" "$data/heldout_f_9111" "$data/heldout_f_9112_harsh"
