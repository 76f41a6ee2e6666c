"""Seconds per image for landmark description, ``crop`` vs ``roi`` pooling, side by side.

Run: ``.venv/bin/python benchmarks/bench_features.py [--repeats 5] [--threads N]
[--backbones efficientnet_lite0 ...] [--working-size 512]``.

One 640x360 image, 100 landmarks of two kinds: the dense grid (Sec. 4: 4 scales x 5x5) and
Edge-Box-like random boxes (100 boxes, seeded, normalised scale drawn over Table-1 Scales 2-8,
aspect 0.5-2, inside the image). For each backbone both pooling modes are timed *interleaved* in
one run (crop, roi, crop, roi, ...) so that load from other processes hits both alike; the table
shows the median wall seconds per image, the median process CPU seconds per image (all threads;
on a shared machine wall time is inflated by other processes, CPU time much less) and the ratios
crop / roi of both (target: roi >= 10x faster). ``crop0`` is ``crop`` in a child process with
``VPR_TUNE_MALLOC=0`` (glibc's default allocator, see :func:`vpr_core.utils.tune_allocator`),
timed in the same interleaved rounds (crop, roi, crop0, ...): the same descriptors, bit for bit;
the column shows what the allocator tuning buys. ``crop0 / roi`` approximates the ratio against
the crop path before this round's speed-ups (``crop0`` still has the fused ReLU6 + padding of
the stride-2 layers, a few percent). AlexNet runs with ``weights="random"`` (the
ImageNet file is not shipped): its timing is valid, its descriptors are not. HOG has no feature
map, so no ``roi`` mode.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np
import torch


def edge_box_like(image_size: tuple[int, int], n: int, seed: int = 0) -> np.ndarray:
    """``(n, 4)`` random boxes shaped like Edge Boxes proposals (scales 0.02-0.72, inside)."""
    from vpr_core import paper

    h, w = image_size
    rng = np.random.default_rng(seed)
    area = rng.uniform(paper.SCALE_EDGES[0], paper.SCALE_EDGES[-1], n) * h * w
    aspect = np.exp(rng.uniform(np.log(0.5), np.log(2.0), n))
    bw = np.minimum(np.sqrt(area * aspect), w)
    bh = np.minimum(area / bw, h)
    x = rng.uniform(0, w - bw)
    y = rng.uniform(0, h - bh)
    return np.stack([x, y, bw, bh], 1)


def _timed_encode(enc, image: np.ndarray, boxes: np.ndarray) -> tuple[float, float, np.ndarray]:
    t0, c0 = time.perf_counter(), time.process_time()
    out = enc.encode(image, boxes)
    return time.perf_counter() - t0, time.process_time() - c0, out


def _untuned_worker(conn, name: str, weights, threads: int | None) -> None:
    """Child process (``VPR_TUNE_MALLOC=0``): encode in crop mode whenever the parent asks."""
    if threads:
        torch.set_num_threads(threads)
    from vpr_core.features import LandmarkEncoder

    enc = LandmarkEncoder(name, weights=weights)
    while (msg := conn.recv()) is not None:
        conn.send(_timed_encode(enc, *msg))


class UntunedCrop:
    """``crop`` mode in a spawned child process with glibc's default allocator."""

    def __init__(self, name: str, weights, threads: int | None) -> None:
        import multiprocessing as mp

        old = os.environ.get("VPR_TUNE_MALLOC")
        os.environ["VPR_TUNE_MALLOC"] = "0"  # inherited by the spawned child only now
        ctx = mp.get_context("spawn")
        try:
            self.conn, child = ctx.Pipe()
            self.proc = ctx.Process(
                target=_untuned_worker, args=(child, name, weights, threads), daemon=True
            )
            self.proc.start()
        finally:
            if old is None:
                os.environ.pop("VPR_TUNE_MALLOC")
            else:
                os.environ["VPR_TUNE_MALLOC"] = old

    def timed_encode(self, image: np.ndarray, boxes: np.ndarray):
        self.conn.send((image, boxes))
        return self.conn.recv()

    def close(self) -> None:
        self.conn.send(None)
        self.proc.join(30)


