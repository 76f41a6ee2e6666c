"""The floor under a cold ``make study`` on this machine: the distinct landmark crops the study
describes, times the backbone's seconds per crop.

Issue 35 asks for ``make study`` from an empty cache within 5 minutes on a 2-core machine, with
the paper's crop pooling kept. Each distinct box of each study image goes through the backbone
exactly once (the feature stores are keyed by box content, shared by every sweep point and
notebook). This script counts the rows of the stores in a cache that ``make study`` filled and
times ``LandmarkEncoder.encode_crops`` (network and projection, the study's batches of 50) here;
their product is what the crop features alone take, whatever the rest of the study does. The
timing is taken with the backbone's fused oneDNN path (what the study runs) and, interleaved,
without it (``model.fused.enabled = False``); the two runs' descriptors are compared bit for
bit.

Usage::

    VPR_CACHE_DIR=/tmp/cold make study                                    # only the study
    VPR_CACHE_DIR=/tmp/cold .venv/bin/python benchmarks/study_floor.py [--repeats 5]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from vpr_core import utils
from vpr_core.features import encoder_slug, get_encoder

TARGET_S = 300.0  # issue 35: the whole cold study


def store_rows(folder: Path) -> tuple[int, int]:
    """``(images, boxes)``: per-image feature stores in ``folder`` and their rows."""
    stores = sorted(folder.glob("*.npz"))
    rows = 0
    for path in stores:
        with np.load(path, allow_pickle=False) as z:
            rows += len(z["boxes"])
    return len(stores), rows


def seconds_per_crop(encoder, n: int, repeats: int) -> tuple[float, float, bool]:
    """Median seconds per crop of ``encode_crops`` on ``n`` random crops, with the backbone's fused
    oneDNN path and without it (interleaved, ``repeats`` times each), and whether the two gave the
    same descriptors bit for bit."""
    s = encoder.input_size
    crops = torch.randn(n, 3, s, s, generator=torch.Generator().manual_seed(0))
    model = encoder.model
    fusable = hasattr(model, "fused")
    times: dict[bool, list[float]] = {True: [], False: []}
    outs: dict[bool, np.ndarray] = {}
    for fused in (True, False) if fusable else (False,):
        if fusable:
            model.fused.enabled = fused
        outs[fused] = encoder.encode_crops(crops[: encoder.batch_size])  # warm-up (and check)
    for _ in range(repeats):
        for fused in outs:
            if fusable:
                model.fused.enabled = fused
            t0 = time.perf_counter()
            encoder.encode_crops(crops)
            times[fused].append((time.perf_counter() - t0) / n)
    if fusable:
        model.fused.enabled = True
    fused_s = statistics.median(times[True] or times[False])
    same = all(np.array_equal(o, outs[False]) for o in outs.values())
    return fused_s, statistics.median(times[False]), same


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--backbone", default="efficientnet_lite0")
    parser.add_argument("--crops", type=int, default=500, help="crops per timing (default 500)")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    utils.tune_allocator()  # as the study's notebooks do
    encoder = get_encoder(args.backbone)  # the study's crop encoder
    slug = encoder_slug(encoder)
    root = utils.cache_dir("features")
    images, boxes = store_rows(root / slug)
    for other in sorted(p for p in root.iterdir() if p.is_dir() and p.name != slug):
        n_img, n_box = store_rows(other)
        print(f"(other encoder {other.name}: {n_box:,} boxes in {n_img} images, not counted)")
    if boxes == 0:
        raise SystemExit(f"no feature stores in {root / slug}: run make study with this cache")
    per_crop, module_s, same = seconds_per_crop(encoder, args.crops, args.repeats)
    floor = boxes * per_crop
    print(f"distinct crops in {root / slug}: {boxes:,} in {images} images")
    print(
        f"encode_crops here: {per_crop * 1e3:.2f} ms per crop (median of {args.repeats} x "
        f"{args.crops} crops, {torch.get_num_threads()} torch threads); module path "
        f"{module_s * 1e3:.2f} ms ({module_s / per_crop:.2f}x the fused oneDNN path), "
        f"descriptors {'identical' if same else 'DIFFERENT'} bit for bit"
    )
    print(
        f"floor: the crop features alone take >= {floor:.0f} s; issue 35's target for the "
        f"whole cold study is {TARGET_S:.0f} s (floor / target {floor / TARGET_S:.2f})"
    )


if __name__ == "__main__":
    main()
