"""Reciprocal nearest neighbours of a block of image pairs, with near-ties decided in one place
(:func:`_resolve_ties`: float64 cosines, lowest index wins).
"""

from __future__ import annotations

import math

import numpy as np
import torch

from ._sides import PAD, Selection, Side, selection_index, selection_size

__all__ = ["TIE_TOL", "reciprocal"]

#: Cosine similarities closer than this to the row/column best are ties (lowest index wins).
TIE_TOL = 1e-9


# ---- near-ties: the one place they are decided -------------------------------------------
def _cos64(q: Side, qrows: torch.Tensor, r: Side, rrows: torch.Tensor) -> torch.Tensor:
    """``(t,)`` float64 cosines ``dot(a, b) / (|a| |b|)`` of flat rows (0 for zero rows)."""
    norms = q.norm64().index_select(0, qrows) * r.norm64().index_select(0, rrows)
    if q.raw.device.type == "cpu":
        # NumPy gathers the rows and casts chunk by chunk inside einsum (no big float64
        # temporaries); float32 products are exact in float64
        x = q.raw.numpy()[qrows.numpy()]
        y = r.raw.numpy()[rrows.numpy()]
        return torch.from_numpy(np.einsum("ij,ij->i", x, y, dtype=np.float64)) / norms
    x = q.raw.index_select(0, qrows).to(torch.float64)
    y = r.raw.index_select(0, rrows).to(torch.float64)
    return torch.linalg.vecdot(x, y) / norms


def _resolve_ties(vals: torch.Tensor, best: torch.Tensor, margin: float, sim64_fn):
    """Nearest neighbour of near-tied rows in float64: within TIE_TOL of the best, lowest index.

    Args:
        vals: ``(n, K)`` matmul-dtype similarities of the ambiguous rows.
        best: ``(n,)`` their maxima.
        margin: matmul error bound; every entry within it of the max is a candidate.
        sim64_fn: ``(row_ids (t,), cols (t,)) -> (t,)`` float64 similarities.

    Returns:
        ``(nn (n,) int64, sim (n,) float64)``.
    """
    n, k = vals.shape
    cand = vals >= (best - margin).unsqueeze(1)
    rows, cols = cand.nonzero(as_tuple=True)
    sims = torch.empty(rows.shape[0], dtype=torch.float64, device=vals.device)
    step = 1024  # keeps the gathered float64 rows in cache
    for s in range(0, rows.shape[0], step):
        sims[s : s + step] = sim64_fn(rows[s : s + step], cols[s : s + step])
    sims = sims.clamp(-1.0, 1.0)
    mx = torch.full((n,), -math.inf, dtype=torch.float64, device=vals.device)
    mx = mx.scatter_reduce(0, rows, sims, reduce="amax")
    tied = sims >= mx[rows] - TIE_TOL
    big = torch.full_like(cols, k)
    nn = torch.full((n,), k, dtype=torch.int64, device=vals.device)
    nn = nn.scatter_reduce(0, rows, torch.where(tied, cols, big), reduce="amin")
    chosen = cols == nn[rows]
    sim = torch.zeros(n, dtype=torch.float64, device=vals.device)
    sim[rows[chosen]] = sims[chosen]
    return nn, sim


# ---- reciprocal nearest neighbours of a block --------------------------------------------
_INDEX_ONES: dict = {}


