"""Sun-sensor centroids: accuracy against the synthetic frames' truth, and throughput.

Frames like the sun-vector paper's camera (1280 x 1024 px, 23 x 17 deg; the sun a
limb-darkened disk 29 px across, 32 px tall), 12-bit detector with shot and read noise,
20 hot pixels a frame (pointax.sunsensor.frames). For each case, the RMS and largest
error (px, 2-D) of the intensity centroid, the limb fit and the method ``auto`` picks,
and the fraction of frames that got a centre:

* unclipped, realistic noise (disk centre at 70 % of full scale);
* saturated disks (centre at 1.5x and 3x full scale);
* thin cloud (optical depth 0.3) and an 8-bit detector;
* clipped by the frame edge: 80-100 %, 60-80 % and 40-60 % of the limb inside the
  frame, and clipped and saturated (60-80 %).

Throughput: frames per second of ``centroid`` on batches of 32 uint16 frames on the
CPU with torch using 2 threads (and 1), from the arrays in memory (validation,
conversion and everything after).

Prints a table and writes benchmarks/results/centroid.json (``--quick``:
centroid_quick.json, fewer frames, under a minute).

    .venv/bin/python benchmarks/centroid.py [--quick]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import kornia
import numpy as np
import torch

from pointax.sunsensor import (
    PAPER_ASPECT,
    PAPER_SUN_RADIUS_PX,
    Detector,
    centroid,
    synthetic_frames,
)

HERE = Path(__file__).resolve().parent
R = PAPER_SUN_RADIUS_PX
OPTIONS = dict(aspect=PAPER_ASPECT, saturation=4095)


def clipped_x(rng, n, lo, hi):
    """Centre x (near the left edge) giving a visible limb fraction in [lo, hi]: the
    fraction inside is 1 - acos(d / R) / pi for a centre d = x + 0.5 inside the edge."""
    frac = rng.uniform(lo, hi, n)
    return -0.5 + R * np.cos(np.pi * (1 - frac))


CASES = {
    # name: (frame options, how x is drawn)
    "unclipped": ({}, "free"),
    "saturated 1.5x": ({"level": 1.5}, "free"),
    "saturated 3x": ({"level": 3.0}, "free"),
    "thin cloud (tau 0.3)": ({"cloud": 0.3}, "free"),
    "8-bit detector": ({"detector": Detector(bits=8, gain=40.0, read_noise=8.0, bias=2.0)}, "free"),
    "clipped, 80-100% limb": ({}, (0.8, 0.999)),
    "clipped, 60-80% limb": ({}, (0.6, 0.8)),
    "clipped, 40-60% limb": ({}, (0.42, 0.6)),
    "clipped 60-80%, saturated 3x": ({"level": 3.0}, (0.6, 0.8)),
}


def accuracy(n: int, seed: int = 0) -> dict:
    rng = np.random.default_rng(seed)
    out = {}
    for name, (options, where) in CASES.items():
        y = rng.uniform(60, 964, n)
        x = rng.uniform(60, 1220, n) if where == "free" else clipped_x(rng, n, *where)
        frames = synthetic_frames(x, y, hot_pixels=20, seed=int(rng.integers(1 << 30)), **options)
        saturation = 255 if "detector" in options else 4095
        found = centroid(frames.images, aspect=PAPER_ASPECT, saturation=saturation)
        truth = np.stack([frames.x, frames.y], axis=1)

        def stats(xy):
            err = np.hypot(*(xy - truth).T)
            err = err[np.isfinite(err)]
            if err.size == 0:
                return {"rms_px": None, "max_px": None}
            return {"rms_px": float(np.sqrt(np.mean(err**2))), "max_px": float(err.max())}

        ok = found.ok
        out[name] = {
            "frames": n,
            "ok_fraction": float(ok.mean()),
            "statuses": {s: found.status.count(s) for s in sorted(set(found.status))},
            "methods": {m: found.method.count(m) for m in sorted(set(found.method)) if m},
            "visible_limb": [float(frames.visible.min()), float(frames.visible.max())],
            "intensity": stats(np.where(ok[:, None], found.intensity, np.nan)),
            "limb": stats(np.where(ok[:, None], found.limb, np.nan)),
            "auto": stats(found.xy),
            "radius_px": float(np.nanmean(found.radius)),
        }
    return out


def throughput(threads: int, batches: int, batch: int = 32) -> dict:
    torch.set_num_threads(threads)
    rng = np.random.default_rng(1)
    frames = synthetic_frames(rng.uniform(60, 1220, batch), rng.uniform(60, 964, batch), hot_pixels=20, seed=2)
    centroid(frames.images[:4], **OPTIONS)  # warm up
    times = []
    for _ in range(batches):
        start = time.perf_counter()
        centroid(frames.images, **OPTIONS)
        times.append(time.perf_counter() - start)
    best, median = min(times), float(np.median(times))
    return {"threads": threads, "batch": batch, "frames_per_s_best": batch / best, "frames_per_s_median": batch / median}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer frames (under a minute)")
    args = parser.parse_args()
    n = 16 if args.quick else 128
    torch.set_num_threads(2)
    start = time.perf_counter()
    acc = accuracy(n)
    speed = [throughput(2, 2 if args.quick else 8), throughput(1, 2 if args.quick else 5)]
    torch.set_num_threads(2)
    result = {
        "quick": args.quick,
        "camera": "1280 x 1024 px, 23 x 17 deg; sun radius 14.55 px (x), aspect fy/fx 1.089",
        "accuracy": acc,
        "throughput": speed,
        "environment": {
            "torch": torch.__version__,
            "kornia": kornia.__version__,
            "cpu_count": os.cpu_count(),
            "load_average": os.getloadavg(),
            "machine": platform.machine(),
        },
        "seconds": time.perf_counter() - start,
    }

    def cell(d):
        return f"{d['rms_px']:8.4f} {d['max_px']:7.4f}" if d["rms_px"] is not None else f"{'-':>8s} {'-':>7s}"

    print(f"Centroid accuracy on synthetic frames, {n} frames a case (px, RMS and largest 2-D error)\n")
    print(f"  {'case':<30s} {'intensity':>16s} {'limb fit':>16s} {'auto':>16s}  ok   method")
    for name, d in acc.items():
        methods = ",".join(f"{m}:{c}" for m, c in d["methods"].items())
        print(f"  {name:<30s} {cell(d['intensity'])} {cell(d['limb'])} {cell(d['auto'])} {100 * d['ok_fraction']:4.0f}%  {methods}")
    print("\n  (auto: the intensity centroid unless the disk is clipped, then the limb fit;")
    print("   the intensity centroid of a clipped disk is biased and never returned)")
    print("\nThroughput, batches of 32 frames of 1280 x 1024 uint16 on the CPU:")
    for s in speed:
        print(f"  torch threads {s['threads']}: {s['frames_per_s_median']:6.1f} frames/s (median), {s['frames_per_s_best']:6.1f} (best)")
    print(f"  (load average at the end: {', '.join(f'{v:.1f}' for v in os.getloadavg())} on {os.cpu_count()} cores)")
    out = HERE / "results" / ("centroid_quick.json" if args.quick else "centroid.json")
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(result, indent=1))
    print(f"\nwrote {out.relative_to(HERE.parent)} ({result['seconds']:.0f} s)")


if __name__ == "__main__":
    main()
