"""The one matching core: Eq. (1) with Eq. (2) and optional Algorithm 4 for blocks of image pairs.

Definitions: ``docs/DEFINITIONS.md`` (Matching). Public entry points: :mod:`.similarity`.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple, Union

import numpy as np
import torch

from ..boxes import box_iou
from ..checks import check_boxes, check_choice, check_range

__all__ = [
    "NMS_TIE_TOL",
    "SPATIAL_OPTIONS",
    "SPATIAL_TAU",
    "TIE_TOL",
    "BlockPairs",
    "LandmarkSets",
    "Problem",
    "Selection",
    "check_spatial",
    "reciprocal",
    "rescale_rows",
    "resolve_ties",
    "score_block",
    "shape_terms",
    "soft_nms",
    "spatial_weights",
    "unit_rows",
]

#: Cosine similarities closer than this to the row/column best are ties (lowest index wins).
TIE_TOL = 1e-9
#: Soft-NMS: current pair scores closer than this to the best are ties (lowest pair index wins).
NMS_TIE_TOL = 1e-9
#: Rows whose max-abs lies outside this range are rescaled before any norm: inside it, a float32
#: sum of D < 2^28 squares neither overflows nor underflows.
SAFE_MAGNITUDE = (2.0**-60, 2.0**50)
#: Below any cosine: padded landmarks never win an argmax.
PAD = -4.0
#: Bytes of matmul output per block: big enough for an efficient matmul, small enough that the
#: reductions that follow read it from the L2/L3 cache.
BLOCK_BYTES = 8 << 20
#: (Not in the paper.) Names of the geometry-aware re-scorings of ``spatial=``
#: (docs/DEFINITIONS.md, "(not in the paper) geometry-aware score").
SPATIAL_OPTIONS = ("consistency",)
#: (Not in the paper.) Width of the ``spatial="consistency"`` Gaussian, in units of the image's
#: landmark extent (0.1: a match displaced a tenth of the image from the consensus keeps 61%).
SPATIAL_TAU = 0.1

LandmarkSets = Union[np.ndarray, Sequence[np.ndarray]]  # noqa: UP007
#: Images of one side in a block: a contiguous range or an int64 index tensor.
Selection = Union[slice, torch.Tensor]  # noqa: UP007


# ---- safe unit descriptors ---------------------------------------------------------------
def rescale_rows(x: np.ndarray) -> np.ndarray:
    """Scale rows of huge or tiny magnitude by a power of two so that no norm over/underflows.

    A row whose max-abs lies outside :data:`SAFE_MAGNITUDE` is multiplied by ``2^-e`` (exact) so
    its max-abs lands in ``[0.5, 1)``; cosines do not change. Other rows (and NaN / inf rows)
    keep their bits; ``x`` itself is never modified.

    Args:
        x: ``(..., D)`` float array.

    Returns:
        ``x`` when no row needed it, else a rescaled copy.
    """
    if x.size == 0:
        return x
    mag = np.maximum(x.max(axis=-1), -x.min(axis=-1))  # max-abs without an |x| temporary
    low, high = SAFE_MAGNITUDE
    bad = (mag > 0) & ((mag > high) | (mag < low)) & np.isfinite(mag)
    if not bad.any():
        return x
    exp = np.where(bad, np.frexp(mag)[1], 0)
    return np.ldexp(x, -exp[..., None]).astype(x.dtype, copy=False)


def unit_rows(x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Rows scaled to unit L2 norm (zero rows stay zero: cosine 0 with everything).

    Args:
        x: ``(N, D)`` rows, already through :func:`rescale_rows`.

    Returns:
        ``(unit (N, D), norm (N,))`` in ``x``'s dtype; a NaN / inf row shows in its norm.
    """
    norm = torch.linalg.vector_norm(x, dim=1)
    inv = torch.where(norm > 0, 1.0 / torch.where(norm > 0, norm, 1.0), torch.zeros_like(norm))
    return x * inv[:, None], norm


