"""Scores the exported detector (through ONNX Runtime, as shipped) on held-out sets.

mAP@0.5 over the classes, per-class AP, precision and recall at the card's operating threshold,
and the count of bottles reported as a part at that threshold. On family sets (`twincell dataset
--family`, whose label metadata records each image's camera and each tube's size) also mAP@0.5
per camera tilt band and the tubes' AP per bore-size band. Images are letterboxed as the Rust side does it
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

TILT_BANDS = ((0.0, 10.0), (10.0, 20.0), (20.0, 30.0), (30.0, 35.0))
BORE_BANDS_MM = ((8.0, 16.0), (16.0, 32.0), (32.0, 64.0), (64.0, 90.0))
# Share of the end face in view: partly hidden by a bottle, or in the clear.
VISIBLE_BANDS = ((0.5, 0.9), (0.9, 1.0))


def in_band(value, band, last):
    """Half-open bands, the last one closed."""
    low, high = band
    return low <= value < high or (last and value == high)


def face_visible(obj, meta):
    """The share of a tube's end face the camera sees past the bottles, from the label metadata
    (1 for sets rendered before it was recorded)."""
    for t in meta.get("tubes", []):
        if t.get("position_m") == obj.get("position_m"):
            return t.get("face_visible", 1.0)
    return 1.0


def tube_subset(detections, targets, metas, tube, names, threshold, keep_tube):
    """The tube class's AP and recall over the tubes `keep_tube(object, meta)` keeps (the other
    tubes ignored: their truths dropped, and the detections that hit them); None when none is
    kept."""
    dets_b, tgts_b, truths = [], [], 0
    for dets, t, m in zip(detections, targets, metas):
        if not m:
            continue
        keep = np.ones(len(t), dtype=bool)
        for j, o in enumerate(m["objects"]):
            if int(t[j, 0]) == tube:
                keep[j] = keep_tube(o, m)
        others = t[~keep]
        kept_dets = []
        for det in dets:
            if det[0] == tube and len(others):
                ious = common.box_iou(det[2][None], others[:, 1:])[0]
                if ious.max() >= 0.5:
                    continue
            kept_dets.append(det)
        dets_b.append(kept_dets)
        tgts_b.append(t[keep])
        truths += int((t[keep][:, 0] == tube).sum())
    if not truths:
        return None
    r = common.evaluate(dets_b, tgts_b, names, threshold)
    return {
        "tube_ap50": r["per_class"][names[tube]]["ap50"],
        "tubes": truths,
        "recall": r["per_class"][names[tube]]["recall"],
    }


def band_metrics(detections, targets, metas, names, threshold):
    """mAP@0.5 per tilt band (whole images), and the tube class's AP per bore band and per band
    of the end face's share in view (a bottle in front)."""
    tilt, bore, visible = {}, {}, {}
    tube = names.index("tube") if "tube" in names else 0
    for i, band in enumerate(TILT_BANDS):
        idx = [
            k
            for k, m in enumerate(metas)
            if m and in_band(m["camera"]["tilt_deg"], band, i == len(TILT_BANDS) - 1)
        ]
        if idx:
            r = common.evaluate([detections[k] for k in idx], [targets[k] for k in idx], names, threshold)
            tilt[f"{band[0]:g}-{band[1]:g}"] = {
                "map50": r["map50"],
                "images": len(idx),
                "per_class_ap50": {n: v["ap50"] for n, v in r["per_class"].items()},
                "bottle_as_part": r["bottle_as_part"],
            }
    for i, band in enumerate(BORE_BANDS_MM):
        last = i == len(BORE_BANDS_MM) - 1
        r = tube_subset(
            detections, targets, metas, tube, names, threshold,
            lambda o, m, band=band, last=last: in_band(2.0 * o["bore"]["radius_mm"], band, last),
        )
        if r:
            bore[f"{band[0]:g}-{band[1]:g}"] = r
    for i, band in enumerate(VISIBLE_BANDS):
        last = i == len(VISIBLE_BANDS) - 1
        r = tube_subset(
            detections, targets, metas, tube, names, threshold,
            lambda o, m, band=band, last=last: in_band(face_visible(o, m), band, last),
        )
        if r:
            visible[f"{band[0]:g}-{band[1]:g}"] = r
    return tilt, bore, visible


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
    detections, targets, sets, metas = [], [], [], []
    start = time.time()
    for d in args.data:
        # A set from one part catalogue holds a subset of the card's classes.
        classes = common.class_map(d, names)
        n = 0
        for split in ("train", "val"):
            images, tgts, frames, _ = common.read_split(
                d, split, card["input_width"], card["input_height"], card["pad_value"], classes
            )
            metas.extend(common.read_meta(d, split))
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
    if any(metas):
        tilt, bore, visible = band_metrics(
            detections, targets, metas, names, card["score_threshold"]
        )
        metrics["per_tilt_band_deg"] = tilt
        metrics["per_bore_band_mm"] = bore
        metrics["per_face_visible_band"] = visible
    metrics["sets"] = sets
    metrics["images"] = len(targets)
    metrics["score_threshold"] = card["score_threshold"]
    print(f"held-out images {len(targets)} ({time.time() - start:.0f} s)")
    print(f"mAP@0.5 {metrics['map50']:.4f}; bottles reported as parts: {metrics['bottle_as_part']}")
    for band, m in metrics.get("per_tilt_band_deg", {}).items():
        print(f"tilt {band:>6} deg: mAP@0.5 {m['map50']:.4f} over {m['images']} images")
    for band, m in metrics.get("per_bore_band_mm", {}).items():
        print(f"bore {band:>6} mm: tube AP50 {m['tube_ap50']:.4f}, recall {m['recall']:.4f}, {m['tubes']} tubes")
    for band, m in metrics.get("per_face_visible_band", {}).items():
        print(f"face in view {band:>7}: tube AP50 {m['tube_ap50']:.4f}, recall {m['recall']:.4f}, {m['tubes']} tubes")
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
