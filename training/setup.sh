#!/usr/bin/env bash
# Makes the training venv at ~/.cache/twincell/venv (or $TWINCELL_VENV) from PyPI only.
#
# PyPI's Linux torch wheel is the CUDA build and pulls the NVIDIA runtime wheels (about 5 GB
# installed); no CPU-only torch is published on PyPI for x86_64 Linux, and the CPU wheel index is
# not reachable here, so we take PyPI's wheel and simply never touch CUDA (training runs on the
# CPU with one thread). The versions are pinned so the retrain is reproducible.
set -euo pipefail
venv="${TWINCELL_VENV:-$HOME/.cache/twincell/venv}"
if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
fi
"$venv/bin/pip" install --quiet \
    torch==2.15.0 onnx==1.23.2 onnxruntime==1.32.0 numpy==2.4.6 pillow==13.0.0
"$venv/bin/python" -c 'import torch, onnx, onnxruntime; print("torch", torch.__version__, "onnx", onnx.__version__, "onnxruntime", onnxruntime.__version__)'
