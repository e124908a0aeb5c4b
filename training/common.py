"""Shared by training, evaluation and export: dataset reading, decoding, NMS and mAP."""

import hashlib
import json
import os
import math
import random
from typing import NamedTuple

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


PAD_VALUE = 114  # grey of the letterbox padding


class Letterbox(NamedTuple):
    """How an image was put into the network input (as src/detect/letterbox.rs does it):
    input = image x scale + offset."""

    scale: float
    offset_x: int
    offset_y: int
    image_width: int
    image_height: int

    def to_input(self, boxes):
        """x0, y0, x1, y1 boxes [k, 4] from image pixels to input pixels."""
        offset = np.array([self.offset_x, self.offset_y] * 2, dtype=np.float32)
        return (boxes * self.scale + offset).astype(np.float32)

    def to_image(self, boxes):
        """x0, y0, x1, y1 boxes [k, 4] from input pixels to image pixels, clipped to the image."""
        offset = np.array([self.offset_x, self.offset_y] * 2, dtype=np.float32)
        limit = np.array([self.image_width, self.image_height] * 2, dtype=np.float32)
        return np.clip((boxes - offset) / self.scale, 0.0, limit)


def fitted_size(w, h, width, height):
    """The size a w x h image takes inside a width x height input, aspect kept: the Rust
    letterbox's f32 arithmetic (round half away from zero)."""
    if (w, h) == (width, height):
        return w, h
    scale = min(np.float32(width) / np.float32(w), np.float32(height) / np.float32(h))

    def fit(side, limit):
        return min(max(math.floor(float(np.float32(side) * scale) + 0.5), 1), limit)

    return fit(w, width), fit(h, height)


