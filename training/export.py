"""Exports trained weights to the shipped ONNX graph and writes its model card.

The graph takes [1, 3, H, W] RGB in 0..1 (H x W = 480 x 640, the camera's detector resolution)
and returns [1, cells, 5 + classes]: x0, y0, x1, y1 in input pixels, objectness, class
probabilities. The card (same stem, .json) holds what inference needs (classes, input size,
padding, operating threshold, NMS IoU) plus the training record and, once evaluate.py has run,
the held-out metrics.
"""

import argparse
import json
import os
import sys

import torch

from model import Detector, Exported

INPUT_H, INPUT_W = 480, 640
PAD_VALUE = 114
SCORE_THRESHOLD = 0.5
NMS_IOU = 0.5


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
    graph = Exported(net, INPUT_H, INPUT_W).eval()
    dummy = torch.zeros(1, 3, INPUT_H, INPUT_W)
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
        "input_width": INPUT_W,
        "input_height": INPUT_H,
        "input_layout": "NCHW float32 RGB in 0..1, letterboxed (aspect kept, centred)",
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
