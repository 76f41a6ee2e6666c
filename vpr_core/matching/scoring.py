"""The batched path's core: padded landmark sets, exact near-ties, and Eq. (1) for one block.

* **Padded landmark sets** (:class:`Side`, :func:`prepare_side`): every image's ``(K_i, D)``
  descriptors are zero padded to ``K = max K_i`` and stacked to ``(N * K, D)``; a mask marks the
  real landmarks. Box sizes and per-image IoU matrices are kept for Eq. (2) and soft-NMS.
* **Exact nearest neighbours** (:func:`resolve_ties`): the matmul runs in float32; a row (or
  column) whose best cosines lie within the float32 error bound of each other is re-decided in
  float64 with the pairwise rule (:data:`~vpr_core.matching.pairwise.TIE_TOL`, lowest index), so
  the batched matches equal :func:`~vpr_core.matching.pairwise.reciprocal_matches` exactly.
* **Eq. (1) per block** (:func:`score_block`): a block is ``nq`` query images x ``nr`` reference
  images, selected by a ``slice`` (a contiguous range, as
  :func:`~vpr_core.matching.batched.similarity_matrix` uses) or by a 1-D int64 tensor of image
  indices (as :func:`~vpr_core.matching.batched.similarity_pairs` uses).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Union

import numpy as np
import torch

from ..boxes import box_iou, check_boxes
from .pairwise import TIE_TOL, shape_terms
from .soft_nms import nms_block

__all__ = [
    "PAD",
    "LandmarkSets",
    "Selection",
    "Side",
    "cos64",
    "iou_stack",
    "prepare_side",
    "resolve_ties",
    "score_block",
]


# ---- padded landmark sets ----------------------------------------------------------------
LandmarkSets = Union[np.ndarray, Sequence[np.ndarray]]  # noqa: UP007


@dataclass
class Side:
    """Padded landmark sets of one side (query or reference); built by :func:`prepare_side`."""

    raw: torch.Tensor  # (N*K, D) descriptors as given (float32/float64), zero padded
    d32: torch.Tensor  # (N*K, D) normalised, matmul dtype
    mask: torch.Tensor  # (N, K) bool valid landmark
    count: torch.Tensor  # (N,) float64 number of landmarks
    wh: torch.Tensor  # (N, K, 2) float64 box sizes
    boxes: list[np.ndarray]
    n: int
    k: int
    dim: int
    padded: bool

    _norm64: torch.Tensor | None = None
    _unit64: torch.Tensor | None = None

    def images(self, sel: slice | torch.Tensor) -> torch.Tensor:
        """``(n * K, D)`` normalised matmul-dtype descriptors of the images ``sel``.

        Args:
            sel: a ``slice`` of image indices (a view, no copy) or an int64 index tensor.
        """
        if isinstance(sel, slice):
            return self.d32[sel.start * self.k : sel.stop * self.k]
        return self.d32.view(self.n, self.k, -1).index_select(0, sel).view(-1, self.dim)

    def unit_images64(self, sel: slice | torch.Tensor) -> torch.Tensor:
        """``(n * K, D)`` float64 unit descriptors of the images ``sel`` (cache built once)."""
        if self._unit64 is None:
            self._unit64 = self.raw.double() / self.norm64()[:, None]
        if isinstance(sel, slice):
            return self._unit64[sel.start * self.k : sel.stop * self.k]
        return self._unit64.view(self.n, self.k, -1).index_select(0, sel).view(-1, self.dim)

    def build_caches(self, unit64: bool) -> None:
        """Compute the lazy float64 caches now (before worker threads share this side)."""
        self.norm64()
        if unit64:
            self.unit_images64(slice(0, 0))

    def norm64(self) -> torch.Tensor:
        """``(N*K,)`` float64 descriptor norms (1 for zero rows), computed once."""
        if self._norm64 is None:
            n = torch.linalg.vector_norm(self.raw, dim=1, dtype=torch.float64)
            self._norm64 = torch.where(n > 0, n, torch.ones_like(n))
        return self._norm64


def _as_list(x: LandmarkSets, name: str, kind: str) -> list[np.ndarray]:
    """One array per image from a sequence or a stacked ``(N, K, kind)`` array."""
    if isinstance(x, (np.ndarray, torch.Tensor)):
        arr = np.asarray(x.detach().cpu() if isinstance(x, torch.Tensor) else x)
        if arr.ndim != 3:
            raise ValueError(f"{name} as one array must be (N, K, {kind}), got shape {arr.shape}")
        return list(arr)
    try:
        return [np.asarray(v) for v in x]
    except TypeError as e:
        raise ValueError(f"{name} must be a sequence of arrays or one (N, K, ...) array") from e


def prepare_side(
    desc: LandmarkSets, boxes: LandmarkSets, side: str, mm_dtype: torch.dtype, device: torch.device
) -> Side:
    """Check, pad and normalise one side's landmark sets.

    Args:
        desc: sequence of ``(K_i, D)`` arrays, or one ``(N, K, D)`` array / tensor.
        boxes: sequence of ``(K_i, 4)`` ``(x, y, w, h)`` arrays, or one ``(N, K, 4)`` array.
        side: ``"query"`` or ``"reference"`` (used in error messages).
        mm_dtype: dtype of the normalised descriptors used in the matmul.
        device: torch device of every tensor.

    Returns:
        :class:`Side`.
    """
    bl = _as_list(boxes, f"{side}_boxes", "4")
    if isinstance(desc, (np.ndarray, torch.Tensor)) and np.ndim(desc) == 3:
        stacked = np.asarray(desc.detach().cpu() if isinstance(desc, torch.Tensor) else desc)
        if stacked.dtype not in (np.float32, np.float64):
            stacked = stacked.astype(np.float64)
        n, k, dim = stacked.shape
        counts = [k] * n
    else:
        dl = _as_list(desc, f"{side}_desc", "D")
        n = len(dl)
        dl = [np.zeros((0, 0)) if d.ndim == 1 and d.size == 0 else d for d in dl]
        for i, d in enumerate(dl):
            if d.ndim != 2:
                raise ValueError(f"{side}_desc[{i}] must be (K, D), got shape {d.shape}")
        dims = sorted({d.shape[1] for d in dl if d.shape[0]})
        if len(dims) > 1:
            raise ValueError(f"{side}_desc mixes descriptor dimensions {dims}")
        dim = dims[0] if dims else 0
        counts = [d.shape[0] for d in dl]
        k = max(counts + [1])
        dtype = np.float32 if all(d.dtype == np.float32 for d in dl) else np.float64
        stacked = np.zeros((n, k, dim), dtype=dtype)
        for i, d in enumerate(dl):
            if d.shape[0]:
                stacked[i, : d.shape[0]] = d
    if len(bl) != n:
        raise ValueError(f"{side}_desc has {n} images but {side}_boxes has {len(bl)}")
    if n == 0:
        raise ValueError(f"{side}_desc is empty")
    raw = torch.from_numpy(np.ascontiguousarray(stacked)).to(device).reshape(n * k, dim)
    raw_mm = raw.to(mm_dtype)
    norm = torch.linalg.vector_norm(raw_mm, dim=1)  # NaN / inf anywhere shows in the norm
    if not bool(torch.isfinite(norm).all()):
        raise ValueError(f"{side}_desc contains NaN or inf")
    inv = torch.where(norm > 0, 1.0 / torch.where(norm > 0, norm, 1.0), torch.zeros_like(norm))
    d32 = (raw_mm * inv[:, None]).contiguous()
    wh = np.zeros((n, k, 2), dtype=np.float64)
    mask = np.zeros((n, k), dtype=bool)
    bs = []
    for i, (c, b) in enumerate(zip(counts, bl, strict=False)):
        b = check_boxes(b, f"{side}_boxes[{i}]", c)
        bs.append(b)
        wh[i, :c] = b[:, 2:]
        mask[i, :c] = True
    return Side(
        raw=raw,
        d32=d32,
        mask=torch.from_numpy(mask).to(device),
        count=torch.tensor(counts, dtype=torch.float64, device=device),
        wh=torch.from_numpy(wh).to(device),
        boxes=bs,
        n=n,
        k=k,
        dim=dim,
        padded=bool(min(counts) != k),
    )


def iou_stack(side: Side, device: torch.device) -> torch.Tensor:
    """(N, K, K) float64 per-image IoU matrices (zero padded), via :func:`vpr_core.boxes.box_iou`."""
    out = np.zeros((side.n, side.k, side.k), dtype=np.float64)
    for i, b in enumerate(side.boxes):
        c = b.shape[0]
        if c:
            out[i, :c, :c] = box_iou(b, b)
    return torch.from_numpy(out).to(device)


# ---- exact nearest neighbours: float64 re-decision of float32 near-ties ------------------
def cos64(q: Side, qrows: torch.Tensor, r: Side, rrows: torch.Tensor) -> torch.Tensor:
    """``(t,)`` float64 cosines of flat query rows ``qrows`` and reference rows ``rrows``.

    ``dot(a, b) / (|a| |b|)`` with float64 norms computed once per side: equal to the pairwise
    path's ``(a / |a|) . (b / |b|)`` to a few ulp (far inside :data:`TIE_TOL`); 0 for zero rows.
    """
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


def resolve_ties(vals: torch.Tensor, best: torch.Tensor, margin: float, sim64_fn):
    """Exact (float64, TIE_TOL) nearest neighbour of near-tied rows.

    Args:
        vals: ``(n, K)`` float32 similarities of the ambiguous rows.
        best: ``(n,)`` their float32 maxima.
        margin: float32 error bound; every entry within it of the max is a candidate.
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


# ---- Eq. (1) for one block of image pairs ------------------------------------------------
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
    # below. The passes run one query image at a time, so that its slice of `s` (and of the
    # scratch map) stays in the L2 cache from the first pass to the last.
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
    rv: torch.Tensor,
    cv: torch.Tensor,
    ri: torch.Tensor,
    ci: torch.Tensor,
    amb_r: torch.Tensor,
    amb_c: torch.Tensor,
) -> torch.Tensor:
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


def score_block(
    s: torch.Tensor,
    q: Side,
    r: Side,
    qsel: Selection,
    rsel: Selection,
    margin: float,
    nms: tuple | None,
    s64: torch.Tensor | None = None,
    work: torch.Tensor | None = None,
) -> torch.Tensor:
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