def time_interleaved(
    encoders: dict, image: np.ndarray, boxes: np.ndarray, repeats: int
) -> dict[str, tuple[float, float]]:
    """Median ``(wall s, cpu s)`` per encoder, calls interleaved round-robin after a warm-up.

    An :class:`UntunedCrop` value times itself in its process; its descriptors must equal the
    ``crop`` encoder's bit for bit (checked, so the column compares the same computation).
    """

    def run(enc):
        if isinstance(enc, UntunedCrop):
            return enc.timed_encode(image, boxes)
        return _timed_encode(enc, image, boxes)

    first = {k: run(enc)[2] for k, enc in encoders.items()}
    if "crop0" in first and not np.array_equal(first["crop0"], first["crop"]):
        raise RuntimeError("crop descriptors differ with and without the allocator tuning")
    wall: dict[str, list[float]] = {k: [] for k in encoders}
    cpu: dict[str, list[float]] = {k: [] for k in encoders}
    for _ in range(repeats):
        for k, enc in encoders.items():
            w, c, _ = run(enc)
            wall[k].append(w)
            cpu[k].append(c)
    return {k: (statistics.median(wall[k]), statistics.median(cpu[k])) for k in encoders}


def main() -> None:
    """Run the benchmark and print the table."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--threads", type=int, default=None, help="torch threads (default: torch's)")
    p.add_argument("--backbones", nargs="*", default=["efficientnet_lite0"])
    p.add_argument("--working-size", type=int, default=None, help="roi working size")
    args = p.parse_args()
    os.environ.setdefault("TQDM_DISABLE", "1")
    if args.threads:
        torch.set_num_threads(args.threads)

    from skimage.data import astronaut

    from vpr_core import paper
    from vpr_core.features import LandmarkEncoder
    from vpr_core.landmarks import dense_sampling

    image = np.ascontiguousarray(np.concatenate([astronaut(), astronaut()[:, ::-1]], 1)[:360, :640])
    box_sets = {
        "dense": np.asarray(dense_sampling(image.shape[:2])),
        "edge-box-like": edge_box_like(image.shape[:2], paper.N_LANDMARKS),
    }
    print(
        f"640x360 image, {paper.N_LANDMARKS} landmarks, repeats={args.repeats}, torch "
        f"{torch.__version__}, threads {torch.get_num_threads()}, load average "
        f"{os.getloadavg()} (other processes share these cores)"
    )
    from vpr_core import utils

    tuned = utils.tune_allocator()
    header = (
        f"{'backbone':<34}{'work px':>8} {'boxes':<15}{'crop s':>8}{'roi s':>8}{'ratio':>7}"
        f"{'crop cpu':>10}{'roi cpu':>9}{'ratio':>7}{'crop0 s':>9}{'crop0/roi':>10}"
    )
    print(header)
    print("-" * len(header))
    for name in args.backbones:
        weights = "random" if name.startswith("alexnet") else None
        roi_kw = {"working_size": args.working_size} if args.working_size else {}
        encs = {
            "crop": LandmarkEncoder(name, weights=weights),
            "roi": LandmarkEncoder(name, weights=weights, pooling="roi", **roi_kw),
        }
        if tuned:  # else crop is already glibc's default: no second column to compare
            encs["crop0"] = UntunedCrop(name, weights, args.threads)
        for kind, boxes in box_sets.items():
            t = time_interleaved(encs, image, boxes, args.repeats)
            (cw, cc), (rw, rc) = t["crop"], t["roi"]
            c0 = (
                f"{t['crop0'][0]:>9.3f}{t['crop0'][0] / rw:>10.1f}"
                if "crop0" in t
                else f"{'-':>9}{'-':>10}"
            )
            print(
                f"{name:<34}{encs['roi'].working_size:>8} {kind:<15}{cw:>8.3f}{rw:>8.3f}"
                f"{cw / rw:>7.1f}{cc:>10.3f}{rc:>9.3f}{cc / rc:>7.1f}{c0}",
                flush=True,
            )
        if "crop0" in encs:
            encs["crop0"].close()
    print(
        "work px: roi working size (long side; default 4 crop sides). crop0: crop mode with "
        "glibc's default allocator (VPR_TUNE_MALLOC=0, child process), same descriptors"
    )


if __name__ == "__main__":
    main()
