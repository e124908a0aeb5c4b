"""Trains the part detector from scratch on `twincell dataset` output.

Seeded and single-process with a fixed thread count, so the same command on the same data gives
the same weights. Recipe after the paper's: Adam, cosine learning-rate decay, Gaussian-noise and
random-colour augmentation; plus flips. Every image is letterboxed to the network input exactly
as the Rust side does it (common.letterbox: a 640x480 render halves to 320x240 by 2x2 block
means and is centred on a 320x256 grey canvas), so training sees what inference sees; no other
rescaling, as the parts' apparent size is what tells neighbouring types apart. Records the command, the data's
digest and per-epoch metrics to NAME.train.json next to the weights NAME.pt.
"""

import argparse
import math
import os
import sys
import time

import numpy as np
import torch
import torch.nn.functional as F

import common
from model import Detector, STRIDES, decode_boxes, flatten

# Box sizes (longest side, input px) each level learns; overlapping so no object falls between.
# At the 320x256 input parts are 26-67 px and bottles up to 88 px.
LEVEL_RANGES = {8: (0, 56), 16: (32, 112), 32: (80, 1e9)}
CENTRE_RADIUS = 2.5  # positives: cells within this many strides of the box centre, inside the box


def parse_args(argv):
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--data", nargs="+", required=True, help="dataset directories (data.yaml)")
    p.add_argument("--out", required=True, help="output .pt path; the record goes to .train.json beside")
    p.add_argument("--epochs", type=int, default=30)
    p.add_argument("--batch", type=int, default=16)
    p.add_argument("--lr", type=float, default=3e-3)
    p.add_argument(
        "--input", type=int, nargs=2, default=[320, 256], metavar=("W", "H"),
        help="network input size; each side must divide by 32",
    )
    p.add_argument("--seed", type=int, default=6)
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--limit", type=int, default=0, help="use only the first N training images")
    p.add_argument("--eval-every", type=int, default=5, help="epochs between val mAP checks")
    p.add_argument(
        "--deadline-s", type=float, default=0.0,
        help="stop after the epoch that ends past this many seconds of training (0: never); "
        "the record says how many epochs ran",
    )
    p.add_argument(
        "--device", default="cpu",
        help="torch device; `cpu` (the documented, bit-reproducible run) or e.g. `cuda`, where "
        "the augmentation noise is drawn on the device from the same seed (a different stream)",
    )
    return p.parse_args(argv)


def augment(batch, rng, noise_gen=None):
    """Random colour (per-channel gain, brightness, contrast) and Gaussian noise; float 0..1.
    The noise comes from `rng` (numpy) or, given `noise_gen`, a torch generator on the batch's
    device."""
    n = batch.shape[0]
    dev = batch.device
    gain = torch.from_numpy(rng.uniform(0.8, 1.2, (n, 3, 1, 1)).astype(np.float32)).to(dev)
    bright = torch.from_numpy(rng.uniform(-0.1, 0.1, (n, 1, 1, 1)).astype(np.float32)).to(dev)
    contrast = torch.from_numpy(rng.uniform(0.7, 1.3, (n, 1, 1, 1)).astype(np.float32)).to(dev)
    mean = batch.mean((1, 2, 3), keepdim=True)
    x = (batch * gain - mean) * contrast + mean + bright
    sigma = torch.from_numpy(rng.uniform(0.0, 10.0 / 255.0, (n, 1, 1, 1)).astype(np.float32)).to(dev)
    if noise_gen is None:
        noise = torch.from_numpy(rng.standard_normal(x.shape).astype(np.float32))
    else:
        noise = torch.randn(x.shape, generator=noise_gen, device=dev)
    return (x + sigma * noise).clamp(0.0, 1.0)


def flip(image, boxes, horizontal):
    h, w = image.shape[:2]
    out = boxes.copy()
    if horizontal:
        image = image[:, ::-1]
        out[:, [1, 3]] = w - boxes[:, [3, 1]]
    else:
        image = image[::-1]
        out[:, [2, 4]] = h - boxes[:, [4, 2]]
    return image, out


