"""Shared by training, evaluation and export: dataset reading, decoding, NMS and mAP."""

import hashlib
import json
import os
import random

import numpy as np
import torch
from PIL import Image

from model import decode_boxes, flatten


def read_names(data_dir):
    """Class names from a `twincell dataset` data.yaml, in class-id order."""
    names = {}
    in_names = False
    with open(os.path.join(data_dir, "data.yaml"), encoding="utf-8") as f:
        for line in f:
            if line.startswith("names:"):
                in_names = True
            elif in_names and line.startswith("  ") and ":" in line:
                key, value = line.strip().split(":", 1)
                names[int(key)] = value.strip()
            elif in_names:
                in_names = False
    if not names:
        raise ValueError(f"{data_dir}/data.yaml: no `names:` list")
    return [names[i] for i in range(len(names))]


def read_split(data_dir, split):
    """(uint8 images [N, H, W, 3], boxes per image as float arrays [k, 5] of class, x0, y0, x1, y1
    in pixels, file stems) for one split of a dataset directory."""
    image_dir = os.path.join(data_dir, "images", split)
    label_dir = os.path.join(data_dir, "labels", split)
    stems = sorted(f[:-4] for f in os.listdir(image_dir) if f.endswith(".png"))
    images, targets = [], []
    for stem in stems:
        image = np.asarray(Image.open(os.path.join(image_dir, stem + ".png")).convert("RGB"))
        h, w = image.shape[:2]
        rows = []
        with open(os.path.join(label_dir, stem + ".txt"), encoding="utf-8") as f:
            for n, line in enumerate(f, 1):
                parts = line.split()
                if len(parts) != 5:
                    raise ValueError(f"{label_dir}/{stem}.txt line {n}: expected 5 fields")
                c, cx, cy, bw, bh = int(parts[0]), *map(float, parts[1:])
                rows.append(
                    [c, (cx - bw / 2) * w, (cy - bh / 2) * h, (cx + bw / 2) * w, (cy + bh / 2) * h]
                )
        images.append(image)
        targets.append(np.array(rows, dtype=np.float32).reshape(-1, 5))
    return np.stack(images), targets, stems


def digest(paths):
    """SHA-256 over the listed files' bytes, in order: identifies the data a model saw."""
    h = hashlib.sha256()
    for p in paths:
        with open(p, "rb") as f:
            h.update(f.read())
    return h.hexdigest()


def seed_everything(seed, threads):
    """Seeds every generator and pins the thread count so runs repeat bit for bit."""
    random.seed(seed)
    np.random.seed(seed)
    torch.manual_seed(seed)
    torch.set_num_threads(threads)
    torch.use_deterministic_algorithms(True)


def to_tensor(images):
    """uint8 [N, H, W, 3] to float [N, 3, H, W] in 0..1."""
    return torch.from_numpy(np.ascontiguousarray(images)).permute(0, 3, 1, 2).float() / 255.0


def box_iou(a, b):
    """IoU matrix of x0, y0, x1, y1 boxes: a [n, 4], b [m, 4] -> [n, m]."""
    lt = np.maximum(a[:, None, :2], b[None, :, :2])
    rb = np.minimum(a[:, None, 2:], b[None, :, 2:])
    inter = np.clip(rb - lt, 0, None).prod(-1)
    area_a = (a[:, 2:] - a[:, :2]).prod(-1)
    area_b = (b[:, 2:] - b[:, :2]).prod(-1)
    return inter / (area_a[:, None] + area_b[None, :] - inter + 1e-9)


def nms(boxes, scores, iou_threshold):
    """Class-agnostic greedy non-maximum suppression; ties keep the lower index. Returns kept
    indices in descending score order."""
    order = np.lexsort((np.arange(len(scores)), -scores))
    keep = []
    while len(order):
        i = order[0]
        keep.append(i)
        if len(order) == 1:
            break
        ious = box_iou(boxes[i : i + 1], boxes[order[1:]])[0]
        order = order[1:][ious <= iou_threshold]
    return np.array(keep, dtype=np.int64)