# ---- padded landmark sets ----------------------------------------------------------------
@dataclass
class Side:
    """Padded landmark sets of one side: ``N`` images zero padded to ``K = max K_i`` landmarks."""

    name: str  # "query", "reference", "a", "b": used in messages
    raw: torch.Tensor  # (N*K, D) descriptors as given (float32/float64, rescaled), zero padded
    d32: torch.Tensor  # (N*K, D) unit rows, matmul dtype
    mask: torch.Tensor  # (N, K) bool valid landmark
    count: torch.Tensor  # (N,) float64 number of landmarks
    wh: torch.Tensor  # (N, K, 2) float64 box sizes
    xy: torch.Tensor  # (N, K, 2) float64 box centres in units of the image's landmark extent
    boxes: list[np.ndarray]
    n: int
    k: int
    dim: int
    padded: bool

    _norm64: torch.Tensor | None = None
    _unit64: torch.Tensor | None = None

    def images(self, sel: Selection) -> torch.Tensor:
        """``(n * K, D)`` unit matmul-dtype descriptors of the images ``sel`` (a slice: a view)."""
        if isinstance(sel, slice):
            return self.d32[sel.start * self.k : sel.stop * self.k]
        return self.d32.view(self.n, self.k, -1).index_select(0, sel).view(-1, self.dim)

    def unit_images64(self, sel: Selection) -> torch.Tensor:
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
    desc: LandmarkSets,
    boxes: LandmarkSets | None,
    side: str,
    mm_dtype: torch.dtype,
    device: torch.device,
) -> Side:
    """Parse and check one side's landmark sets (the boundary check), pad and normalise them.

    Args:
        desc: sequence of ``(K_i, D)`` arrays or one ``(N, K, D)`` array.
        boxes: sequence of ``(K_i, 4)`` ``(x, y, w, h)`` arrays or ``(N, K, 4)``; None: no boxes
            (sizes 0, for the reciprocal matches alone).
        side: ``"query"`` / ``"reference"`` (messages name ``query_desc[i]``), or ``"a"`` / ``"b"``
            for one image (``desc_a``, ``boxes_a``).
        mm_dtype: dtype of the unit descriptors used in the matmul.
        device: torch device of every tensor.
    """
    one = side in ("a", "b")
    dname, bname = (f"desc_{side}", f"boxes_{side}") if one else (f"{side}_desc", f"{side}_boxes")

    def item(name: str, i: int) -> str:
        return name if one else f"{name}[{i}]"

    if isinstance(desc, (np.ndarray, torch.Tensor)) and np.ndim(desc) == 3:
        stacked = np.asarray(desc.detach().cpu() if isinstance(desc, torch.Tensor) else desc)
        if stacked.dtype not in (np.float32, np.float64):
            stacked = stacked.astype(np.float64)
        n, k, dim = stacked.shape
        counts = [k] * n
    else:
        dl = _as_list(desc, dname, "D")
        n = len(dl)
        dl = [np.zeros((0, 0)) if d.ndim == 1 and d.size == 0 else d for d in dl]
        for i, d in enumerate(dl):
            if d.ndim != 2:
                raise ValueError(f"{item(dname, i)} must be (K, D), got shape {d.shape}")
        dims = sorted({d.shape[1] for d in dl if d.shape[0]})
        if len(dims) > 1:
            raise ValueError(f"{dname} mixes descriptor dimensions {dims}")
        dim = dims[0] if dims else 0
        counts = [d.shape[0] for d in dl]
        k = max(counts + [1])
        dtype = np.float32 if all(d.dtype == np.float32 for d in dl) else np.float64
        stacked = np.zeros((n, k, dim), dtype=dtype)
        for i, d in enumerate(dl):
            if d.shape[0]:
                stacked[i, : d.shape[0]] = d
    bl = [np.zeros((c, 4)) for c in counts] if boxes is None else _as_list(boxes, bname, "4")
    if len(bl) != n:
        raise ValueError(f"{dname} has {n} images but {bname} has {len(bl)}")
    if n == 0:
        raise ValueError(f"{dname} is empty")
    stacked = rescale_rows(stacked)
    raw = torch.from_numpy(np.ascontiguousarray(stacked)).to(device).reshape(n * k, dim)
    d32, norm = unit_rows(raw.to(mm_dtype))
    if not bool(torch.isfinite(norm).all()):  # NaN / inf anywhere shows in the norm
        raise ValueError(f"{dname} contains NaN or inf")
    wh = np.zeros((n, k, 2), dtype=np.float64)
    xy = np.zeros((n, k, 2), dtype=np.float64)
    mask = np.zeros((n, k), dtype=bool)
    bs = []
    for i, (c, b) in enumerate(zip(counts, bl, strict=True)):
        b = check_boxes(b, item(bname, i), c)
        bs.append(b)
        wh[i, :c] = b[:, 2:]
        xy[i, :c] = normalised_centres(b)
        mask[i, :c] = True
    return Side(
        name=dname,
        raw=raw,
        d32=d32.contiguous(),
        mask=torch.from_numpy(mask).to(device),
        count=torch.tensor(counts, dtype=torch.float64, device=device),
        wh=torch.from_numpy(wh).to(device),
        xy=torch.from_numpy(xy).to(device),
        boxes=bs,
        n=n,
        k=k,
        dim=dim,
        padded=bool(min(counts) != k),
    )


