"""Seconds per image for landmark description: 100 dense landmarks on a 640x360 image.

Run: ``.venv/bin/python benchmarks/bench_features.py [--repeats 5] [--threads N]``.

Prints, per backbone, the median (and best) wall seconds to encode one 640x360 image with 100 dense
landmarks (4 scales x 5x5 grid), the raw and output dims, and the ratio to the 0.5 s/image target
of the default ``efficientnet_lite0`` (median wall / 0.5). ``cpu s`` is the process CPU time
(all threads) per image: on a shared, busy machine wall time is inflated by other processes, and
``cpu s / threads`` is a lower bound of the uncontended wall time. AlexNet runs with ``weights="random"`` (the ImageNet file is
not shipped): its timing is valid, its descriptors are not.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np
import torch

TARGET_S = 0.5


def dense_boxes(image_size: tuple[int, int]) -> np.ndarray:
    """100 dense boxes (Section 4): ``vpr_core.landmarks.dense_sampling`` or an inline 4x25 grid."""
    try:
        from vpr_core.landmarks import dense_sampling

        return np.asarray(dense_sampling(image_size), dtype=np.float64)
    except ImportError:
        h, w = image_size
        out = []
        for a in (0.16, 0.25, 0.36, 0.49):
            bw, bh = np.sqrt(a) * w, np.sqrt(a) * h
            for y in np.linspace(0, h - bh, 5):
                for x in np.linspace(0, w - bw, 5):
                    out.append((x, y, bw, bh))
        return np.asarray(out)


def main() -> None:
    """Run the benchmark and print the table."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--threads", type=int, default=None, help="torch threads (default: torch's)")
    p.add_argument("--backbones", nargs="*", default=None)
    p.add_argument("--input-size", type=int, default=None)
    args = p.parse_args()
    os.environ.setdefault("TQDM_DISABLE", "1")
    if args.threads:
        torch.set_num_threads(args.threads)

    from vpr_core.features import LandmarkEncoder, available_backbones

    rng = np.random.default_rng(0)
    image = rng.integers(0, 256, (360, 640, 3), dtype=np.uint8)
    boxes = dense_boxes((360, 640))
    names = args.backbones or available_backbones()
    print(f"landmark encoding: 640x360 image, {len(boxes)} dense boxes, repeats={args.repeats}")
    print(f"torch {torch.__version__}, torch threads {torch.get_num_threads()}, "
          f"os.cpu_count() {os.cpu_count()}")
    header = (f"{'backbone':<27}{'input':>6}{'raw_dim':>9}{'dim':>6}{'median s':>10}"
              f"{'best s':>9}{'cpu s':>8}{'/0.5s':>7}  note")
    print(f"load average before run: {os.getloadavg()} (other processes share these cores)")
    print(header)
    print("-" * len(header))
    for name in names:
        weights = "random" if name.startswith("alexnet") else None
        enc = LandmarkEncoder(name, dim=1024, weights=weights, input_size=args.input_size)
        enc.encode(image, boxes[:10])  # warm-up
        times, cpu = [], []
        for _ in range(args.repeats):
            t0, c0 = time.perf_counter(), time.process_time()
            enc.encode(image, boxes)
            times.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
        med = statistics.median(times)
        note = "RANDOM weights: speed only" if weights == "random" else enc.weights_source
        print(f"{name:<27}{enc.input_size:>6}{enc.raw_dim:>9}{enc.dim:>6}{med:>10.3f}"
              f"{min(times):>9.3f}{statistics.median(cpu):>8.3f}{med / TARGET_S:>7.2f}  {note}")


if __name__ == "__main__":
    main()
