"""Batched path: Eq. (1) for every query x reference image pair at once, in torch.

:func:`similarity_matrix` computes the same numbers as
:func:`~vpr_core.matching.pairwise.image_similarity` for every pair: one float32 matmul per block of
queries x references, reciprocal test by argmax both ways, and a float64 re-check of every
near-tie (:mod:`~vpr_core.matching.ties`) so that the matches are exactly those of the pairwise
path. Values agree to ~1e-6 (float32 cosines), always within 1e-5.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from ..paper import SOFT_NMS_SIGMA
from ..utils import progress
from .padding import LandmarkSets, Side, iou_stack, prepare_side
from .pairwise import TIE_TOL, check_soft_nms, shape_terms
from .soft_nms import nms_block
from .ties import cos64, resolve_ties

__all__ = ["similarity_matrix"]

_PAD = -4.0  # below any cosine: padded landmarks never win an argmax


def similarity_matrix(query_desc: LandmarkSets, query_boxes: LandmarkSets,
                      reference_desc: LandmarkSets, reference_boxes: LandmarkSets,
                      soft_nms_iou: float | None = None, sigma: float = SOFT_NMS_SIGMA,
                      device: str | torch.device = "cpu", batch_size: int | None = None,
                      ref_batch_size: int | None = None, matmul_dtype: str = "float32",
                      show_progress: bool = True) -> np.ndarray:
    """Eq. (1) similarity of every query x reference image pair, vectorised in torch.

    Descriptors are L2-normalised, zero padded to the largest landmark count (padded entries are
    masked out), and compared by one matmul per block of ``batch_size`` queries x
    ``ref_batch_size`` references; reciprocal matches come from argmax both ways. The matmul runs
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
        ``(Nq, Nr)`` float64 similarity matrix.
    """
    check_soft_nms(soft_nms_iou, sigma)
    if matmul_dtype not in ("float32", "float64"):
        raise ValueError(f"matmul_dtype must be 'float32' or 'float64', got {matmul_dtype!r}")
    dev = torch.device(device)
    mm_dtype = torch.float32 if matmul_dtype == "float32" else torch.float64
    q = prepare_side(query_desc, query_boxes, "query", mm_dtype, dev)
    r = prepare_side(reference_desc, reference_boxes, "reference", mm_dtype, dev)
    if q.dim and r.dim and q.dim != r.dim:
        raise ValueError(f"descriptor dimensions differ: query D={q.dim}, reference D={r.dim}")
    dim = max(q.dim, r.dim)
    out = torch.zeros((q.n, r.n), dtype=torch.float64, device=dev)
    if q.dim == 0 or r.dim == 0:  # no landmark anywhere on one side
        return out.cpu().numpy()

    # float32 dot of unit vectors: |error| <= D * 2^-24 (+ rounding); two entries' difference
    # is off by at most twice that. Everything within `margin` of a max is re-checked in float64.
    unit = 2.0**-24 if mm_dtype == torch.float32 else 2.0**-53
    margin = 2.5 * dim * unit + 4 * unit + TIE_TOL

    bq = max(1, int(batch_size or 8))
    # ~8 MB of float32 cosines per block: big enough for an efficient matmul, small enough that
    # the reductions that follow read it from cache.
    br = int(ref_batch_size or max(1, (8 << 20) // (4 * bq * q.k * r.k)))
    br = max(1, min(br, r.n))
    nms = None
    if soft_nms_iou is not None:
        nms = (iou_stack(q, dev), iou_stack(r, dev), float(soft_nms_iou), float(sigma))
    qd, rd = q.d32.view(q.n, q.k, dim), r.d32.view(r.n, r.k, dim)
    threads = torch.get_num_threads()
    # The reductions after each matmul run on one thread: on small blocks OpenMP start-up costs
    # (and, on a loaded machine, waiting for the second core) exceed the work.
    single = dev.type == "cpu" and threads > 1

    buf = None  # reused matmul output (avoids page faults from fresh 8 MB blocks)
    work = None  # reused scratch of the same size for the reductions
    starts = range(0, q.n, bq)
    if show_progress:
        starts = progress(starts, desc="similarity", total=len(starts), unit="chunk")
    try:
        for q0 in starts:
            q1 = min(q0 + bq, q.n)
            a = qd[q0:q1].reshape((q1 - q0) * q.k, dim)
            for r0 in range(0, r.n, br):
                r1 = min(r0 + br, r.n)
                if single:
                    torch.set_num_threads(threads)
                b = rd[r0:r1].reshape((r1 - r0) * r.k, dim)
                shape = (a.shape[0], b.shape[0])
                if buf is None or buf.numel() < shape[0] * shape[1]:
                    buf = torch.empty(shape[0] * shape[1], dtype=mm_dtype, device=dev)
                    work = torch.empty(q.k * shape[1], dtype=mm_dtype, device=dev)
                s = torch.matmul(a, b.T, out=buf[: shape[0] * shape[1]].view(shape))
                s64 = None
                if nms is not None:
                    # float64 cosines for soft-NMS scores: Algorithm 4's argmax is discontinuous
                    # at ties, so its scores must match the pairwise path to ~1e-15
                    s64 = (q.unit_rows64(q0 * q.k, q1 * q.k)
                           @ r.unit_rows64(r0 * r.k, r1 * r.k).T).view(q1 - q0, q.k, r1 - r0, r.k)
                if single:
                    torch.set_num_threads(1)
                out[q0:q1, r0:r1] = _score_block(s, q, r, q0, q1, r0, r1, margin, nms, s64,
                                                       work)
    finally:
        torch.set_num_threads(threads)
    return out.cpu().numpy()


_INDEX_ONES: dict = {}


def _index_ones(k: int, dtype: torch.dtype, device: torch.device) -> torch.Tensor:
    """``(2, k)`` rows ``index`` and ``1`` (cached): times a 0/1 map, index sums and counts."""
    key = (k, dtype, device)
    if key not in _INDEX_ONES:
        _INDEX_ONES[key] = torch.stack(
            [torch.arange(k, dtype=dtype, device=device), torch.ones(k, dtype=dtype, device=device)])
    return _INDEX_ONES[key]


def _score_block(s: torch.Tensor, q: Side, r: Side, q0: int, q1: int, r0: int, r1: int,
                 margin: float, nms: tuple | None, s64: torch.Tensor | None = None,
                 work: torch.Tensor | None = None) -> torch.Tensor:
    """Eq. (1) for a block of image pairs from its landmark cosines.

    Args:
        s: ``(nq * Kq, nr * Kr)`` cosines (matmul dtype) of queries ``q0:q1`` x references
            ``r0:r1``; padded entries are overwritten in place.
        q, r: prepared sides; margin: float error bound of ``s``.
        nms: ``(iou_q, iou_r, t, sigma)`` or None.
        s64: ``(nq, Kq, nr, Kr)`` float64 cosines (soft-NMS only).
        work: flat scratch buffer of ``s``'s dtype with at least ``Kq * nr * Kr`` entries
            (reused across blocks), or None.

    Returns:
        ``(nq, nr)`` float64 similarities.
    """
    nq, nr = q1 - q0, r1 - r0
    s = s.view(nq, q.k, nr, r.k)
    qmask = q.mask[q0:q1]  # (nq, Kq)
    rmask = r.mask[r0:r1]  # (nr, Kr)
    if q.padded:
        s.masked_fill_(~qmask[:, :, None, None], _PAD)
    if r.padded:
        s.masked_fill_(~rmask[None, None], _PAD)
    # Row / column maxima (amax is a vectorised reduction, several times faster than max with
    # indices). Each entry within `margin` of its row's (column's) max is a candidate; a 0/1
    # candidate map times [index, 1] gives every row's (column's) candidate count and, where that
    # count is 1, its argmax -- cheap streaming passes instead of an argmax and a second-best
    # pass. Rows / columns with more than one candidate are the near-ties decided in float64
    # below. The passes run one query image at a time, so that its slice of `s` (and of the
    # scratch map) stays in the L2 cache from the first pass to the last.
    dt, dev = s.dtype, s.device
    rv = torch.empty((nq, q.k, nr), dtype=dt, device=dev)  # best cosine of each query landmark
    cv = torch.empty((nq, nr, r.k), dtype=dt, device=dev)  # ... of each reference landmark
    rsum = torch.empty((nq, 2, q.k * nr), dtype=dt, device=dev)  # [index sum, count] per row
    csum = torch.empty((nq, 2, nr * r.k), dtype=dt, device=dev)  # ... per column
    w = (torch.empty(s.shape[1:], dtype=dt, device=dev) if work is None
         else work[: s[0].numel()].view(s.shape[1:]))
    idx_r = _index_ones(r.k, dt, dev)  # (2, Kr)
    idx_q = _index_ones(q.k, dt, dev)  # (2, Kq)
    for g in range(nq):
        sg = s[g]  # (Kq, nr, Kr)
        torch.amax(sg, 2, out=rv[g])
        torch.amax(sg, 0, out=cv[g])
        torch.ge(sg, (rv[g] - margin).unsqueeze(2), out=w)
        torch.mm(idx_r, w.view(q.k * nr, r.k).T, out=rsum[g])
        torch.ge(sg, (cv[g] - margin).unsqueeze(0), out=w)
        torch.mm(idx_q, w.view(q.k, nr * r.k), out=csum[g])
    one_r = (rsum[:, 1] == 1).view(nq, q.k, nr)
    one_c = (csum[:, 1] == 1).view(nq, nr, r.k)
    ri = torch.where(one_r, rsum[:, 0].view(nq, q.k, nr), 0.0).long()  # (nq, Kq, nr)
    ci = torch.where(one_c, csum[:, 0].view(nq, nr, r.k), 0.0).long()  # (nq, nr, Kr)

    has_r = (r.count[r0:r1] > 0).view(1, 1, nr)
    has_q = (q.count[q0:q1] > 0).view(nq, 1, 1)
    amb_r = ~one_r & qmask[:, :, None] & has_r
    amb_c = ~one_c & rmask[None] & has_q
    rv = rv.double()
    if bool(amb_r.any()):
        iq, ii, ir = amb_r.nonzero(as_tuple=True)
        vals = s[iq, ii, ir]  # (n, Kr)
        ri[iq, ii, ir] = vals.argmax(1)  # a candidate; re-decided below where it matters
        best = rv[iq, ii, ir].to(s.dtype)
        # a near-tied row matters only if one of its candidates j could pick i back
        cand = (vals >= (best - margin)[:, None]) & (vals >= cv[iq, ir] - margin)
        keep = cand.any(1)
        iq, ii, ir, vals, best = iq[keep], ii[keep], ir[keep], vals[keep], best[keep]
        qrow = (q0 + iq) * q.k + ii
        rbase = (r0 + ir) * r.k

        def f_row(rows, cols):
            return cos64(q, qrow[rows], r, rbase[rows] + cols)

        if iq.numel():
            nn, sim = resolve_ties(vals, best, margin, f_row)
            ri[iq, ii, ir] = nn
            rv[iq, ii, ir] = sim
    if bool(amb_c.any()):
        iq, ir, ij = amb_c.nonzero(as_tuple=True)
        vals = s[iq, :, ir, ij]  # (n, Kq)
        ci[iq, ir, ij] = vals.argmax(1)
        best = cv[iq, ir, ij]
        rv_c = rv[iq, :, ir].to(s.dtype)  # (n, Kq) row maxima (refined rows: float64 values)
        cand = (vals >= (best - margin)[:, None]) & (vals >= rv_c - margin)
        keep = cand.any(1)
        iq, ir, ij, vals, best = iq[keep], ir[keep], ij[keep], vals[keep], best[keep]
        qbase = (q0 + iq) * q.k
        rrow = (r0 + ir) * r.k + ij

        def f_col(rows, cols):
            return cos64(q, qbase[rows] + cols, r, rrow[rows])

        if iq.numel():
            nn, _ = resolve_ties(vals, best, margin, f_col)
            ci[iq, ir, ij] = nn

    # per image pair layout (nq, nr, Kq)
    ri_p = ri.permute(0, 2, 1)
    recip = ci.gather(2, ri_p) == torch.arange(q.k, device=s.device)
    if q.padded:
        recip &= qmask[:, None, :]
    if r.padded or not bool(has_r.all()):
        recip &= rmask.unsqueeze(0).expand(nq, -1, -1).gather(2, ri_p)
    norm = torch.sqrt(q.count[q0:q1, None] * r.count[None, r0:r1])
    norm = torch.where(norm > 0, norm, torch.full_like(norm, math.inf))  # no landmark: 0
    if nms is None:
        # Eq. (1) on the reciprocal pairs only (a fraction of all query landmarks)
        g, rr, i = recip.nonzero(as_tuple=True)  # sorted: pair (g, rr), then landmark i
        j = ri[g, i, rr]
        cos = rv[g, i, rr].clamp(-1.0, 1.0)
        wq = q.wh[q0 + g, i]  # (P, 2)
        wr = r.wh[r0 + rr, j]
        shp = shape_terms(wq[:, 0], wr[:, 0], wq[:, 1], wr[:, 1], xp=torch)
        total = torch.zeros(nq * nr, dtype=torch.float64, device=s.device)
        total.index_add_(0, g * nr + rr, 1.0 - (1.0 - cos) * shp)
        return total.view(nq, nr) / norm
    cos = rv.permute(0, 2, 1).clamp(-1.0, 1.0)
    wh_q = q.wh[q0:q1].unsqueeze(1)  # (nq, 1, Kq, 2)
    wh_r = r.wh[r0:r1].unsqueeze(0).expand(nq, -1, -1, -1)  # (nq, nr, Kr, 2)
    wh_r = wh_r.gather(2, ri_p.unsqueeze(3).expand(-1, -1, -1, 2))  # (nq, nr, Kq, 2)
    shp = shape_terms(wh_q[..., 0], wh_r[..., 0], wh_q[..., 1], wh_r[..., 1], xp=torch)
    score = 1.0 - (1.0 - cos) * shp
    iou_q, iou_r, t, sigma = nms
    score = nms_block(score, shp, recip, ri_p, s64, iou_q[q0:q1], iou_r[r0:r1], t, sigma)
    total = torch.where(recip, score, torch.zeros_like(score)).sum(2)
    return total / norm
