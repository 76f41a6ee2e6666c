"""The block engine: Eq. (1) with Eq. (2) and optional Algorithm 4 for blocks of image pairs, the
same numbers for blocks of pairs (reference: matching/pairwise.py, one pair in float64). Inputs
prepared in :mod:`._sides`, matches found in :mod:`.reciprocal`, public entry points in
:mod:`.similarity`; definitions in docs/DEFINITIONS.md (Matching)."""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
import torch

from ..boxes import box_iou
from ._sides import (
    PAD,
    LandmarkSets,
    Selection,
    Side,
    check_same_dim,
    prepare_side,
    selection_index,
    selection_size,
)
from .reciprocal import TIE_TOL, reciprocal

if TYPE_CHECKING:
    from .spec import Compute, Matching

__all__ = [
    "BLOCK_BYTES",
    "NMS_TIE_TOL",
    "SPATIAL_TAU",
    "BlockPairs",
    "Matches",
    "Problem",
    "score_block",
    "shape_terms",
    "soft_nms",
]

#: Soft-NMS: current pair scores closer than this to the best are ties (lowest pair index wins).
NMS_TIE_TOL = 1e-9
#: Bytes of matmul output per block: big enough for an efficient matmul, small enough that the
#: reductions that follow read it from the L2/L3 cache.
BLOCK_BYTES = 8 << 20
#: (Not in the paper.) Width of the ``spatial="consistency"`` Gaussian, in units of the image's
#: landmark extent (0.1: a match displaced a tenth of the image from the consensus keeps 61%).
SPATIAL_TAU = 0.1


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


class _SoftNMS(NamedTuple):
    """Algorithm 4's settings and every image's box IoUs ``(N, K, K)`` per side."""

    iou_q: torch.Tensor
    iou_r: torch.Tensor
    t: float
    sigma: float


def soft_nms(
    scores: torch.Tensor,
    alive: torch.Tensor,
    oq: torch.Tensor,
    orf: torch.Tensor,
    nms: _SoftNMS,
) -> torch.Tensor:
    """Algorithm 4 (soft-NMS, overlap Scheme 2) on G image pairs in lockstep.

    Args:
        scores: ``(G, P)`` float64 pair scores (pairs in query-landmark order).
        alive: ``(G, P)`` bool real pairs.
        oq: ``(G, P, P)`` IoU of the query boxes of two pairs.
        orf: ``(G, P, P)`` IoU of the reference boxes of two pairs.
        nms: Algorithm 4's threshold ``t`` and Gaussian width ``sigma``.

    Returns:
        ``(G, P)`` rescaled scores (undefined where not alive).
    """
    o = torch.minimum(oq, orf)
    decay = torch.where(o > nms.t, torch.exp(-(o * o) / nms.sigma), torch.ones_like(o))
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
    m: Matches,
    iou_q: torch.Tensor,
    iou_r: torch.Tensor,
    nms: _SoftNMS,
    weight: torch.Tensor | None = None,
    group: int = 1024,
) -> torch.Tensor:
    """:func:`soft_nms` on every image pair of a block with at least two reciprocal pairs.

    Args:
        score: ``(nq, nr, Kq)`` pair scores per query landmark (times ``weight`` when given);
            shp: their Eq. (2) penalties.
        m: the block's matches (with their float64 cosines ``cos64``).
        iou_q: ``(nq, Kq, Kq)``; iou_r: ``(nr, Kr, Kr)`` the block's box IoUs.
        nms: Algorithm 4's ``t`` and ``sigma``.
        weight: ``(nq, nr, Kq)`` weights of the terms (spatial, database) or None.

    Returns:
        ``(nq, nr, Kq)`` rescaled scores (unchanged where not matched).
    """
    recip, ri_p, cos64 = m.recip, m.nn, m.cos64
    assert cos64 is not None
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
        cos = cos64[gq, gr].gather(1, order)[alive].clamp(-1.0, 1.0)
        sc = torch.zeros(alive.shape, dtype=torch.float64, device=score.device)
        sc[alive] = 1.0 - (1.0 - cos) * shp[gq, gr].gather(1, order)[alive]
        if weight is not None:
            sc[alive] *= weight[gq, gr].gather(1, order)[alive]
        oq = iou_q[gq[:, None, None], ii[:, :, None], ii[:, None, :]]
        orf = iou_r[gr[:, None, None], jj[:, :, None], jj[:, None, :]]
        new = soft_nms(sc, alive, oq, orf, nms)
        rows = score[gq, gr]
        rows.scatter_(1, order, torch.where(alive, new, sc))
        score[gq, gr] = rows
    return score