def assign(targets, centres, strides, num_classes):
    """Per cell: positive mask, class target, box target. targets: list of [k, 5]."""
    n, cells = len(targets), len(centres)
    pos = torch.zeros(n, cells, dtype=torch.bool)
    cls_t = torch.zeros(n, cells, num_classes)
    box_t = torch.zeros(n, cells, 4)
    best_area = torch.full((n, cells), float("inf"))
    cx, cy = centres[:, 0], centres[:, 1]
    for i, t in enumerate(targets):
        for c, x0, y0, x1, y1 in t.tolist():
            inside = (cx > x0) & (cx < x1) & (cy > y0) & (cy < y1)
            side = max(x1 - x0, y1 - y0)
            bx, by = (x0 + x1) / 2, (y0 + y1) / 2
            level_ok = torch.zeros(cells, dtype=torch.bool)
            for s, (lo, hi) in LEVEL_RANGES.items():
                if lo <= side <= hi:
                    level_ok |= strides == s
            near = ((cx - bx).abs() < CENTRE_RADIUS * strides) & (
                (cy - by).abs() < CENTRE_RADIUS * strides
            )
            area = (x1 - x0) * (y1 - y0)
            m = inside & near & level_ok & (area < best_area[i])
            best_area[i][m] = area
            pos[i] |= m
            cls_t[i][m] = 0.0
            cls_t[i][m, int(c)] = 1.0
            box_t[i][m] = torch.tensor([x0, y0, x1, y1])
    return pos, cls_t, box_t


def giou(a, b):
    lt = torch.max(a[:, :2], b[:, :2])
    rb = torch.min(a[:, 2:], b[:, 2:])
    inter = (rb - lt).clamp(min=0).prod(1)
    area_a = (a[:, 2:] - a[:, :2]).clamp(min=0).prod(1)
    area_b = (b[:, 2:] - b[:, :2]).clamp(min=0).prod(1)
    union = area_a + area_b - inter + 1e-7
    iou = inter / union
    hull = (torch.max(a[:, 2:], b[:, 2:]) - torch.min(a[:, :2], b[:, :2])).prod(1) + 1e-7
    return iou - (hull - union) / hull


def loss_fn(maps, targets, num_classes):
    raw, centres, strides = flatten(maps)
    pos, cls_t, box_t = assign(targets, centres.cpu(), strides.cpu(), num_classes)
    dev = raw.device
    pos, cls_t, box_t = pos.to(dev), cls_t.to(dev), box_t.to(dev)
    n_pos = max(int(pos.sum()), 1)
    boxes = decode_boxes(raw, centres, strides)
    obj = F.binary_cross_entropy_with_logits(raw[..., 4], pos.float(), reduction="sum")
    if pos.any():
        g = giou(boxes[pos], box_t[pos])
        box = (1.0 - g).sum()
        cls = F.binary_cross_entropy_with_logits(raw[..., 5:][pos], cls_t[pos], reduction="sum")
    else:
        box = cls = raw.sum() * 0.0
    return (5.0 * box + obj + cls) / n_pos, {
        "box": float(box.detach()) / n_pos,
        "obj": float(obj.detach()) / n_pos,
        "cls": float(cls.detach()) / n_pos,
    }


def validate(net, images, frames, targets, names):
    """Metrics on the validation inputs, boxes compared in image pixels."""
    rows = common.predict(net, images)
    dets = [common.postprocess(r, 0.01, 0.5, f) for r, f in zip(rows, frames)]
    return common.evaluate(dets, targets, names, 0.5)


