"""Benchmark `similarity_matrix` against a bare matmul of the same FLOP count (issue 10 item 4).

Usage: ``.venv/bin/python benchmarks/bench_matching.py [--n 200] [--k 100] [--dim 1024]
[--repeat 5] [--nms]``

Prints, from one run (both timed in this process, interleaved, ``--repeat`` times each):
  similarity_matrix / bare torch matmul ``(n*k, dim) @ (dim, n*k)``, the median of the per-repeat
  ratios (target <= 1.3x), with the median times and the CPU-time ratio (user + sys of the
  process, less sensitive to other processes on a shared machine);
  the largest difference to `image_similarity` (the core's one-pair case, float64) on a few pairs;
  with ``--nms``: the soft-NMS path (Algorithm 4, t = paper.SOFT_NMS_IOU) per image pair.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np
import torch

from vpr_core.matching import image_similarity, similarity_matrix
from vpr_core.paper import SOFT_NMS_IOU

TARGET = 1.3


def _timed(fn) -> tuple[float, float]:
    """Wall and CPU time (user + sys, all threads) of one call."""
    t, c = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - t, time.process_time() - c


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=200, help="query and reference images")
    ap.add_argument("--k", type=int, default=100, help="landmarks per image")
    ap.add_argument("--dim", type=int, default=1024, help="descriptor dimension")
    ap.add_argument("--repeat", type=int, default=5, help="timed runs of each (median)")
    ap.add_argument("--check-pairs", type=int, default=20, help="pairs checked vs image_similarity")
    ap.add_argument("--nms", action="store_true", help="also time the soft-NMS path")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    os.environ.setdefault("TQDM_DISABLE", "1")
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
        sim = similarity_matrix(qd, qb, rd, rb, show_progress=False)

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
                qd, qb, rd, rb, soft_nms_iou=SOFT_NMS_IOU, show_progress=False
            )

        t_nms, _ = _timed(run_nms)
        print(
            f"similarity_matrix soft-NMS t={SOFT_NMS_IOU}: {t_nms:.3f} s "
            f"({t_nms / t_mm:.2f}x bare matmul); {t_nms / n / n * 1e3:.3f} ms per image pair"
        )
        sub = pairs[:10]
        err = max(
            abs(
                image_similarity(qd[i], qb[i], rd[j], rb[j], soft_nms_iou=SOFT_NMS_IOU)
                - sim_nms[i, j]
            )
            for i, j in sub
        )
        print(f"max |diff| soft-NMS on {len(sub)} pairs: {err:.2e}")


if __name__ == "__main__":
    main()