def normalised_centres(boxes: np.ndarray) -> np.ndarray:
    """Box centres in units of the extent of all the image's boxes (not in the paper).

    Args:
        boxes: ``(K, 4)`` float64 ``(x, y, w, h)`` boxes of one image.

    Returns:
        ``(K, 2)`` ``((cx - x0) / W, (cy - y0) / H)``: ``x0``, ``W`` the left edge and width of
        the boxes' union bounding box (``W = 1`` when it is 0), likewise ``y0``, ``H``.
    """
    if boxes.shape[0] == 0:
        return np.zeros((0, 2), dtype=np.float64)
    lo = boxes[:, :2].min(axis=0)
    ext = (boxes[:, :2] + boxes[:, 2:]).max(axis=0) - lo
    ext = np.where(ext > 0, ext, 1.0)
    return (boxes[:, :2] + 0.5 * boxes[:, 2:] - lo) / ext


def iou_stack(side: Side, device: torch.device) -> torch.Tensor:
    """``(N, K, K)`` float64 per-image IoU matrices (zero padded)."""
    out = np.zeros((side.n, side.k, side.k), dtype=np.float64)
    for i, b in enumerate(side.boxes):
        c = b.shape[0]
        if c:
            out[i, :c, :c] = box_iou(b, b)
    return torch.from_numpy(out).to(device)


# ---- near-ties: the one place they are decided -------------------------------------------
def cos64(q: Side, qrows: torch.Tensor, r: Side, rrows: torch.Tensor) -> torch.Tensor:
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