def postprocess(rows, score_threshold, iou_threshold):
    """One image's decoded rows [cells, 5 + C] (numpy) to detections: list of (class, score, box).
    Score = objectness x best class probability; class-agnostic NMS."""
    cls = rows[:, 5:]
    class_ids = cls.argmax(1)
    scores = rows[:, 4] * cls[np.arange(len(cls)), class_ids]
    mask = scores >= score_threshold
    boxes, scores, class_ids = rows[mask, :4], scores[mask], class_ids[mask]
    keep = nms(boxes, scores, iou_threshold)
    return [(int(class_ids[k]), float(scores[k]), boxes[k]) for k in keep]


@torch.no_grad()
def predict(net, images, batch=8):
    """Decoded rows [N, cells, 5 + C] for uint8 images [N, H, W, 3]."""
    net.eval()
    out = []
    for i in range(0, len(images), batch):
        raw, centres, strides = flatten(net(to_tensor(images[i : i + batch])))
        boxes = decode_boxes(raw, centres, strides)
        out.append(torch.cat((boxes, torch.sigmoid(raw[..., 4:])), -1).numpy())
    return np.concatenate(out)


def average_precision(recall, precision):
    """Area under the precision envelope (all-point interpolation, as in VOC 2010+)."""
    r = np.concatenate(([0.0], recall, [1.0]))
    p = np.concatenate(([0.0], precision, [0.0]))
    for i in range(len(p) - 2, -1, -1):
        p[i] = max(p[i], p[i + 1])
    idx = np.where(r[1:] != r[:-1])[0]
    return float(np.sum((r[idx + 1] - r[idx]) * p[idx + 1]))


def evaluate(detections, targets, names, operating_threshold, iou_match=0.5):
    """mAP@0.5 over classes, per-class AP, precision and recall at the operating threshold, and
    the count of bottles reported as a part (a part-class detection whose best-IoU ground truth
    is a bottle, IoU >= 0.5) at that threshold.

    detections: per image, list of (class, score, box) from `postprocess` at a low threshold.
    targets: per image, array [k, 5] of class, x0, y0, x1, y1."""
    bottle = names.index("bottle") if "bottle" in names else -1
    per_class = {}
    bottle_as_part = 0
    for c, name in enumerate(names):
        scored = []  # (score, is true positive)
        n_truth = 0
        for dets, truth in zip(detections, targets):
            gt = truth[truth[:, 0] == c][:, 1:]
            n_truth += len(gt)
            used = np.zeros(len(gt), dtype=bool)
            for cls, score, box in sorted(
                (d for d in dets if d[0] == c), key=lambda d: -d[1]
            ):
                tp = False
                if len(gt):
                    ious = box_iou(box[None], gt)[0]
                    j = int(ious.argmax())
                    if ious[j] >= iou_match and not used[j]:
                        used[j] = True
                        tp = True
                scored.append((score, tp))
        scored.sort(key=lambda s: -s[0])
        tps = np.array([s[1] for s in scored], dtype=np.float64)
        ctp = np.cumsum(tps)
        recall = ctp / max(n_truth, 1)
        precision = ctp / np.arange(1, len(tps) + 1)
        ap = average_precision(recall, precision) if len(tps) else 0.0
        at_op = np.array([s[0] >= operating_threshold for s in scored], dtype=bool)
        tp_op = int(tps[at_op].sum()) if len(tps) else 0
        n_op = int(at_op.sum())
        per_class[name] = {
            "ap50": ap,
            "truths": n_truth,
            "precision": tp_op / n_op if n_op else 1.0,
            "recall": tp_op / n_truth if n_truth else 1.0,
            "detections_at_threshold": n_op,
        }
    for dets, truth in zip(detections, targets):
        for cls, score, box in dets:
            if cls == bottle or score < operating_threshold or not len(truth):
                continue
            ious = box_iou(box[None], truth[:, 1:])[0]
            j = int(ious.argmax())
            if ious[j] >= iou_match and int(truth[j, 0]) == bottle:
                bottle_as_part += 1
    m = float(np.mean([v["ap50"] for v in per_class.values()]))
    return {"map50": m, "per_class": per_class, "bottle_as_part": bottle_as_part}


def write_json(path, obj):
    with open(path, "w", encoding="utf-8") as f:
        json.dump(obj, f, indent=2, sort_keys=True)
        f.write("\n")
