"""Exports trained weights to the shipped ONNX graph and writes its model card.

The graph takes [1, 3, H, W] RGB in 0..1 (W x H the input size the weights were trained at,
recorded in the .pt: 320 x 256, a 640 x 480 camera frame halved and letterboxed) and returns [1, cells, 5 + classes]: x0, y0, x1, y1 in input pixels, objectness, class
probabilities. The card (same stem, .json) holds what inference needs (classes, input size,
padding, operating threshold, NMS IoU) plus the training record and, once evaluate.py has run,
the held-out metrics.
"""

import argparse
import json
import os
import sys

import torch

from common import PAD_VALUE
from model import Detector, Exported

SCORE_THRESHOLD = 0.5
NMS_IOU = 0.5
INPUT_LAYOUT = (
    "NCHW float32 RGB in 0..1 (byte / 255). The image is letterboxed: scaled to fit with its "
    "aspect kept and centred on pad_value grey. When the image is a whole factor k larger than "
    "its fitted size (a 640x480 frame into 320x256: k = 2, 320x240 plus 8 grey rows above and "
    "below; a 1280x960 frame: k = 4), each input pixel is the mean of a k x k block, per channel "
    "rounded half up as (sum + k*k/2) div (k*k); training uses only this path. Any other size is "
    "scaled bilinearly (the Rust image crate's Triangle filter)."
)


def main(argv):
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--weights", required=True, help="train.py output (.pt)")
    p.add_argument("--out", required=True, help="ONNX path; the card goes beside it as .json")
    args = p.parse_args(argv)
    torch.manual_seed(0)
    ckpt = torch.load(args.weights, map_location="cpu")
    names = ckpt["names"]
    net = Detector(len(names))
    net.load_state_dict(ckpt["state_dict"])
    net.eval()
    width, height = ckpt["input"]
    graph = Exported(net, height, width).eval()
    dummy = torch.zeros(1, 3, height, width)
    torch.onnx.export(
        graph,
        (dummy,),
        args.out,
        input_names=["images"],
        output_names=["detections"],
        opset_version=17,
        dynamo=False,
    )
    with open(os.path.splitext(args.weights)[0] + ".train.json", encoding="utf-8") as f:
        training = json.load(f)
    card = {
        "name": "twincell part detector",
        "classes": names,
        "input_width": width,
        "input_height": height,
        "input_layout": INPUT_LAYOUT,
        "pad_value": PAD_VALUE,
        "output_layout": "[1, cells, 5 + classes]: x0, y0, x1, y1 (input px), objectness, "
        "class probabilities; score = objectness x best class probability",
        "score_threshold": SCORE_THRESHOLD,
        "nms_iou_threshold": NMS_IOU,
        "nms": "class-agnostic",
        "training": {
            "command": training["command"],
            "data": training["data"],
            "seed": training["seed"],
            "threads": training["threads"],
            "torch": training["torch"],
            "seconds": training["seconds"],
            "val_map50": training["val"]["map50"],
        },
    }
    card_path = os.path.splitext(args.out)[0] + ".json"
    if os.path.exists(card_path):
        with open(card_path, encoding="utf-8") as f:
            old = json.load(f)
        if "heldout" in old and old.get("training", {}).get("data") == card["training"]["data"]:
            card["heldout"] = old["heldout"]
    with open(card_path, "w", encoding="utf-8") as f:
        json.dump(card, f, indent=2)
        f.write("\n")
    print(f"wrote {args.out} ({os.path.getsize(args.out)} bytes) and {card_path}")


if __name__ == "__main__":
    main(sys.argv[1:])
