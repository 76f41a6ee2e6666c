"""Benchmark `similarity_matrix` against a bare matmul and a per-pair loop.

Usage: ``.venv/bin/python benchmarks/bench_matching.py [--n 200] [--k 100] [--dim 1024]``

Prints, from one run:
  (a) similarity_matrix / bare torch matmul of the same FLOP count  (target <= 1.5x)
  (b) per-pair `image_similarity` loop (timed on a subset, scaled) / similarity_matrix
      (target >= 30x)
  and the soft-NMS path (Algorithm 4, t=0.5) with its time per image pair.
Times are the best of ``--repeat`` runs (the machine is shared); the CPU-time ratio (user + sys
of the process) is printed too, as it is less sensitive to other processes on the cores.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
import torch

from vpr_core.matching import image_similarity, similarity_matrix


def _best(fn, repeat: int) -> tuple[float, float]:
    """Best wall time and the CPU time (user + sys, all threads) of that run."""
    best, cpu = float("inf"), float("inf")
    for _ in range(repeat):
        t, c = time.perf_counter(), time.process_time()
        fn()
        wall = time.perf_counter() - t
        if wall < best:
            best, cpu = wall, time.process_time() - c
    return best, cpu


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=200, help="query and reference images")
    ap.add_argument("--k", type=int, default=100, help="landmarks per image")
    ap.add_argument("--dim", type=int, default=1024, help="descriptor dimension")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--loop-pairs", type=int, default=300, help="pairs timed in the loop")
    args = ap.parse_args()
    os.environ.setdefault("TQDM_DISABLE", "1")
    n, k, dim = args.n, args.k, args.dim

    rng = np.random.default_rng(0)
    qd = rng.standard_normal((n, k, dim), dtype=np.float32)
    rd = rng.standard_normal((n, k, dim), dtype=np.float32)
    wh = rng.uniform(40, 300, size=(2, n, k, 2))
    xy = rng.uniform(0, 300, size=(2, n, k, 2))
    qb = np.concatenate([xy[0], wh[0]], axis=2)
    rb = np.concatenate([xy[1], wh[1]], axis=2)

    print(f"torch {torch.__version__}, threads {torch.get_num_threads()}, "
          f"cpu_count {os.cpu_count()}; {n} x {n} images x {k} landmarks x {dim}-d")

    a = torch.from_numpy(qd.reshape(n * k, dim))
    b = torch.from_numpy(rd.reshape(n * k, dim))
    t_mm, c_mm = _best(lambda: a @ b.T, args.repeat)
    flops = 2.0 * (n * k) ** 2 * dim
    print(f"bare matmul ({n * k}, {dim}) @ ({dim}, {n * k}): {t_mm:.3f} s "
          f"({flops / t_mm / 1e9:.0f} GFLOP/s)")

    sim = None

    def run():
        nonlocal sim
        sim = similarity_matrix(qd, qb, rd, rb, show_progress=False)

    t_sm, c_sm = _best(run, args.repeat)
    print(f"similarity_matrix: {t_sm:.3f} s  -> {t_sm / t_mm:.2f}x bare matmul (target <= 1.5x); "
          f"CPU time {c_sm:.1f} s vs {c_mm:.1f} s -> {c_sm / c_mm:.2f}x")

    pairs = [(int(i), int(j)) for i, j in rng.integers(0, n, size=(args.loop_pairs, 2))]
    t = time.perf_counter()
    loop_vals = [image_similarity(qd[i], qb[i], rd[j], rb[j]) for i, j in pairs]
    t_loop = (time.perf_counter() - t) / len(pairs) * n * n
    err = max(abs(v - sim[i, j]) for v, (i, j) in zip(loop_vals, pairs))
    print(f"per-pair loop (scaled from {len(pairs)} pairs): {t_loop:.1f} s -> "
          f"similarity_matrix is {t_loop / t_sm:.0f}x faster (target >= 30x); "
          f"max |diff| {err:.2e}")

    sim_nms = None

    def run_nms():
        nonlocal sim_nms
        sim_nms = similarity_matrix(qd, qb, rd, rb, soft_nms_iou=0.5, show_progress=False)

    t_nms, _ = _best(run_nms, 1)
    print(f"similarity_matrix soft-NMS t=0.5: {t_nms:.3f} s ({t_nms / t_mm:.2f}x bare matmul); "
          f"soft-NMS overhead {(t_nms - t_sm) / n / n * 1e3:.3f} ms per image pair")
    sub = pairs[:50]
    t = time.perf_counter()
    loop_nms = [image_similarity(qd[i], qb[i], rd[j], rb[j], soft_nms_iou=0.5) for i, j in sub]
    t_loop_nms = (time.perf_counter() - t) / len(sub) * n * n
    err = max(abs(v - sim_nms[i, j]) for v, (i, j) in zip(loop_nms, sub))
    print(f"per-pair soft-NMS loop (scaled): {t_loop_nms:.1f} s -> {t_loop_nms / t_nms:.0f}x; "
          f"max |diff| {err:.2e}")


if __name__ == "__main__":
    main()
