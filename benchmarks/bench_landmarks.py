"""Seconds per 640x360 image for Edge Boxes (1,000 candidates) vs dense sampling.

Usage::

    .venv/bin/python benchmarks/bench_landmarks.py [--source skimage|synthetic|gardens]
        [--n-images 6] [--repeats 3] [--candidates 1000]

``skimage`` (default): scikit-image's bundled photographs resized to 640x360. ``synthetic``: the
embedded default dataset (``vpr_core.datasets``), query and reference images. ``gardens``: the
real pairs in ``../shared/data/gardens_point_mini`` (day query, night reference). Prints the
machine's core count, the per-image median time of each method and the ratio edge_boxes/dense
measured in this run (target: Edge Boxes <= 1 s per image on the 2-core machine; the paper
quotes ~0.25 s for Edge Boxes in MATLAB/C++).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from vpr_core import landmarks as L
from vpr_core import paper

SIZE = (360, 640)


def _resize(img: np.ndarray) -> np.ndarray:
    import cv2

    if img.ndim == 2:
        img = np.repeat(img[:, :, None], 3, axis=2)
    img = img[:, :, :3]
    return cv2.resize(img, (SIZE[1], SIZE[0]), interpolation=cv2.INTER_AREA)


def images_skimage(n: int) -> list[tuple[str, np.ndarray]]:
    from skimage import data

    names = [
        "astronaut",
        "coffee",
        "chelsea",
        "rocket",
        "immunohistochemistry",
        "camera",
        "hubble_deep_field",
        "retina",
    ]
    out = []
    for name in names[:n]:
        out.append((name, _resize(getattr(data, name)())))
    return out


def images_synthetic(n: int) -> list[tuple[str, np.ndarray]]:
    from vpr_core.datasets import load_dataset

    ds = load_dataset("synthetic", n_places=max(2, (n + 1) // 2))
    out = []
    for i in range(len(ds)):
        for side in ("query", "reference"):
            if len(out) < n:
                out.append((f"synthetic-{side}-{i}", _resize(ds.load_image(side, i))))
    return out


def images_gardens(n: int) -> list[tuple[str, np.ndarray]]:
    import cv2

    root = Path(__file__).resolve().parents[2] / "shared" / "data" / "gardens_point_mini"
    paths = sorted((root / "query").glob("*.jpg"))[: (n + 1) // 2]
    paths += sorted((root / "reference").glob("*.jpg"))[: n // 2]
    if not paths:
        raise SystemExit(f"no images under {root}")
    return [
        (f"{p.parent.name}/{p.name}", _resize(cv2.cvtColor(cv2.imread(str(p)), cv2.COLOR_BGR2RGB)))
        for p in paths
    ]


def best_of(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--source", choices=("skimage", "synthetic", "gardens"), default="skimage")
    ap.add_argument("--n-images", type=int, default=6)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--candidates", type=int, default=paper.N_CANDIDATES)
    args = ap.parse_args(argv)

    loader = {"skimage": images_skimage, "synthetic": images_synthetic, "gardens": images_gardens}[
        args.source
    ]
    images = loader(args.n_images)
    L.edge_boxes(images[0][1], max_boxes=10)  # warm-up (imports, logging)

    print(
        f"cores: {os.cpu_count()}  images: {len(images)} x {SIZE[1]}x{SIZE[0]} "
        f"({args.source})  repeats: {args.repeats} (best of)"
    )
    print(f"{'image':32s} {'edge_boxes [s]':>14s} {'#boxes':>7s} {'dense [s]':>11s}")
    eb_t, dn_t = [], []
    for name, img in images:
        n_boxes = len(L.edge_boxes(img, max_boxes=args.candidates))
        t_eb = best_of(lambda im=img: L.edge_boxes(im, max_boxes=args.candidates), args.repeats)
        t_dn = best_of(lambda im=img: L.dense_sampling(im.shape[:2]), max(args.repeats, 20))
        eb_t.append(t_eb)
        dn_t.append(t_dn)
        print(f"{name:32s} {t_eb:14.3f} {n_boxes:7d} {t_dn:11.2e}")
    eb_med, dn_med = float(np.median(eb_t)), float(np.median(dn_t))
    print(
        f"median s/image: edge_boxes({args.candidates}) = {eb_med:.3f}   "
        f"dense_sampling = {dn_med:.2e}"
    )
    print(
        f"ratio edge_boxes / dense = {eb_med / dn_med:,.0f}x   "
        f"(target edge_boxes <= 1 s/image: {'OK' if eb_med <= 1.0 else 'MISSED'})"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
