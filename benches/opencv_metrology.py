#!/usr/bin/env python3
"""Times OpenCV's equivalents of the metrology stages on the frames `cargo bench --bench metrology`
writes (target/metrology-frames/), one thread, summed over the timed frames (timed_NN.png): the
median and the minimum of 200 calls each. It also measures the roundness bias of OpenCV's classic
pipeline (median -> adaptive threshold -> findContours -> least-squares circle on integer contour
points -> Rmax - Rmin of those points) against the truth sidecars.

Usage: `cargo bench --bench metrology` runs it (see that file for the Python it picks); by hand:
       pip install opencv-python-headless numpy; cargo bench --bench metrology;
       python3 benches/opencv_metrology.py [--json]
"""
import glob
import json
import os
import sys
import time

import cv2
import numpy as np

FRAMES = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "target", "metrology-frames")
# The same parameters as twincell's default detector: 3x3 median, adaptive mean over a 41x41
# block asking pixels to be 15 levels brighter than their block (OpenCV's C = -15).
BLOCK = 41
C = -15


def best_ms(fn, repeats=200):
    """Median and minimum of per-call times, ms. On a loaded machine the median still counts the
    calls that other processes interrupted; the minimum is the call that ran alone."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append((time.perf_counter() - t0) * 1e3)
    return float(np.median(times)), float(np.min(times))


def stages(gray):
    med = cv2.medianBlur(gray, 3)
    binary = cv2.adaptiveThreshold(med, 255, cv2.ADAPTIVE_THRESH_MEAN_C, cv2.THRESH_BINARY, BLOCK, C)
    edges = cv2.Canny(binary, 50, 150)
    return med, binary, edges


def time_frame(path):
    gray = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
    med, binary, edges = stages(gray)
    out = {
        "median3": best_ms(lambda: cv2.medianBlur(gray, 3)),
        "adaptive_mean": best_ms(lambda: cv2.adaptiveThreshold(
            med, 255, cv2.ADAPTIVE_THRESH_MEAN_C, cv2.THRESH_BINARY, BLOCK, C)),
        "canny": best_ms(lambda: cv2.Canny(binary, 50, 150)),
        "find_contours": best_ms(lambda: cv2.findContours(edges, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)),
    }

    def chain():
        m, b, e = stages(gray)
        cv2.findContours(e, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)

    out["chain_median_adaptive_canny_contours"] = best_ms(chain)
    return out


def ls_circle(points):
    """Algebraic (Kasa) least-squares circle, then Rmax - Rmin of the points about its centre."""
    x, y = points[:, 0].astype(float), points[:, 1].astype(float)
    a = np.column_stack([x, y, np.ones_like(x)])
    b = -(x * x + y * y)
    d, e, f = np.linalg.lstsq(a, b, rcond=None)[0]
    cx, cy = -d / 2, -e / 2
    r = np.sqrt(cx * cx + cy * cy - f)
    dist = np.hypot(x - cx, y - cy)
    return cx, cy, r, dist.max() - dist.min()


def classic_bias(paths):
    """OpenCV classic pipeline vs truth: mean absolute errors over matched bores."""
    errs = {"centre": [], "radius": [], "roundness": [], "roundness_signed": []}
    truths = found = 0
    for path in paths:
        gray = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
        truth = json.load(open(path + ".truth.json"))["circles"]
        truths += len(truth)
        _, binary, _ = stages(gray)
        contours, hierarchy = cv2.findContours(binary, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)
        circles = []
        for i, c in enumerate(contours):
            if hierarchy[0][i][3] < 0 or len(c) < 40:  # hole borders only
                continue
            circles.append(ls_circle(c[:, 0, :]))
        for t in truth:
            best = min(circles, key=lambda c: np.hypot(c[0] - t["cx"], c[1] - t["cy"]), default=None)
            if best is None or np.hypot(best[0] - t["cx"], best[1] - t["cy"]) > 0.3 * t["r"]:
                continue
            found += 1
            errs["centre"].append(np.hypot(best[0] - t["cx"], best[1] - t["cy"]))
            errs["radius"].append(abs(best[2] - t["r"]))
            errs["roundness"].append(abs(best[3] - t["roundness"]))
            errs["roundness_signed"].append(best[3] - t["roundness"])
    return {"truths": truths, "found": found, **{k + "_err_px": float(np.mean(v)) for k, v in errs.items()}}


def time_frames(paths):
    """Stage and chain times summed over the timed frames: medians, then minima."""
    medians, minima = {}, {}
    for path in paths:
        for stage, (median, minimum) in time_frame(path).items():
            medians[stage] = medians.get(stage, 0.0) + median
            minima[stage] = minima.get(stage, 0.0) + minimum
    return medians, minima


def main():
    cv2.setNumThreads(1)
    report = {"opencv": cv2.__version__, "threads": cv2.getNumThreads(), "sizes": {}}
    for size in ("640x480", "1280x960"):
        d = os.path.join(FRAMES, size)
        timed = sorted(glob.glob(os.path.join(d, "timed_*.png")))
        if not timed:
            sys.exit(f"{d}/timed_*.png: missing; run `cargo bench --bench metrology` first")
        medians, minima = time_frames(timed)
        report["sizes"][size] = {
            "frames": len(timed),
            "timing_ms": medians,
            "timing_min_ms": minima,
            "classic_accuracy": classic_bias(sorted(glob.glob(os.path.join(d, "scene_*.png")))),
        }
    if "--json" in sys.argv:
        print(json.dumps(report))
        return
    print(f"OpenCV {report['opencv']}, {report['threads']} thread")
    for size, r in report["sizes"].items():
        print(size)
        for k, v in r["timing_ms"].items():
            print(f"  {k:<40} {v:8.3f} ms median, {r['timing_min_ms'][k]:8.3f} ms minimum")
        print("  classic pipeline accuracy:", json.dumps(r["classic_accuracy"]))


if __name__ == "__main__":
    main()
