"""Batched path: Eq. (1) for every query x reference image pair at once, in torch.

:func:`similarity_matrix` computes the same numbers as
:func:`~vpr_core.matching.pairwise.image_similarity` for every pair: one float32 matmul per block of
queries x references, reciprocal test by argmax both ways, and a float64 re-check of every
near-tie (:func:`~vpr_core.matching.scoring.resolve_ties`) so that the matches are exactly those of the pairwise
path. Values agree to ~1e-6 (float32 cosines), always within 1e-5.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass

import numpy as np
import torch

from ..paper import SOFT_NMS_SIGMA
from ..utils import progress
from .pairwise import TIE_TOL, check_soft_nms
from .scoring import LandmarkSets, Selection, Side, iou_stack, prepare_side, score_block

__all__ = ["check_pairs", "similarity_matrix", "similarity_pairs"]

#: Bytes of matmul output per block: big enough for an efficient matmul, small enough that the
#: reductions that follow read it from the L2/L3 cache.
BLOCK_BYTES = 8 << 20


def similarity_matrix(
    query_desc: LandmarkSets,
    query_boxes: LandmarkSets,
    reference_desc: LandmarkSets,
    reference_boxes: LandmarkSets,
    soft_nms_iou: float | None = None,
    sigma: float = SOFT_NMS_SIGMA,
    device: str | torch.device = "cpu",
    batch_size: int | None = None,
    ref_batch_size: int | None = None,
    matmul_dtype: str = "float32",
    show_progress: bool = True,
) -> np.ndarray:
    """Eq. (1) similarity of every query x reference image pair, vectorised in torch.

    Descriptors are L2-normalised, zero padded to the largest landmark count (padded entries are
    masked out), and compared by one matmul per block of ``batch_size`` queries x
    ``ref_batch_size`` references; reciprocal matches come from argmax both ways. On the CPU the
    blocks are spread over ``torch.get_num_threads()`` worker threads, each running its
    matmuls and reductions on one core (no per-operation barriers, so the reductions after each
    matmul use every core; the result does not depend on the thread count). The matmul runs
    in ``matmul_dtype`` (float32 by default); every row or column whose best two cosines lie within
    the float32 error bound is re-decided in float64 with the pairwise rule (TIE_TOL, lowest
    index), so the matches equal :func:`reciprocal_matches` exactly and the values equal
    :func:`image_similarity` to ~1e-6. Soft-NMS (Algorithm 4) runs on all image pairs of a block in
    lockstep.

    Args:
        query_desc: sequence of ``(K_q, D)`` arrays, or one ``(Nq, K, D)`` array.
        query_boxes: sequence of ``(K_q, 4)`` ``(x, y, w, h)`` arrays, or ``(Nq, K, 4)``.
        reference_desc: sequence of ``(K_r, D)`` arrays, or ``(Nr, K, D)``.
        reference_boxes: sequence of ``(K_r, 4)`` arrays, or ``(Nr, K, 4)``.
        soft_nms_iou: Algorithm 4 threshold ``t`` or None.
        sigma: soft-NMS Gaussian width.
        device: torch device (``"cpu"``, ``"cuda"``).
        batch_size: queries per block (default: 8).
        ref_batch_size: references per block (default: a block of ~8 MB of float32 cosines).
        matmul_dtype: ``"float32"`` (fast) or ``"float64"``.
        show_progress: progress bar over query blocks (``TQDM_DISABLE=1`` silences it).

    Returns:
        ``(Nq, Nr)`` float64 similarity matrix; 0 for a pair where an image has no landmark
        (Eq. 1's convention; to exclude such images from ranking, set their entries to NaN,
        which :mod:`vpr_core.evaluation` treats as "not ranked").
    """
    ctx = _Context.build(
        query_desc,
        query_boxes,
        reference_desc,
        reference_boxes,
        soft_nms_iou,
        sigma,
        device,
        matmul_dtype,
    )
    q, r = ctx.q, ctx.r
    out = torch.zeros((q.n, r.n), dtype=torch.float64, device=ctx.dev)
    if ctx.empty:  # no landmark anywhere on one side
        return out.cpu().numpy()
    bq = max(1, int(batch_size or 8))
    br = int(ref_batch_size or max(1, BLOCK_BYTES // (4 * bq * q.k * r.k)))
    br = max(1, min(br, r.n))

    def task(q0: int, r0: int) -> None:
        q1, r1 = min(q0 + bq, q.n), min(r0 + br, r.n)
        out[q0:q1, r0:r1] = ctx.block(slice(q0, q1), slice(r0, r1))

    tasks = [
        lambda q0=q0, r0=r0: task(q0, r0) for q0 in range(0, q.n, bq) for r0 in range(0, r.n, br)
    ]
    _run(ctx, tasks, show_progress)
    return out.cpu().numpy()


def similarity_pairs(
    query_desc: LandmarkSets,
    query_boxes: LandmarkSets,
    reference_desc: LandmarkSets,
    reference_boxes: LandmarkSets,
    pairs: np.ndarray | Sequence,
    soft_nms_iou: float | None = None,
    sigma: float = SOFT_NMS_SIGMA,
    device: str | torch.device = "cpu",
    ref_batch_size: int | None = None,
    matmul_dtype: str = "float32",
    show_progress: bool = True,
) -> np.ndarray:
    """Eq. (1) similarity of the listed (query, reference) image pairs only (e.g. a shortlist).

    Pairs are grouped by query; each query is compared with its listed references by one matmul
    per chunk of ``ref_batch_size`` references (memory bounded), with the same reductions and
    float64 tie re-decision as :func:`similarity_matrix`. Equal to :func:`image_similarity` pair
    by pair (to 1e-5, the same matches).

    Args:
        query_desc, query_boxes, reference_desc, reference_boxes: as :func:`similarity_matrix`.
        pairs: ``(P, 2)`` int ``(query index, reference index)``; any order, repeats allowed.
        soft_nms_iou: Algorithm 4 threshold ``t`` or None.
        sigma: soft-NMS Gaussian width.
        device: torch device (``"cpu"``, ``"cuda"``).
        ref_batch_size: references per matmul (default: a block of ~8 MB of float32 cosines).
        matmul_dtype: ``"float32"`` (fast) or ``"float64"``.
        show_progress: progress bar over queries (``TQDM_DISABLE=1`` silences it).

    Returns:
        ``(P,)`` float64 similarities, in the order of ``pairs``.
    """
    ctx = _Context.build(
        query_desc,
        query_boxes,
        reference_desc,
        reference_boxes,
        soft_nms_iou,
        sigma,
        device,
        matmul_dtype,
    )
    q, r = ctx.q, ctx.r
    pr = check_pairs(pairs, q.n, r.n)
    out = np.zeros(pr.shape[0], dtype=np.float64)
    if ctx.empty or pr.shape[0] == 0:
        return out
    br = int(ref_batch_size or max(1, BLOCK_BYTES // (4 * q.k * r.k)))
    order = np.argsort(pr[:, 0], kind="stable")
    starts = np.flatnonzero(np.r_[True, pr[order[1:], 0] != pr[order[:-1], 0]])
    groups = np.split(order, starts[1:])

    def task(rows: np.ndarray) -> None:
        qi = int(pr[rows[0], 0])
        for c0 in range(0, rows.shape[0], br):
            chunk = rows[c0 : c0 + br]
            ridx = torch.from_numpy(pr[chunk, 1]).to(ctx.dev)
            out[chunk] = ctx.block(slice(qi, qi + 1), ridx)[0].cpu().numpy()

    _run(ctx, [lambda g=g: task(g) for g in groups], show_progress)
    return out


def check_pairs(pairs: np.ndarray | Sequence, nq: int, nr: int) -> np.ndarray:
    """``pairs`` as an int64 ``(P, 2)`` array of valid (query, reference) indices."""
    arr = np.asarray(pairs)
    if arr.size == 0:
        return np.zeros((0, 2), dtype=np.int64)
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ValueError(
            f"pairs must be a (P, 2) array of (query index, reference index), got shape {arr.shape}"
        )
    if not np.issubdtype(arr.dtype, np.integer):
        raise ValueError(f"pairs must hold integer indices, got dtype {arr.dtype}")
    arr = arr.astype(np.int64)
    for col, n, what in ((0, nq, "query"), (1, nr, "reference")):
        bad = np.flatnonzero((arr[:, col] < 0) | (arr[:, col] >= n))
        if bad.size:
            raise ValueError(
                f"pairs[{bad[0]}] has {what} index {arr[bad[0], col]}, outside "
                f"0..{n - 1} ({n} {what} images)"
            )
    return arr


@dataclass
class _Context:
    """Prepared sides and per-call settings shared by every block of one call."""

    q: Side
    r: Side
    dev: torch.device
    mm_dtype: torch.dtype
    margin: float
    nms: tuple | None
    empty: bool

    @classmethod
    def build(
        cls,
        query_desc,
        query_boxes,
        reference_desc,
        reference_boxes,
        soft_nms_iou,
        sigma,
        device,
        matmul_dtype,
    ) -> _Context:
        """Check the inputs and prepare both sides (see :func:`similarity_matrix`)."""
        check_soft_nms(soft_nms_iou, sigma)
        if matmul_dtype not in ("float32", "float64"):
            raise ValueError(f"matmul_dtype must be 'float32' or 'float64', got {matmul_dtype!r}")
        dev = torch.device(device)
        if dev.type == "cuda" and not torch.cuda.is_available():
            raise ValueError(f"device={device!r} but torch sees no CUDA GPU; use device='cpu'")
        mm_dtype = torch.float32 if matmul_dtype == "float32" else torch.float64
        q = prepare_side(query_desc, query_boxes, "query", mm_dtype, dev)
        r = prepare_side(reference_desc, reference_boxes, "reference", mm_dtype, dev)
        if q.dim and r.dim and q.dim != r.dim:
            raise ValueError(f"descriptor dimensions differ: query D={q.dim}, reference D={r.dim}")
        dim = max(q.dim, r.dim)
        # float32 dot of unit vectors: |error| <= D * 2^-24 (+ rounding); two entries'
        # difference is off by at most twice that. Entries within `margin` of a max are
        # re-checked in float64.
        unit = 2.0**-24 if mm_dtype == torch.float32 else 2.0**-53
        margin = 2.5 * dim * unit + 4 * unit + TIE_TOL
        empty = q.dim == 0 or r.dim == 0
        nms = None
        if soft_nms_iou is not None and not empty:
            nms = (iou_stack(q, dev), iou_stack(r, dev), float(soft_nms_iou), float(sigma))
        if not empty:
            q.build_caches(unit64=nms is not None)
            r.build_caches(unit64=nms is not None)
        return cls(q, r, dev, mm_dtype, margin, nms, empty)

    def block(self, qsel: Selection, rsel: Selection) -> torch.Tensor:
        """``(nq, nr)`` float64 Eq. (1) similarities of the images ``qsel`` x ``rsel``."""
        q, r = self.q, self.r
        a = q.images(qsel)
        b = r.images(rsel)
        n = a.shape[0] * b.shape[0]
        buf, work = _buffers(n, q.k * b.shape[0], self.mm_dtype, self.dev)
        s = torch.matmul(a, b.T, out=buf[:n].view(a.shape[0], b.shape[0]))
        s64 = None
        if self.nms is not None:
            # float64 cosines for soft-NMS scores: Algorithm 4's argmax is discontinuous at
            # ties, so its scores must match the pairwise path to ~1e-15
            s64 = (q.unit_images64(qsel) @ r.unit_images64(rsel).T).view(
                a.shape[0] // q.k, q.k, b.shape[0] // r.k, r.k
            )
        return score_block(s, q, r, qsel, rsel, self.margin, self.nms, s64, work)


_LOCAL = threading.local()


def _buffers(n: int, n_work: int, dtype: torch.dtype, device: torch.device):
    """Per-thread reused matmul output and scratch (fresh 8 MB blocks would page-fault)."""
    buf = getattr(_LOCAL, "buf", None)
    if buf is None or buf.numel() < n or buf.dtype != dtype or buf.device != device:
        _LOCAL.buf = torch.empty(n, dtype=dtype, device=device)
    work = getattr(_LOCAL, "work", None)
    if work is None or work.numel() < n_work or work.dtype != dtype or work.device != device:
        _LOCAL.work = torch.empty(n_work, dtype=dtype, device=device)
    return _LOCAL.buf, _LOCAL.work


def _run(ctx: _Context, tasks: list[Callable[[], None]], show_progress: bool) -> None:
    """Run independent tasks; on a multi-core CPU, on one worker thread per torch thread.

    Each worker sets torch's intra-op threads to 1 for itself, so the small reductions after
    each matmul never wait at an OpenMP barrier (on a loaded machine, for a descheduled core);
    the cores are used by running different blocks at once. Blocks write disjoint outputs, so
    the result is the same for any number of workers.
    """
    bar = (
        progress(None, total=len(tasks), desc="similarity", unit="block") if show_progress else None
    )
    threads = torch.get_num_threads()
    workers = min(threads, len(tasks)) if ctx.dev.type == "cpu" else 1
    try:
        if workers <= 1:
            for t in tasks:
                t()
                if bar is not None:
                    bar.update()
            return
        ex = ThreadPoolExecutor(workers, initializer=torch.set_num_threads, initargs=(1,))
        try:
            for f in as_completed([ex.submit(t) for t in tasks]):
                f.result()  # re-raises a worker's exception here
                if bar is not None:
                    bar.update()
        finally:
            ex.shutdown(wait=True, cancel_futures=True)
    finally:
        torch.set_num_threads(threads)  # MKL's thread count is process-wide
        if bar is not None:
            bar.close()
