"""Scores the exported detector (through ONNX Runtime, as shipped) on held-out sets.

mAP@0.5 over the classes, per-class AP, precision and recall at the card's operating threshold,
and the count of bottles reported as a part at that threshold. Images are letterboxed as the Rust side does it
(common.letterbox) and boxes are compared in image pixels. Held-out sets are rendered by
make_data.sh with seeds never used in training (both splits of each set are used). Writes the
metrics into the model card under "heldout" and prints them.
"""

import argparse
import json
import os
import sys
import time

import numpy as np
import onnxruntime as ort

import common


def main(argv):
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--model", required=True, help="ONNX file (card beside it)")
    p.add_argument("--data", nargs="+", required=True, help="held-out dataset directories")
    p.add_argument("--no-write", action="store_true", help="do not update the model card")
    args = p.parse_args(argv)
    card_path = os.path.splitext(args.model)[0] + ".json"
    with open(card_path, encoding="utf-8") as f:
        card = json.load(f)
    names = card["classes"]
    opts = ort.SessionOptions()
    opts.intra_op_num_threads = 1
    session = ort.InferenceSession(args.model, opts, providers=["CPUExecutionProvider"])
    detections, targets, sets = [], [], []
    start = time.time()
    for d in args.data:
        # A set from one part catalogue holds a subset of the card's classes.
        classes = common.class_map(d, names)
        n = 0
        for split in ("train", "val"):
            images, tgts, frames, _ = common.read_split(
                d, split, card["input_width"], card["input_height"], card["pad_value"], classes
            )
            for image, t, frame in zip(images, tgts, frames):
                x = common.to_tensor(image[None]).numpy()
                rows = session.run(None, {"images": x})[0][0]
                detections.append(
                    common.postprocess(rows, 0.01, card["nms_iou_threshold"], frame)
                )
                targets.append(t)
                n += 1
        sets.append({"dir": os.path.basename(os.path.normpath(d)), "images": n})
    metrics = common.evaluate(detections, targets, names, card["score_threshold"])
    metrics["sets"] = sets
    metrics["images"] = len(targets)
    metrics["score_threshold"] = card["score_threshold"]
    print(f"held-out images {len(targets)} ({time.time() - start:.0f} s)")
    print(f"mAP@0.5 {metrics['map50']:.4f}; bottles reported as parts: {metrics['bottle_as_part']}")
    print(f"{'class':<10} {'AP50':>6} {'P':>6} {'R':>6} {'truths':>6}")
    for name, m in metrics["per_class"].items():
        print(
            f"{name:<10} {m['ap50']:6.3f} {m['precision']:6.3f} {m['recall']:6.3f} {m['truths']:6d}"
        )
    if not args.no_write:
        card["heldout"] = metrics
        with open(card_path, "w", encoding="utf-8") as f:
            json.dump(card, f, indent=2)
            f.write("\n")
        print(f"wrote held-out metrics to {card_path}")


if __name__ == "__main__":
    main(sys.argv[1:])