# ---- (not in the paper) geometry-aware re-scoring -----------------------------------------
def _spatial_weights(
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
    nq = selection_size(qsel)
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
class Matches(NamedTuple):
    """Reciprocal nearest neighbours of ``nq x nr`` image pairs, ``(nq, nr, Kq)`` per query
    landmark ``i``: its best cosine ``b_i(r)`` in each reference, that landmark ``j``, and
    whether ``(i, j)`` is reciprocal."""

    best: torch.Tensor  # float64 b_i(r) = cos(i, j)
    nn: torch.Tensor  # int64 j
    recip: torch.Tensor  # bool
    cos64: torch.Tensor | None  # float64 cos(i, j) exact to ~1e-15 (Algorithm 4 only)


def _cat_matches(parts: list[Matches]) -> Matches:
    """The matches of several reference blocks side by side (along the reference axis)."""
    cos = None if parts[0].cos64 is None else torch.cat([p.cos64 for p in parts], 1)  # type: ignore[misc]
    return Matches(
        torch.cat([p.best for p in parts], 1),
        torch.cat([p.nn for p in parts], 1),
        torch.cat([p.recip for p in parts], 1),
        cos,
    )


class BlockPairs(NamedTuple):
    """Reciprocal pairs of a block and their Eq. (1) terms, one entry per pair (``(P,)`` each)."""

    g: torch.Tensor  # block-local query image
    rr: torch.Tensor  # block-local reference image
    i: torch.Tensor  # query landmark
    j: torch.Tensor  # reference landmark
    cos: torch.Tensor  # cosine, clipped to [-1, 1]
    shape: torch.Tensor  # Eq. (2) penalty
    raw: torch.Tensor  # 1 - d * s
    score: torch.Tensor  # the Eq. (1) summand (times the weights, then soft-NMS when on)
    weight: torch.Tensor  # spatial weight (not in the paper; 1 with spatial=None)
    db_weight: torch.Tensor  # database weight (not in the paper; 1 with weighting=None)


def score_block(
    prob: Problem,
    m: Matches,
    qsel: Selection,
    rsel: Selection,
    keep_pairs: bool = False,
    weight: torch.Tensor | None = None,
) -> tuple[torch.Tensor, BlockPairs | None]:
    """Eq. (1) of a block of image pairs from their reciprocal matches:
    ``S = sum over reciprocal (i, j) of (1 - d_ij * s_ij) / sqrt(n_a * n_b)``.

    Args:
        prob: both sides and the :class:`~.spec.Matching` (Algorithm 4 when ``prob.nms``; with
            ``spatial`` set each term is multiplied by its :func:`_spatial_weights`, not in the
            paper).
        m: the matches of the images ``qsel`` x ``rsel`` (:meth:`Problem.matches`).
        keep_pairs: also return the reciprocal pairs and their terms.
        weight: ``(nq, nr, Kq)`` database weights (:mod:`.weighting`) or None (not in the
            paper); they multiply the terms likewise.

    Returns:
        ``((nq, nr) float64 similarities, BlockPairs or None)``.
    """
    q, r, spatial = prob.q, prob.r, prob.matching.spatial
    nq, nr = selection_size(qsel), selection_size(rsel)
    g, rr, i = m.recip.nonzero(as_tuple=True)  # reciprocal (i, j) of image pair (g, rr)
    j = m.nn[g, rr, i]
    cos = m.best[g, rr, i].clamp(-1.0, 1.0)  # d = 1 - cos
    wq = q.wh[selection_index(qsel, g), i]  # (P, 2) box sizes
    wr = r.wh[selection_index(rsel, rr), j]
    shp = shape_terms(wq[:, 0], wr[:, 0], wq[:, 1], wr[:, 1])  # Eq. (2): s
    raw = 1.0 - (1.0 - cos) * shp  # 1 - d * s
    # (not in the paper) weights of the terms: geometry, database
    ones = torch.ones_like(raw)
    ws = ones if spatial is None else _spatial_weights(q, r, qsel, rsel, m.nn, m.recip)[g, rr, i]
    wd = ones if weight is None else weight[g, rr, i]
    w = None if spatial is None and weight is None else ws * wd if weight is not None else ws
    score = raw if w is None else raw * w
    norm = torch.sqrt(q.count[qsel][:, None] * r.count[rsel][None, :])  # sqrt(n_a * n_b)
    norm = torch.where(norm > 0, norm, torch.full_like(norm, math.inf))  # no landmark: 0
    if prob.nms is None:
        total = torch.zeros(nq * nr, dtype=torch.float64, device=norm.device)
        total.index_add_(0, g * nr + rr, score)  # the sum over each image pair's matches
        sim = total.view(nq, nr) / norm  # Eq. (1)
    else:  # Algorithm 4 rescales the terms of each image pair before the sum

        def dense(v: torch.Tensor) -> torch.Tensor:  # (P,) -> (nq, nr, Kq), 0 off the matches
            out = torch.zeros(m.recip.shape, dtype=v.dtype, device=v.device)
            out[g, rr, i] = v
            return out

        nms = prob.nms
        rescaled = _nms_block(
            dense(score),
            dense(shp),
            m,
            nms.iou_q[qsel],
            nms.iou_r[rsel],
            nms,
            None if w is None else dense(w),
        )
        sim = torch.where(m.recip, rescaled, torch.zeros_like(rescaled)).sum(2) / norm  # Eq. (1)
        score = rescaled[g, rr, i]
    pairs = BlockPairs(g, rr, i, j, cos, shp, raw, score, ws, wd) if keep_pairs else None
    return sim, pairs


# ---- one call: both sides prepared, blocks scored ----------------------------------------
def _iou_stack(side: Side, device: torch.device) -> torch.Tensor:
    """``(N, K, K)`` float64 per-image IoU matrices (zero padded), for Algorithm 4."""
    out = np.zeros((side.n, side.k, side.k), dtype=np.float64)
    for i, b in enumerate(side.boxes):
        c = b.shape[0]
        if c:
            out[i, :c, :c] = box_iou(b, b)
    return torch.from_numpy(out).to(device)


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
    """Both sides of one call, prepared once, and the values every block shares."""

    q: Side
    r: Side
    matching: Matching
    compute: Compute
    dev: torch.device
    mm_dtype: torch.dtype
    margin: float
    nms: _SoftNMS | None
    empty: bool
    #: the references of :meth:`best_cosines`, gathered once per call (key: indices, chunk size)
    gathered: dict = field(default_factory=dict, repr=False)
    #: (not in the paper) ``two_sided``'s reference statistics ``(mu, sigma)`` ``(Nr, Kr)``
    #: (:func:`.weighting.prepare_reference_stats`), None otherwise
    ref_stats: tuple[torch.Tensor, torch.Tensor] | None = field(default=None, repr=False)

    @classmethod
    def build(
        cls,
        query_desc: LandmarkSets,
        query_boxes: LandmarkSets | None,
        reference_desc: LandmarkSets,
        reference_boxes: LandmarkSets | None,
        matching: Matching,
        compute: Compute,
        sides: tuple[str, str] = ("query", "reference"),
    ) -> Problem:
        """Check both sides once and prepare them (arguments: see ``similarity_matrix``).

        Args:
            sides: names of the two sides in messages (``("a", "b")`` for one image pair).
        """
        dev = torch.device(compute.device)  # checked by Compute
        mm_dtype = torch.float32 if compute.matmul_dtype == "float32" else torch.float64
        q = prepare_side(query_desc, query_boxes, sides[0], mm_dtype, dev)
        r = prepare_side(reference_desc, reference_boxes, sides[1], mm_dtype, dev)
        dim = check_same_dim([(s.name, s.dim) for s in (q, r) if s.dim])
        # matmul dot of unit vectors: |error| <= D * unit (+ rounding); two entries' difference
        # is off by at most twice that. Entries within `margin` of a max are re-decided in
        # float64 by reciprocal._resolve_ties.
        unit = 2.0**-24 if mm_dtype == torch.float32 else 2.0**-53
        margin = 2.5 * dim * unit + 4 * unit + TIE_TOL
        empty = q.dim == 0 or r.dim == 0
        nms = None
        if matching.soft_nms_iou is not None and not empty:
            nms = _SoftNMS(
                _iou_stack(q, dev), _iou_stack(r, dev), matching.soft_nms_iou, matching.sigma
            )
        if not empty:
            q.build_caches(unit64=nms is not None)
            r.build_caches(unit64=nms is not None)
        return cls(q, r, matching, compute, dev, mm_dtype, margin, nms, empty)

    def matches(self, qsel: Selection, rsel: Selection) -> Matches:
        """Reciprocal nearest neighbours of the images ``qsel`` x ``rsel`` (one matmul)."""
        q, r = self.q, self.r
        a = q.images(qsel)
        b = r.images(rsel)
        n = a.shape[0] * b.shape[0]
        buf, work = _buffers(n, q.k * b.shape[0], self.mm_dtype, self.dev)
        s = torch.matmul(a, b.T, out=buf[:n].view(a.shape[0], b.shape[0]))
        rv, ri_p, recip = reciprocal(s, q, r, qsel, rsel, self.margin, work)
        cos64 = None
        if self.nms is not None:
            # float64 cosines for soft-NMS scores: Algorithm 4's argmax is discontinuous at
            # ties, so its scores must be exact to ~1e-15
            s64 = (q.unit_images64(qsel) @ r.unit_images64(rsel).T).view(
                a.shape[0] // q.k, q.k, b.shape[0] // r.k, r.k
            )
            cos64 = s64.permute(0, 2, 1, 3).gather(3, ri_p.unsqueeze(3)).squeeze(3)
        return Matches(rv.permute(0, 2, 1), ri_p, recip, cos64)

    def block(
        self, qsel: Selection, rsel: Selection, keep_pairs: bool = False
    ) -> tuple[torch.Tensor, BlockPairs | None]:
        """Eq. (1) of the images ``qsel`` x ``rsel``: ``((nq, nr) float64, pairs or None)``."""
        return score_block(self, self.matches(qsel, rsel), qsel, rsel, keep_pairs)

    def chunked(self, qsel: Selection, refs: torch.Tensor | slice, size: int) -> Matches:
        """The matches of ``qsel`` x ``refs`` (a slice or indices), ``size`` references a matmul."""
        if isinstance(refs, slice):
            sels: list[Selection] = [
                slice(r0, min(r0 + size, refs.stop)) for r0 in range(refs.start, refs.stop, size)
            ]
        else:
            sels = [refs[c0 : c0 + size] for c0 in range(0, int(refs.numel()), size)]
        return _cat_matches([self.matches(qsel, s) for s in sels])

    def best_cosines(self, qsel: Selection, refs: torch.Tensor, size: int) -> Matches:
        """The best cosines ``b_i(r)`` of ``qsel``'s landmarks over each reference in ``refs``:
        each the maximum of one row of a matmul of ``qsel``'s landmarks x ``size`` references'
        landmarks (matmul dtype, padded landmarks never win), with no reciprocal test (``nn``
        -1, ``recip`` False): what ``contrast``'s statistics read (:mod:`.weighting`)."""
        q, r = self.q, self.r
        a = q.images(qsel)
        nq = a.shape[0] // q.k
        key = (refs.cpu().numpy().tobytes(), size)
        chunks = self.gathered.get(key)
        if chunks is None:  # the same references for every query of a call: gathered once
            sels = [refs[c0 : c0 + size] for c0 in range(0, int(refs.numel()), size)]
            chunks = [(sel.numel(), r.images(sel), ~r.mask[sel][None, None]) for sel in sels]
            self.gathered[key] = chunks
        parts = []
        for n, b, pad in chunks:
            s = (a @ b.T).view(nq, q.k, n, r.k)
            if r.padded:
                s.masked_fill_(pad, PAD)
            parts.append(s.amax(3))
        best = torch.cat(parts, 2).permute(0, 2, 1).to(torch.float64)  # (nq, ns, Kq)
        nn = torch.full(best.shape, -1, dtype=torch.int64, device=best.device)
        none = torch.zeros(best.shape, dtype=torch.bool, device=best.device)
        return Matches(best, nn, none, None)
