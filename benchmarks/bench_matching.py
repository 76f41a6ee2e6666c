"""Benchmark `similarity_matrix` against a bare matmul of the same FLOP count (issue 10 item 4).

Usage: ``.venv/bin/python benchmarks/bench_matching.py [--n 200] [--k 100] [--dim 1024]
[--repeat 5] [--nms] [--nordland ROOT]``

Prints, from one run (both timed in this process, interleaved, ``--repeat`` times each):
  similarity_matrix / bare torch matmul ``(n*k, dim) @ (dim, n*k)``, the median of the per-repeat
  ratios (target <= 1.3x), with the median times and the CPU-time ratio (user + sys of the
  process, less sensitive to other processes on a shared machine);
  the largest difference to `image_similarity` (the one-pair float64 reference,
`matching/pairwise.py`) on a few pairs;
  with ``--nms``: the soft-NMS path (Algorithm 4, t = paper.SOFT_NMS_IOU) per image pair;
  with ``--nordland ROOT``: on the Nordland study (every 50th place, tolerance 0, roi, dense),
  the block engine (``similarity_matrix``) against Eq. (1) pair by pair (``image_similarity``),
  and each ``weighting`` against none (issue 31 item 4: a faster engine only where it buys
  more than 1.5x; issue 34: the weighting at most 20% more matching time).
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np
import torch

from vpr_core import paper
from vpr_core.matching import Compute, Matching, image_similarity, similarity_matrix

TARGET = 1.3


def _timed(fn) -> tuple[float, float]:
    """Wall and CPU time (user + sys, all threads) of one call."""
    t, c = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - t, time.process_time() - c


def nordland_study(root: str, repeat: int) -> None:
    """Block engine vs pair by pair, and the weightings, on the study's Nordland descriptors."""
    from vpr_core import run_method
    from vpr_core.datasets import load_dataset
    from vpr_core.matching import WEIGHTINGS as WEIGHTING_TABLE

    ds = load_dataset("nordland", root=root, step=50, tolerance=0)
    r = run_method("dense", ds, pooling="roi", keep_descriptors=True, n_bootstrap=0)
    args = (
        r.descriptors["query"],
        r.boxes["query"],
        r.descriptors["reference"],
        r.boxes["reference"],
    )
    nq, nr = len(args[0]), len(args[2])

    def pairwise():
        return np.array(
            [
                [
                    image_similarity(args[0][i], args[1][i], args[2][j], args[3][j])
                    for j in range(nr)
                ]
                for i in range(nq)
            ]
        )

    t_pair, _ = _timed(pairwise)
    t_block = statistics.median(
        _timed(lambda: similarity_matrix(*args, compute=Compute(show_progress=False)))[0]
        for _ in range(repeat)
    )
    print(
        f"Nordland study ({nq} x {nr} places, dense, roi): Eq. (1) pair by pair "
        f"(image_similarity) {t_pair:.2f} s, block engine (similarity_matrix) {t_block:.3f} s: "
        f"{t_pair / t_block:.1f}x"
    )
    times: dict = {w: [] for w in (None, *WEIGHTING_TABLE)}
    for _ in range(repeat):
        for w in times:
            times[w].append(
                _timed(
                    lambda w=w: similarity_matrix(
                        *args, matching=Matching(weighting=w), compute=Compute(show_progress=False)
                    )
                )[0]
            )
    base = statistics.median(times[None])
    for w in WEIGHTING_TABLE:
        print(
            f"weighting={w}: median {statistics.median(times[w]):.3f} s vs {base:.3f} s without: "
            f"{statistics.median(times[w]) / base:.2f}x (target <= 1.2x), {repeat} interleaved runs"
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=200, help="query and reference images")
    ap.add_argument("--k", type=int, default=100, help="landmarks per image")
    ap.add_argument("--dim", type=int, default=1024, help="descriptor dimension")
    ap.add_argument("--repeat", type=int, default=5, help="timed runs of each (median)")
    ap.add_argument("--check-pairs", type=int, default=20, help="pairs checked vs image_similarity")
    ap.add_argument("--nms", action="store_true", help="also time the soft-NMS path")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--nordland", help="nordland_64x32 folder: time the Nordland study instead")
    args = ap.parse_args()
    os.environ.setdefault("TQDM_DISABLE", "1")
    if args.nordland:
        nordland_study(args.nordland, args.repeat)
        return
    n, k, dim = args.n, args.k, args.dim

    rng = np.random.default_rng(args.seed)
    qd = rng.standard_normal((n, k, dim), dtype=np.float32)
    rd = rng.standard_normal((n, k, dim), dtype=np.float32)
    wh = rng.uniform(40, 300, size=(2, n, k, 2))
    xy = rng.uniform(0, 300, size=(2, n, k, 2))
    qb = np.concatenate([xy[0], wh[0]], axis=2)
    rb = np.concatenate([xy[1], wh[1]], axis=2)
    print(
        f"torch {torch.__version__}, threads {torch.get_num_threads()}, "
        f"cpu_count {os.cpu_count()}; {n} x {n} images x {k} landmarks x {dim}-d"
    )

    a = torch.from_numpy(qd.reshape(n * k, dim))
    b = torch.from_numpy(rd.reshape(n * k, dim))
    sim = None

    def run():
        nonlocal sim
        sim = similarity_matrix(qd, qb, rd, rb, compute=Compute(show_progress=False))

    run()  # warm-up (thread pools, allocator)
    mm, sm, ratios, cpu_ratios = [], [], [], []
    for _ in range(args.repeat):
        t_mm, c_mm = _timed(lambda: a @ b.T)
        t_sm, c_sm = _timed(run)
        mm.append(t_mm)
        sm.append(t_sm)
        ratios.append(t_sm / t_mm)
        cpu_ratios.append(c_sm / c_mm)
    flops = 2.0 * (n * k) ** 2 * dim
    t_mm, t_sm = statistics.median(mm), statistics.median(sm)
    ratio = statistics.median(ratios)
    print(
        f"bare matmul ({n * k}, {dim}) @ ({dim}, {n * k}): median {t_mm:.3f} s "
        f"({flops / t_mm / 1e9:.0f} GFLOP/s)"
    )
    print(f"similarity_matrix: median {t_sm:.3f} s")
    print(
        f"ratio similarity_matrix / bare matmul: median {ratio:.2f}x over {args.repeat} "
        f"interleaved runs (per run: {', '.join(f'{x:.2f}' for x in ratios)}); "
        f"target <= {TARGET}x: {'met' if ratio <= TARGET else 'NOT met'}; "
        f"CPU-time ratio {statistics.median(cpu_ratios):.2f}x"
    )

    pairs = rng.integers(0, n, size=(args.check_pairs, 2))
    err = max(abs(image_similarity(qd[i], qb[i], rd[j], rb[j]) - sim[i, j]) for i, j in pairs)
    print(f"max |similarity_matrix - image_similarity| on {len(pairs)} pairs: {err:.2e}")

    if args.nms:
        sim_nms = None

        def run_nms():
            nonlocal sim_nms
            sim_nms = similarity_matrix(
                qd,
                qb,
                rd,
                rb,
                soft_nms_iou=paper.SOFT_NMS_IOU,
                compute=Compute(show_progress=False),
            )

        t_nms, _ = _timed(run_nms)
        print(
            f"similarity_matrix soft-NMS t={paper.SOFT_NMS_IOU}: {t_nms:.3f} s "
            f"({t_nms / t_mm:.2f}x bare matmul); {t_nms / n / n * 1e3:.3f} ms per image pair"
        )
        sub = pairs[:10]
        err = max(
            abs(
                image_similarity(qd[i], qb[i], rd[j], rb[j], soft_nms_iou=paper.SOFT_NMS_IOU)
                - sim_nms[i, j]
            )
            for i, j in sub
        )
        print(f"max |diff| soft-NMS on {len(sub)} pairs: {err:.2e}")


if __name__ == "__main__":
    main()
