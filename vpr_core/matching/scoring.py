"""Eq. (1) for one block of image pairs from its landmark cosines (the batched path's core).

A block is ``nq`` query images x ``nr`` reference images; the images are selected by a ``slice``
(a contiguous range, as :func:`~vpr_core.matching.batched.similarity_matrix` uses) or by a 1-D
int64 tensor of image indices (as :func:`~vpr_core.matching.batched.similarity_pairs` uses).
"""

from __future__ import annotations

import math

import torch

from .padding import Side
from .pairwise import shape_terms
from .soft_nms import nms_block
from .ties import cos64, resolve_ties

__all__ = ["PAD", "Selection", "score_block"]

PAD = -4.0  # below any cosine: padded landmarks never win an argmax

#: Images of one side in a block: a contiguous range or an int64 index tensor.
Selection = slice | torch.Tensor


def _image_index(sel: Selection, local: torch.Tensor) -> torch.Tensor:
    """Absolute image indices of block-local image indices ``local``."""
    return local + sel.start if isinstance(sel, slice) else sel[local]


def _size(sel: Selection) -> int:
    return sel.stop - sel.start if isinstance(sel, slice) else int(sel.numel())


_INDEX_ONES: dict = {}


def _index_ones(k: int, dtype: torch.dtype, device: torch.device) -> torch.Tensor:
    """``(2, k)`` rows ``index`` and ``1`` (cached): times a 0/1 map, index sums and counts."""
    key = (k, dtype, device)
    if key not in _INDEX_ONES:
        _INDEX_ONES[key] = torch.stack(
            [torch.arange(k, dtype=dtype, device=device), torch.ones(k, dtype=dtype, device=device)])
    return _INDEX_ONES[key]


def _maxima(s: torch.Tensor, margin: float, work: torch.Tensor | None):
    """Row and column maxima of a block and, where unambiguous, their arg-maxima.

    Args:
        s: ``(nq, Kq, nr, Kr)`` cosines (padded entries already set to :data:`PAD`).
        margin: float error bound; entries within it of a maximum are candidates.
        work: flat scratch of ``s``'s dtype with at least ``Kq * nr * Kr`` entries, or None.

    Returns:
        ``rv (nq, Kq, nr)`` row maxima, ``cv (nq, nr, Kr)`` column maxima (``s``'s dtype),
        ``ri (nq, Kq, nr)`` / ``ci (nq, nr, Kr)`` int64 arg-maxima (0 where ambiguous),
        ``one_r`` / ``one_c`` bool: the row (column) has exactly one candidate.
    """
    nq, kq, nr, kr = s.shape
    # Row / column maxima (amax is a vectorised reduction, several times faster than max with
    # indices). Each entry within `margin` of its row's (column's) max is a candidate; a 0/1
    # candidate map times [index, 1] gives every row's (column's) candidate count and, where that
    # count is 1, its argmax -- cheap streaming passes instead of an argmax and a second-best
    # pass. Rows / columns with more than one candidate are the near-ties decided in float64
    # below. The passes run one query image at a time, so that its slice of `s` (and of the
    # scratch map) stays in the L2 cache from the first pass to the last.
    dt, dev = s.dtype, s.device
    rv = torch.empty((nq, kq, nr), dtype=dt, device=dev)  # best cosine of each query landmark
    cv = torch.empty((nq, nr, kr), dtype=dt, device=dev)  # ... of each reference landmark
    rsum = torch.empty((nq, 2, kq * nr), dtype=dt, device=dev)  # [index sum, count] per row
    csum = torch.empty((nq, 2, nr * kr), dtype=dt, device=dev)  # ... per column
    w = (torch.empty(s.shape[1:], dtype=dt, device=dev) if work is None
         else work[: s[0].numel()].view(s.shape[1:]))
    idx_r = _index_ones(kr, dt, dev)  # (2, Kr)
    idx_q = _index_ones(kq, dt, dev)  # (2, Kq)
    for g in range(nq):
        sg = s[g]  # (Kq, nr, Kr)
        torch.amax(sg, 2, out=rv[g])
        torch.amax(sg, 0, out=cv[g])
        torch.ge(sg, (rv[g] - margin).unsqueeze(2), out=w)
        torch.mm(idx_r, w.view(kq * nr, kr).T, out=rsum[g])
        torch.ge(sg, (cv[g] - margin).unsqueeze(0), out=w)
        torch.mm(idx_q, w.view(kq, nr * kr), out=csum[g])
    one_r = (rsum[:, 1] == 1).view(nq, kq, nr)
    one_c = (csum[:, 1] == 1).view(nq, nr, kr)
    ri = torch.where(one_r, rsum[:, 0].view(nq, kq, nr), 0.0).long()  # (nq, Kq, nr)
    ci = torch.where(one_c, csum[:, 0].view(nq, nr, kr), 0.0).long()  # (nq, nr, Kr)

    return rv, cv, ri, ci, one_r, one_c