def resolve_ties(vals: torch.Tensor, best: torch.Tensor, margin: float, sim64_fn):
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
    # (resolve_ties). The passes run one query image at a time, so that its slice of `s` (and of
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
    rv: torch.Tensor,
    cv: torch.Tensor,
    ri: torch.Tensor,
    ci: torch.Tensor,
    amb_r: torch.Tensor,
    amb_c: torch.Tensor,
) -> torch.Tensor:
    """Re-decide ambiguous rows (``amb_r``) and columns (``amb_c``) by :func:`resolve_ties`.

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
    ri_p = ri.permute(0, 2, 1)  # per image pair layout (nq, nr, Kq)
    recip = ci.gather(2, ri_p) == torch.arange(q.k, device=s.device)
    if q.padded:
        recip &= qmask[:, None, :]
    if r.padded or not bool(has_r.all()):
        recip &= rmask.unsqueeze(0).expand(nq, -1, -1).gather(2, ri_p)
    return rv, ri_p, recip


# ---- Eq. (2) and Algorithm 4 -------------------------------------------------------------
def shape_terms(
    wa: torch.Tensor, wb: torch.Tensor, ha: torch.Tensor, hb: torch.Tensor
) -> torch.Tensor:
    """Eq. (2) shape penalty from broadcastable widths and heights (a 0/0 term counts as 0)."""

    def term(u: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
        m = torch.maximum(u, v)
        safe = torch.where(m > 0, m, torch.ones_like(m))
        return torch.where(m > 0, torch.abs(u - v) / safe, torch.zeros_like(m))

    return torch.exp(0.5 * (term(wa, wb) + term(ha, hb)))


def soft_nms(
    scores: torch.Tensor,
    alive: torch.Tensor,
    oq: torch.Tensor,
    orf: torch.Tensor,
    t: float,
    sigma: float,
) -> torch.Tensor:
    """Algorithm 4 (soft-NMS, overlap Scheme 2) on G image pairs in lockstep.

    Args:
        scores: ``(G, P)`` float64 pair scores (pairs in query-landmark order).
        alive: ``(G, P)`` bool real pairs.
        oq: ``(G, P, P)`` IoU of the query boxes of two pairs.
        orf: ``(G, P, P)`` IoU of the reference boxes of two pairs.
        t: threshold; sigma: Gaussian width.

    Returns:
        ``(G, P)`` rescaled scores (undefined where not alive).
    """
    o = torch.minimum(oq, orf)
    decay = torch.where(o > t, torch.exp(-(o * o) / sigma), torch.ones_like(o))
    del o
    g = scores.shape[0]
    cur = scores.clone()
    out = scores.clone()
    alive = alive.clone()
    ar = torch.arange(g, device=scores.device)
    neg = torch.tensor(-math.inf, dtype=scores.dtype, device=scores.device)
    for _ in range(int(alive.sum(1).max().item()) if g else 0):
        masked = torch.where(alive, cur, neg)
        mx = masked.amax(1, keepdim=True)
        m = (masked >= mx - NMS_TIE_TOL).to(torch.uint8).argmax(1)  # lowest tied pair index
        has = alive[ar, m]
        out[ar, m] = torch.where(has, cur[ar, m], out[ar, m])
        alive[ar, m] = False
        cur = cur * decay[ar, m]
    return out


def _nms_block(
    score: torch.Tensor,
    shp: torch.Tensor,
    recip: torch.Tensor,
    ri_p: torch.Tensor,
    s64: torch.Tensor,
    iou_q: torch.Tensor,
    iou_r: torch.Tensor,
    t: float,
    sigma: float,
    weight: torch.Tensor | None = None,
    group: int = 1024,
) -> torch.Tensor:
    """:func:`soft_nms` on every image pair of a block with at least two reciprocal pairs.

    Args:
        score: ``(nq, nr, Kq)`` pair scores per query landmark (times ``weight`` when given);
            shp: their Eq. (2) penalties.
        recip: ``(nq, nr, Kq)`` bool reciprocal; ri_p: ``(nq, nr, Kq)`` matched reference landmark.
        s64: ``(nq, Kq, nr, Kr)`` float64 cosines of the block.
        iou_q: ``(nq, Kq, Kq)``; iou_r: ``(nr, Kr, Kr)`` per-image box IoUs.
        t, sigma: soft-NMS parameters.
        weight: ``(nq, nr, Kq)`` spatial weights (:func:`spatial_weights`) or None.

    Returns:
        ``(nq, nr, Kq)`` rescaled scores (unchanged where not matched).
    """
    npair = recip.sum(2)
    qi, rj = (npair > 1).nonzero(as_tuple=True)  # soft-NMS is the identity below 2 matches
    if qi.numel() == 0:
        return score
    score = score.clone()
    for s0 in range(0, qi.numel(), group):
        gq, gr = qi[s0 : s0 + group], rj[s0 : s0 + group]
        alive0 = recip[gq, gr]  # (G, Kq)
        p = int(npair[gq, gr].max().item())
        # compact matched landmarks to the front, keeping query-landmark order (pair index)
        order = torch.argsort((~alive0).to(torch.int8), dim=1, stable=True)[:, :p]
        alive = alive0.gather(1, order)
        ii = order
        jj = ri_p[gq, gr].gather(1, order)
        # float64 cosines of the matched pairs: the argmax of Algorithm 4 is discontinuous at
        # ties, so the scores must be exact to ~1e-15, not just ~1e-7
        cos = s64[gq[:, None], ii, gr[:, None], jj][alive].clamp(-1.0, 1.0)
        sc = torch.zeros(alive.shape, dtype=torch.float64, device=score.device)
        sc[alive] = 1.0 - (1.0 - cos) * shp[gq, gr].gather(1, order)[alive]
        if weight is not None:
            sc[alive] *= weight[gq, gr].gather(1, order)[alive]
        oq = iou_q[gq[:, None, None], ii[:, :, None], ii[:, None, :]]
        orf = iou_r[gr[:, None, None], jj[:, :, None], jj[:, None, :]]
        new = soft_nms(sc, alive, oq, orf, t, sigma)
        rows = score[gq, gr]
        rows.scatter_(1, order, torch.where(alive, new, sc))
        score[gq, gr] = rows
    return score


# ---- (not in the paper) geometry-aware re-scoring -----------------------------------------
def spatial_weights(
    q: Side,
    r: Side,
    qsel: Selection,
    rsel: Selection,
    ri_p: torch.Tensor,
    recip: torch.Tensor,
    tau: float = SPATIAL_TAU,
) -> torch.Tensor:
    """``spatial="consistency"`` weights of a block's reciprocal pairs (not in the paper).

    Each pair's displacement (query centre minus reference centre, :attr:`Side.xy`) is compared
    with the median displacement of its image pair's matches (per coordinate; the mean of the two
    middle values for an even count): ``w = exp(-|delta - median|^2 / (2 tau^2))``.

    Args:
        q, r, qsel, rsel: the sides and the block's images.
        ri_p: ``(nq, nr, Kq)`` matched reference landmark; recip: ``(nq, nr, Kq)`` bool.
        tau: Gaussian width in extent units.

    Returns:
        ``(nq, nr, Kq)`` float64 weights in ``(0, 1]`` (1 where not reciprocal).
    """
    nq = _size(qsel)
    xq = q.xy[qsel].unsqueeze(1)  # (nq, 1, Kq, 2)
    xr = r.xy[rsel].unsqueeze(0).expand(nq, -1, -1, -1)  # (nq, nr, Kr, 2)
    xr = xr.gather(2, ri_p.unsqueeze(3).expand(-1, -1, -1, 2))  # (nq, nr, Kq, 2)
    delta = xq - xr
    srt = torch.where(recip.unsqueeze(3), delta, math.inf).sort(dim=2).values
    p = recip.sum(2, keepdim=True)  # (nq, nr, 1) matches per image pair
    lo = ((p - 1).clamp(min=0) // 2).unsqueeze(3).expand(-1, -1, 1, 2)
    hi = (p // 2).clamp(max=q.k - 1).unsqueeze(3).expand(-1, -1, 1, 2)
    med = 0.5 * (srt.gather(2, lo) + srt.gather(2, hi))  # (nq, nr, 1, 2)
    dev2 = ((delta - med) ** 2).sum(3)
    w = torch.exp(-dev2 / (2.0 * tau * tau))
    return torch.where(recip, w, torch.ones_like(w))


# ---- Eq. (1) for one block of image pairs ------------------------------------------------
class BlockPairs(NamedTuple):
    """Reciprocal pairs of a block and their Eq. (1) terms, one entry per pair (``(P,)`` each)."""

    g: torch.Tensor  # block-local query image
    rr: torch.Tensor  # block-local reference image
    i: torch.Tensor  # query landmark
    j: torch.Tensor  # reference landmark
    cos: torch.Tensor  # cosine, clipped to [-1, 1]
    shape: torch.Tensor  # Eq. (2) penalty
    raw: torch.Tensor  # 1 - d * s
    score: torch.Tensor  # the Eq. (1) summand (times `weight`, then soft-NMS when on)
    weight: torch.Tensor  # spatial weight (not in the paper; 1 with spatial=None)


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
    keep_pairs: bool = False,
    spatial: str | None = None,
) -> tuple[torch.Tensor, BlockPairs | None]:
    """Eq. (1) for a block of image pairs from its landmark cosines.

    Args:
        s: ``(nq * Kq, nr * Kr)`` cosines (matmul dtype) of queries ``qsel`` x references
            ``rsel``; padded entries are overwritten in place.
        q, r: prepared sides; margin: float error bound of ``s``.
        nms: ``(iou_q, iou_r, t, sigma)`` or None.
        s64: ``(nq, Kq, nr, Kr)`` float64 cosines (soft-NMS only).
        work: flat scratch buffer of ``s``'s dtype (see :func:`reciprocal`), or None.
        keep_pairs: also return the reciprocal pairs and their terms.
        spatial: None (the paper) or a name in :data:`SPATIAL_OPTIONS`: each term ``1 - d * s``
            is multiplied by its :func:`spatial_weights` before soft-NMS and the sum.

    Returns:
        ``((nq, nr) float64 similarities, BlockPairs or None)``.
    """
    nq, nr = _size(qsel), _size(rsel)
    rv, ri_p, recip = reciprocal(s, q, r, qsel, rsel, margin, work)
    norm = torch.sqrt(q.count[qsel][:, None] * r.count[rsel][None, :])
    norm = torch.where(norm > 0, norm, torch.full_like(norm, math.inf))  # no landmark: 0
    # (not in the paper) geometry-aware re-scoring: weights multiply 1 - d * s before soft-NMS
    wt = None if spatial is None else spatial_weights(q, r, qsel, rsel, ri_p, recip)
    if nms is None:
        # only the reciprocal pairs (a fraction of all query landmarks)
        g, rr, i = recip.nonzero(as_tuple=True)  # sorted: pair (g, rr), then landmark i
        j = ri_p[g, rr, i]
        cos = rv[g, i, rr].clamp(-1.0, 1.0)
        wq = q.wh[_image_index(qsel, g), i]  # (P, 2)
        wr = r.wh[_image_index(rsel, rr), j]
        shp = shape_terms(wq[:, 0], wr[:, 0], wq[:, 1], wr[:, 1])
        raw = 1.0 - (1.0 - cos) * shp  # 1 - d * s
        w = torch.ones_like(raw) if wt is None else wt[g, rr, i]
        score = raw if wt is None else raw * w
        total = torch.zeros(nq * nr, dtype=torch.float64, device=s.device)
        total.index_add_(0, g * nr + rr, score)
        sim = total.view(nq, nr) / norm  # Eq. (1)
        pairs = BlockPairs(g, rr, i, j, cos, shp, raw, score, w) if keep_pairs else None
        return sim, pairs
    cos_p = rv.permute(0, 2, 1).clamp(-1.0, 1.0)  # (nq, nr, Kq)
    wh_q = q.wh[qsel].unsqueeze(1)  # (nq, 1, Kq, 2)
    wh_r = r.wh[rsel].unsqueeze(0).expand(nq, -1, -1, -1)  # (nq, nr, Kr, 2)
    wh_r = wh_r.gather(2, ri_p.unsqueeze(3).expand(-1, -1, -1, 2))  # (nq, nr, Kq, 2)
    shp_p = shape_terms(wh_q[..., 0], wh_r[..., 0], wh_q[..., 1], wh_r[..., 1])
    raw_p = 1.0 - (1.0 - cos_p) * shp_p  # 1 - d * s
    iou_q, iou_r, t, sigma = nms
    assert s64 is not None
    score_p = _nms_block(
        raw_p if wt is None else raw_p * wt,
        shp_p,
        recip,
        ri_p,
        s64,
        iou_q[qsel],
        iou_r[rsel],
        t,
        sigma,
        wt,
    )
    sim = torch.where(recip, score_p, torch.zeros_like(score_p)).sum(2) / norm  # Eq. (1)
    pairs = None
    if keep_pairs:
        g, rr, i = recip.nonzero(as_tuple=True)
        at = (g, rr, i)
        w_at = torch.ones_like(raw_p[at]) if wt is None else wt[at]
        pairs = BlockPairs(g, rr, i, ri_p[at], cos_p[at], shp_p[at], raw_p[at], score_p[at], w_at)
    return sim, pairs


# ---- one call: both sides prepared, blocks scored ----------------------------------------
def check_spatial(spatial: str | None) -> str | None:
    """``spatial`` if it is None or a name in :data:`SPATIAL_OPTIONS`; else a clear error."""
    if spatial is not None and spatial not in SPATIAL_OPTIONS:
        raise ValueError(
            f"unknown spatial {spatial!r} (geometry-aware score, not in the paper); "
            f"valid: None, {', '.join(repr(n) for n in SPATIAL_OPTIONS)}"
        )
    return spatial


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


@dataclass
class Problem:
    """Both sides of one call, checked and prepared once, and the settings every block shares."""

    q: Side
    r: Side
    dev: torch.device
    mm_dtype: torch.dtype
    margin: float
    nms: tuple | None
    empty: bool
    spatial: str | None = None

    @classmethod
    def build(
        cls,
        query_desc: LandmarkSets,
        query_boxes: LandmarkSets | None,
        reference_desc: LandmarkSets,
        reference_boxes: LandmarkSets | None,
        soft_nms_iou: float | None,
        sigma: float,
        device: str | torch.device = "cpu",
        matmul_dtype: str = "float32",
        sides: tuple[str, str] = ("query", "reference"),
        spatial: str | None = None,
    ) -> Problem:
        """Check every input once and prepare both sides (arguments: see ``similarity_matrix``).

        Args:
            sides: names of the two sides in messages (``("a", "b")`` for one image pair).
        """
        if soft_nms_iou is not None:
            check_range(soft_nms_iou, "soft_nms_iou (Algorithm 4 threshold, or None)", 0.0, 1.0)
        check_range(sigma, "sigma (soft-NMS width)", 0.0, low_open=True)
        check_choice(matmul_dtype, "matmul_dtype", ("float32", "float64"))
        check_spatial(spatial)
        dev = torch.device(device)
        if dev.type == "cuda" and not torch.cuda.is_available():
            raise ValueError(f"device={device!r} but torch sees no CUDA GPU; use device='cpu'")
        mm_dtype = torch.float32 if matmul_dtype == "float32" else torch.float64
        q = prepare_side(query_desc, query_boxes, sides[0], mm_dtype, dev)
        r = prepare_side(reference_desc, reference_boxes, sides[1], mm_dtype, dev)
        if q.dim and r.dim and q.dim != r.dim:
            raise ValueError(
                f"descriptor dimensions differ: {q.name} D={q.dim}, {r.name} D={r.dim}"
            )
        dim = max(q.dim, r.dim)
        # matmul dot of unit vectors: |error| <= D * unit (+ rounding); two entries' difference
        # is off by at most twice that. Entries within `margin` of a max are re-decided in
        # float64 by resolve_ties.
        unit = 2.0**-24 if mm_dtype == torch.float32 else 2.0**-53
        margin = 2.5 * dim * unit + 4 * unit + TIE_TOL
        empty = q.dim == 0 or r.dim == 0
        nms = None
        if soft_nms_iou is not None and not empty:
            nms = (iou_stack(q, dev), iou_stack(r, dev), float(soft_nms_iou), float(sigma))
        if not empty:
            q.build_caches(unit64=nms is not None)
            r.build_caches(unit64=nms is not None)
        return cls(q, r, dev, mm_dtype, margin, nms, empty, spatial)

    def block(
        self, qsel: Selection, rsel: Selection, keep_pairs: bool = False
    ) -> tuple[torch.Tensor, BlockPairs | None]:
        """Eq. (1) of the images ``qsel`` x ``rsel``: ``((nq, nr) float64, pairs or None)``."""
        q, r = self.q, self.r
        a = q.images(qsel)
        b = r.images(rsel)
        n = a.shape[0] * b.shape[0]
        buf, work = _buffers(n, q.k * b.shape[0], self.mm_dtype, self.dev)
        s = torch.matmul(a, b.T, out=buf[:n].view(a.shape[0], b.shape[0]))
        s64 = None
        if self.nms is not None:
            # float64 cosines for soft-NMS scores: Algorithm 4's argmax is discontinuous at
            # ties, so its scores must be exact to ~1e-15
            s64 = (q.unit_images64(qsel) @ r.unit_images64(rsel).T).view(
                a.shape[0] // q.k, q.k, b.shape[0] // r.k, r.k
            )
        return score_block(
            s, q, r, qsel, rsel, self.margin, self.nms, s64, work, keep_pairs, self.spatial
        )