def _index_ones(k: int, dtype: torch.dtype, device: torch.device) -> torch.Tensor:
    """``(2, k)`` rows ``index`` and ``1`` (cached): times a 0/1 map, index sums and counts."""
    key = (k, dtype, device)
    if key not in _INDEX_ONES:
        _INDEX_ONES[key] = torch.stack(
            [torch.arange(k, dtype=dtype, device=device), torch.ones(k, dtype=dtype, device=device)]
        )
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
    # (_resolve_ties). The passes run one query image at a time, so that its slice of `s` (and of
    # the scratch map) stays in the L2 cache from the first pass to the last.
    dt, dev = s.dtype, s.device
    rv = torch.empty((nq, kq, nr), dtype=dt, device=dev)  # best cosine of each query landmark
    cv = torch.empty((nq, nr, kr), dtype=dt, device=dev)  # ... of each reference landmark
    rsum = torch.empty((nq, 2, kq * nr), dtype=dt, device=dev)  # [index sum, count] per row
    csum = torch.empty((nq, 2, nr * kr), dtype=dt, device=dev)  # ... per column
    w = (
        torch.empty(s.shape[1:], dtype=dt, device=dev)
        if work is None
        else work[: s[0].numel()].view(s.shape[1:])
    )
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


def _decide_near_ties(
    s: torch.Tensor,
    q: Side,
    r: Side,
    qsel: Selection,
    rsel: Selection,
    margin: float,
    maxima: tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor],
    ambiguous: tuple[torch.Tensor, torch.Tensor],
) -> torch.Tensor:
    """Re-decide ambiguous rows and columns by :func:`_resolve_ties`.

    Args:
        s: ``(nq, Kq, nr, Kr)`` block cosines.
        q, r, qsel, rsel: the sides and the block's images; margin: float error bound.
        maxima: ``(rv, cv, ri, ci)`` from :func:`_maxima` (``ri`` and ``ci`` updated in place).
        ambiguous: ``(amb_r (nq, Kq, nr), amb_c (nq, nr, Kr))`` bool rows and columns to decide.

    Returns:
        ``(nq, Kq, nr)`` float64 row maxima (float64 cosines where a row was re-decided).
    """
    rv, cv, ri, ci = maxima
    amb_r, amb_c = ambiguous
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
        qrow = selection_index(qsel, iq) * q.k + ii
        rbase = selection_index(rsel, ir) * r.k

        def f_row(rows, cols):
            return _cos64(q, qrow[rows], r, rbase[rows] + cols)

        if iq.numel():
            nn, sim = _resolve_ties(vals, best, margin, f_row)
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
        qbase = selection_index(qsel, iq) * q.k
        rrow = selection_index(rsel, ir) * r.k + ij

        def f_col(rows, cols):
            return _cos64(q, qbase[rows] + cols, r, rrow[rows])

        if iq.numel():
            nn, _ = _resolve_ties(vals, best, margin, f_col)
            ci[iq, ir, ij] = nn
    return rv


def reciprocal(
    s: torch.Tensor,
    q: Side,
    r: Side,
    qsel: Selection,
    rsel: Selection,
    margin: float,
    work: torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Reciprocal nearest neighbours of every image pair of a block (ties: lowest index).

    Args:
        s: ``(nq * Kq, nr * Kr)`` cosines (matmul dtype) of the images ``qsel`` x ``rsel``;
            padded entries are overwritten in place.
        q, r: prepared sides; margin: float error bound of ``s``.
        work: flat scratch of ``s``'s dtype with at least ``Kq * nr * Kr`` entries, or None.

    Returns:
        ``(rv (nq, Kq, nr) float64 best cosine of each query landmark, ri_p (nq, nr, Kq) int64
        its nearest reference landmark, recip (nq, nr, Kq) bool: the pair is reciprocal)``.
    """
    nq, nr = selection_size(qsel), selection_size(rsel)
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
    rv = _decide_near_ties(s, q, r, qsel, rsel, margin, (rv, cv, ri, ci), (amb_r, amb_c))
    ri_p = ri.permute(0, 2, 1)  # per image pair layout (nq, nr, Kq)
    recip = ci.gather(2, ri_p) == torch.arange(q.k, device=s.device)
    if q.padded:
        recip &= qmask[:, None, :]
    if r.padded or not bool(has_r.all()):
        recip &= rmask.unsqueeze(0).expand(nq, -1, -1).gather(2, ri_p)
    return rv, ri_p, recip