def _decide_near_ties(s: torch.Tensor, q: Side, r: Side, qsel: Selection, rsel: Selection,
                      margin: float, rv: torch.Tensor, cv: torch.Tensor, ri: torch.Tensor,
                      ci: torch.Tensor, amb_r: torch.Tensor, amb_c: torch.Tensor) -> torch.Tensor:
    """Re-decide ambiguous rows (``amb_r``) and columns (``amb_c``) in float64, in place.

    Args:
        s: ``(nq, Kq, nr, Kr)`` block cosines; ``rv``, ``cv``, ``ri``, ``ci``: from
            :func:`_maxima` (``ri`` and ``ci`` are updated in place).
        q, r, qsel, rsel: the sides and the block's images; margin: float error bound.
        amb_r: ``(nq, Kq, nr)`` bool rows to decide; amb_c: ``(nq, nr, Kr)`` bool columns.

    Returns:
        ``(nq, Kq, nr)`` float64 row maxima (float64 cosines where a row was re-decided).
    """
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
        qrow = _image_index(qsel, iq) * q.k + ii
        rbase = _image_index(rsel, ir) * r.k

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
        qbase = _image_index(qsel, iq) * q.k
        rrow = _image_index(rsel, ir) * r.k + ij

        def f_col(rows, cols):
            return cos64(q, qbase[rows] + cols, r, rrow[rows])

        if iq.numel():
            nn, _ = resolve_ties(vals, best, margin, f_col)
            ci[iq, ir, ij] = nn

    return rv


def score_block(s: torch.Tensor, q: Side, r: Side, qsel: Selection, rsel: Selection,
                 margin: float, nms: tuple | None, s64: torch.Tensor | None = None,
                 work: torch.Tensor | None = None) -> torch.Tensor:
    """Eq. (1) for a block of image pairs from its landmark cosines.

    Args:
        s: ``(nq * Kq, nr * Kr)`` cosines (matmul dtype) of queries ``qsel`` x references
            ``rsel``; padded entries are overwritten in place.
        q, r: prepared sides; margin: float error bound of ``s``.
        nms: ``(iou_q, iou_r, t, sigma)`` or None.
        s64: ``(nq, Kq, nr, Kr)`` float64 cosines (soft-NMS only).
        work: flat scratch buffer of ``s``'s dtype with at least ``Kq * nr * Kr`` entries
            (reused across blocks), or None.

    Returns:
        ``(nq, nr)`` float64 similarities.
    """
    nq, nr = _size(qsel), _size(rsel)
    s = s.view(nq, q.k, nr, r.k)
    qmask = q.mask[qsel]  # (nq, Kq)
    rmask = r.mask[rsel]  # (nr, Kr)
    if q.padded:
        s.masked_fill_(~qmask[:, :, None, None], PAD)
    if r.padded:
        s.masked_fill_(~rmask[None, None], PAD)
    rv, cv, ri, ci, one_r, one_c = _maxima(s, margin, work)
    has_r = (r.count[rsel] > 0).view(1, 1, nr)
    has_q = (q.count[qsel] > 0).view(nq, 1, 1)
    amb_r = ~one_r & qmask[:, :, None] & has_r
    amb_c = ~one_c & rmask[None] & has_q
    rv = _decide_near_ties(s, q, r, qsel, rsel, margin, rv, cv, ri, ci, amb_r, amb_c)

    # per image pair layout (nq, nr, Kq)
    ri_p = ri.permute(0, 2, 1)
    recip = ci.gather(2, ri_p) == torch.arange(q.k, device=s.device)
    if q.padded:
        recip &= qmask[:, None, :]
    if r.padded or not bool(has_r.all()):
        recip &= rmask.unsqueeze(0).expand(nq, -1, -1).gather(2, ri_p)
    norm = torch.sqrt(q.count[qsel][:, None] * r.count[rsel][None, :])
    norm = torch.where(norm > 0, norm, torch.full_like(norm, math.inf))  # no landmark: 0
    if nms is None:
        # Eq. (1) on the reciprocal pairs only (a fraction of all query landmarks)
        g, rr, i = recip.nonzero(as_tuple=True)  # sorted: pair (g, rr), then landmark i
        j = ri[g, i, rr]
        cos = rv[g, i, rr].clamp(-1.0, 1.0)
        wq = q.wh[_image_index(qsel, g), i]  # (P, 2)
        wr = r.wh[_image_index(rsel, rr), j]
        shp = shape_terms(wq[:, 0], wr[:, 0], wq[:, 1], wr[:, 1], xp=torch)
        total = torch.zeros(nq * nr, dtype=torch.float64, device=s.device)
        total.index_add_(0, g * nr + rr, 1.0 - (1.0 - cos) * shp)
        return total.view(nq, nr) / norm
    cos = rv.permute(0, 2, 1).clamp(-1.0, 1.0)
    wh_q = q.wh[qsel].unsqueeze(1)  # (nq, 1, Kq, 2)
    wh_r = r.wh[rsel].unsqueeze(0).expand(nq, -1, -1, -1)  # (nq, nr, Kr, 2)
    wh_r = wh_r.gather(2, ri_p.unsqueeze(3).expand(-1, -1, -1, 2))  # (nq, nr, Kq, 2)
    shp = shape_terms(wh_q[..., 0], wh_r[..., 0], wh_q[..., 1], wh_r[..., 1], xp=torch)
    score = 1.0 - (1.0 - cos) * shp
    iou_q, iou_r, t, sigma = nms
    score = nms_block(score, shp, recip, ri_p, s64, iou_q[qsel], iou_r[rsel], t, sigma)
    total = torch.where(recip, score, torch.zeros_like(score)).sum(2)
    return total / norm

