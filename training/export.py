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


# What the training and held-out images are drawn over (src/render/family.rs,
# src/scenario/camera_sections.rs CAMERA_ENVELOPE; training/make_data.sh).
DATA_ENVELOPE = {
    "camera": {
        "tilt_deg": [0.0, 35.0],
        "tilt_direction": "any (azimuth 0-360 degrees)",
        "distance_to_pick_station_m": [0.35, 1.2],
        "roll_deg": [-180.0, 180.0],
        "horizontal_fov_deg": [35.0, 80.0],
        "detector_frame_px": [640, 480],
    },
    "tubes": {
        "bore_mm": [8.0, 90.0],
        "outer_to_bore": [1.15, 3.0],
        "height_mm": [30.0, 120.0],
        "finish": "steel, end-face albedo 0.45-0.85, specular 0.08-0.5, shininess 8-48",
        "max_roundness_mm": 0.3,
        "per_image": [1, 3],
        "smallest_face_px": "outer diameter at least 20 px of the 640 px frame",
        "face_in_view": "at least half of the end face; in half of the images a bottle is set "
        "down between a tube and the camera, leaving 0.5-0.9 of its end face in view",
    },
    "foreign": "the scenarios' bottles, 1-3 a cell, standing or lying (the clutter cell's: one "
    "0-10 mm from the first tube, half of them lying)",
    "cells": [
        "scenarios/paper_50.toml",
        "scenarios/suite/catalogue_b.toml",
        "scenarios/suite/clutter.toml",
    ],
    "sensor": ["each scenario's own", "harsh (make_data.sh HARSH)"],
}


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
        "name": "twincell tube detector",
        "classes": names,
        "finds": "tube: a tube's end face (any tube of the family below); foreign: a bottle or "
        "other foreign object. The part's type is named by measurement, not by the detector.",
        "data_envelope": DATA_ENVELOPE,
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
            "device": training.get("device", "cpu"),
            "epochs_run": training.get("epochs_run"),
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
