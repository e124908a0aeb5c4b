"""ONNX Runtime (Python) against the Rust detector on the same input tensor.

Runs `twincell detect IMAGE --dump-raw DIR` (the Rust side writes its network input and raw
output as little-endian f32), feeds the very same input to ONNX Runtime and reports the largest
absolute difference of the outputs. It also checks that the Rust input equals, bit for bit, what
training and evaluation feed the network for that image (common.letterbox). Exit code 1 when the
outputs differ by more than --tolerance (default 1e-4) or an input differs at all.
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np
import onnxruntime as ort
from PIL import Image

import common


def main(argv):
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--twincell", required=True, help="path to the release twincell binary")
    p.add_argument("--model", required=True, help="ONNX file")
    p.add_argument("--tolerance", type=float, default=1e-4)
    p.add_argument("images", nargs="+")
    args = p.parse_args(argv)
    session = ort.InferenceSession(args.model, providers=["CPUExecutionProvider"])
    with open(os.path.splitext(args.model)[0] + ".json", encoding="utf-8") as f:
        card = json.load(f)
    worst = 0.0
    inputs_differ = 0
    for image in args.images:
        with tempfile.TemporaryDirectory() as tmp:
            subprocess.run(
                [args.twincell, "detect", image, "--model", args.model, "--dump-raw", tmp],
                check=True,
                stdout=subprocess.DEVNULL,
            )
            with open(os.path.join(tmp, "shapes.json"), encoding="utf-8") as f:
                shapes = json.load(f)
            x = np.fromfile(os.path.join(tmp, "input.f32"), "<f4").reshape(shapes["input"])
            rust = np.fromfile(os.path.join(tmp, "output.f32"), "<f4").reshape(shapes["output"])
        canvas, _ = common.letterbox(
            np.asarray(Image.open(image).convert("RGB")),
            card["input_width"],
            card["input_height"],
            card["pad_value"],
            image,
        )
        trained = common.to_tensor(canvas[None]).numpy()
        if trained.shape != x.shape or not np.array_equal(trained, x):
            inputs_differ += 1
            print(f"{image}: the Rust input differs from training's letterbox")
        py = session.run(None, {"images": x})[0][0]
        if py.shape != rust.shape:
            print(f"{image}: shapes differ: python {py.shape}, rust {rust.shape}")
            return 1
        diff = float(np.abs(py - rust).max())
        worst = max(worst, diff)
        print(f"{image}: max abs diff {diff:.3g} over {rust.size} values")
    ok = worst <= args.tolerance and not inputs_differ
    print(f"max abs diff {worst:.3g} ({'within' if worst <= args.tolerance else 'over'} "
          f"{args.tolerance:g}); inputs differing from training's: {inputs_differ}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