def letterbox(image, width, height, pad, label):
    """An image [h, w, 3] uint8 as the network's uint8 input [height, width, 3], and the
    `Letterbox` used. The image shrinks by a whole factor k (k x k block means, each channel
    rounded half up: (sum + k*k/2) div k*k), then is centred on a `pad`-grey canvas. The Rust
    side does exactly this; for sizes that are no whole multiple of the fitted size it falls back
    to bilinear scaling, which training never uses, so such images are refused here."""
    h, w = image.shape[:2]
    nw, nh = fitted_size(w, h, width, height)
    k = w // nw
    if k * nw != w or k * nh != h:
        raise ValueError(
            f"{label}: a {w}x{h} image fits {width}x{height} as {nw}x{nh}, not a whole "
            "factor smaller; only whole-factor block averaging is implemented here"
        )
    if k > 1:
        sums = image.reshape(nh, k, nw, k, 3).sum((1, 3), dtype=np.uint32)
        image = ((sums + k * k // 2) // (k * k)).astype(np.uint8)
    ox, oy = (width - nw) // 2, (height - nh) // 2
    canvas = np.full((height, width, 3), pad, dtype=np.uint8)
    canvas[oy : oy + nh, ox : ox + nw] = image
    return canvas, Letterbox(nw / w, ox, oy, w, h)


FOREIGN = ("foreign", "bottle")  # the class of foreign objects, by either name


def union_names(data_dirs):
    """The classes of several datasets: every class in order of first appearance, the foreign
    objects' class (`foreign`, or `bottle` in catalogue sets) last. Classes of the same name are
    one class."""
    parts, foreign = [], []
    for d in data_dirs:
        for name in read_names(d):
            group = foreign if name in FOREIGN else parts
            if name not in group:
                group.append(name)
    return parts + foreign


def read_meta(data_dir, split):
    """The label metadata of a family set (`twincell dataset --family`): per image, in the order
    `read_split` reads them, the JSON beside its label file, or None where there is none."""
    label_dir = os.path.join(data_dir, "labels", split)
    image_dir = os.path.join(data_dir, "images", split)
    stems = sorted(f[:-4] for f in os.listdir(image_dir) if f.endswith(".png"))
    metas = []
    for stem in stems:
        path = os.path.join(label_dir, stem + ".json")
        if os.path.exists(path):
            with open(path, encoding="utf-8") as f:
                metas.append(json.load(f))
        else:
            metas.append(None)
    return metas


def class_map(data_dir, names):
    """Maps a dataset's own class ids to their index in `names` (every class must be there)."""
    own = read_names(data_dir)
    missing = [n for n in own if n not in names]
    if missing:
        raise ValueError(f"{data_dir}/data.yaml: classes {missing} are not among {names}")
    return [names.index(n) for n in own]


def project_path(path):
    """`path` as a model card records it: relative to the project root when inside it, as
    `$DATA/...` when inside the directory in the environment's DATA (training/retrain.sh sets
    it), else unchanged."""
    full = os.path.realpath(path)
    root = os.path.realpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
    data = os.environ.get("DATA")
    if full == root or full.startswith(root + os.sep):
        return os.path.relpath(full, root)
    if data:
        data = os.path.realpath(data)
        if full.startswith(data + os.sep):
            return "$DATA/" + os.path.relpath(full, data)
    return path


def read_split(data_dir, split, width, height, pad=PAD_VALUE, classes=None):
    """One split of a dataset directory, letterboxed to the network's width x height:
    (uint8 inputs [N, height, width, 3], boxes per image as float arrays [k, 5] of class, x0, y0,
    x1, y1 in image pixels, the `Letterbox` per image, file paths). With `classes` (a list from
    `class_map`), class ids are mapped through it."""
    image_dir = os.path.join(data_dir, "images", split)
    label_dir = os.path.join(data_dir, "labels", split)
    stems = sorted(f[:-4] for f in os.listdir(image_dir) if f.endswith(".png"))
    inputs, targets, frames, files = [], [], [], []
    for stem in stems:
        path = os.path.join(image_dir, stem + ".png")
        image = np.asarray(Image.open(path).convert("RGB"))
        h, w = image.shape[:2]
        rows = []
        with open(os.path.join(label_dir, stem + ".txt"), encoding="utf-8") as f:
            for n, line in enumerate(f, 1):
                parts = line.split()
                if len(parts) != 5:
                    raise ValueError(f"{label_dir}/{stem}.txt line {n}: expected 5 fields")
                c, cx, cy, bw, bh = int(parts[0]), *map(float, parts[1:])
                if classes is not None:
                    c = classes[c]
                rows.append(
                    [c, (cx - bw / 2) * w, (cy - bh / 2) * h, (cx + bw / 2) * w, (cy + bh / 2) * h]
                )
        canvas, frame = letterbox(image, width, height, pad, path)
        inputs.append(canvas)
        targets.append(np.array(rows, dtype=np.float32).reshape(-1, 5))
        frames.append(frame)
        files.append(path)
    return np.stack(inputs), targets, frames, files


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


def postprocess(rows, score_threshold, iou_threshold, frame):
    """One image's decoded rows [cells, 5 + C] (numpy, input pixels) to detections: list of
    (class, score, box in image pixels through `frame`, a `Letterbox`). Score = objectness x best
    class probability; class-agnostic NMS."""
    cls = rows[:, 5:]
    class_ids = cls.argmax(1)
    scores = rows[:, 4] * cls[np.arange(len(cls)), class_ids]
    mask = scores >= score_threshold
    boxes, scores, class_ids = rows[mask, :4], scores[mask], class_ids[mask]
    keep = nms(boxes, scores, iou_threshold)
    boxes = frame.to_image(boxes)
    return [(int(class_ids[k]), float(scores[k]), boxes[k]) for k in keep]


@torch.no_grad()
def predict(net, images, batch=8):
    """Decoded rows [N, cells, 5 + C] (input pixels) for uint8 inputs [N, H, W, 3]."""
    net.eval()
    device = next(net.parameters()).device
    out = []
    for i in range(0, len(images), batch):
        raw, centres, strides = flatten(net(to_tensor(images[i : i + batch]).to(device)))
        boxes = decode_boxes(raw, centres, strides)
        out.append(torch.cat((boxes, torch.sigmoid(raw[..., 4:])), -1).cpu().numpy())
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
    targets: per image, array [k, 5] of class, x0, y0, x1, y1 (same pixels as the boxes)."""
    bottle = next((names.index(n) for n in FOREIGN if n in names), -1)
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
    # Over the classes the sets hold: a set from one part catalogue leaves the other's out.
    m = float(np.mean([v["ap50"] for v in per_class.values() if v["truths"]]))
    return {"map50": m, "per_class": per_class, "bottle_as_part": bottle_as_part}


def write_json(path, obj):
    with open(path, "w", encoding="utf-8") as f:
        json.dump(obj, f, indent=2, sort_keys=True)
        f.write("\n")