def main(argv):
    args = parse_args(argv)
    common.seed_everything(args.seed, args.threads)
    rng = np.random.default_rng(args.seed)
    # Sets rendered from different part catalogues train one detector over all their types.
    names = common.union_names(args.data)
    width, height = args.input
    if width % STRIDES[-1] or height % STRIDES[-1]:
        raise ValueError(f"--input {width} {height}: each side must divide by {STRIDES[-1]}")
    train_images, train_targets, val_images, val_targets, val_frames, files = [], [], [], [], [], []
    for d in args.data:
        classes = common.class_map(d, names)
        imgs, tgts, frames, paths = common.read_split(d, "train", width, height, classes=classes)
        train_images.append(imgs)
        # Training targets live in input pixels.
        train_targets += [
            np.concatenate((t[:, :1], f.to_input(t[:, 1:])), 1) for t, f in zip(tgts, frames)
        ]
        files += paths
        imgs, tgts, frames, _ = common.read_split(d, "val", width, height, classes=classes)
        val_images.append(imgs)
        val_targets += tgts
        val_frames += frames
    train_images = np.concatenate(train_images)
    val_images = np.concatenate(val_images)
    if args.limit:
        train_images, train_targets = train_images[: args.limit], train_targets[: args.limit]
        files = files[: args.limit]
    print(f"train {len(train_images)} images, val {len(val_images)}, classes {names}", flush=True)

    device = torch.device(args.device)
    noise_gen = None
    if device.type != "cpu":
        # Some CUDA kernels (upsampling's backward) have no deterministic form: warn, not fail.
        torch.use_deterministic_algorithms(True, warn_only=True)
        noise_gen = torch.Generator(device=device)
        noise_gen.manual_seed(args.seed)
    net = Detector(len(names)).to(device)
    opt = torch.optim.Adam(net.parameters(), lr=args.lr, weight_decay=0.0)
    steps_per_epoch = len(train_images) // args.batch
    total = steps_per_epoch * args.epochs
    warmup = min(steps_per_epoch, total // 10)

    def lr_at(step):
        if step < warmup:
            return args.lr * (step + 1) / warmup
        t = (step - warmup) / max(total - warmup, 1)
        return args.lr * (0.02 + 0.98 * 0.5 * (1 + math.cos(math.pi * t)))

    history = []
    start = time.time()
    step = 0
    for epoch in range(args.epochs):
        net.train()
        order = rng.permutation(len(train_images))
        sums = {"loss": 0.0, "box": 0.0, "obj": 0.0, "cls": 0.0}
        for b in range(steps_per_epoch):
            inputs, targets = [], []
            for k in order[b * args.batch : (b + 1) * args.batch]:
                image, boxes = train_images[k], train_targets[k]
                if rng.random() < 0.5:
                    image, boxes = flip(image, boxes, True)
                if rng.random() < 0.5:
                    image, boxes = flip(image, boxes, False)
                inputs.append(np.ascontiguousarray(image))
                targets.append(boxes)
            x = augment(common.to_tensor(np.stack(inputs)).to(device), rng, noise_gen)
            for g in opt.param_groups:
                g["lr"] = lr_at(step)
            loss, parts = loss_fn(net(x), targets, len(names))
            opt.zero_grad()
            loss.backward()
            torch.nn.utils.clip_grad_norm_(net.parameters(), 10.0)
            opt.step()
            step += 1
            sums["loss"] += float(loss.detach())
            for key, v in parts.items():
                sums[key] += v
        row = {k: v / steps_per_epoch for k, v in sums.items()}
        row["epoch"] = epoch + 1
        row["seconds"] = round(time.time() - start, 1)
        if (epoch + 1) % args.eval_every == 0 or epoch + 1 == args.epochs:
            row["val_map50"] = validate(net, val_images, val_frames, val_targets, names)["map50"]
        history.append(row)
        if args.deadline_s and time.time() - start > args.deadline_s and epoch + 1 < args.epochs:
            row["stopped"] = f"deadline: stopped after epoch {epoch + 1} of {args.epochs}"
            print(row["stopped"], flush=True)
            break
        print(" ".join(f"{k}={v:.4f}" if isinstance(v, float) else f"{k}={v}" for k, v in row.items()), flush=True)

    # The record names paths relative to the project (or to $DATA), never this machine's.
    command, path_args = [], False
    for a in argv:
        if a.startswith("--"):
            path_args = a in ("--data", "--out")
            command.append(a)
        else:
            command.append(common.project_path(a) if path_args else a)
    torch.save(
        {
            "state_dict": {k: v.cpu() for k, v in net.state_dict().items()},
            "names": names,
            "input": [width, height],
        },
        args.out,
    )
    val = validate(net, val_images, val_frames, val_targets, names)
    common.write_json(
        os.path.splitext(args.out)[0] + ".train.json",
        {
            "command": ["python", "training/train.py", *command],
            "data": {
                "dirs": [common.project_path(d) for d in args.data],
                "train_images": len(train_images),
                "val_images": len(val_images),
                "train_digest_sha256": common.digest(files),
            },
            "torch": torch.__version__,
            "device": torch.cuda.get_device_name(device) if device.type == "cuda" else "cpu",
            "seed": args.seed,
            "threads": args.threads,
            "seconds": round(time.time() - start, 1),
            "epochs_run": len(history),
            "history": history,
            "val": val,
        },
    )
    print(f"val mAP@0.5 {val['map50']:.4f}; wrote {args.out}", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
