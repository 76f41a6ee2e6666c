"""Landmark matching and image similarity: Eq. (1)-(2), reciprocal NN, soft-NMS (Algorithm 4).

Two paths compute the same numbers:

* the *pairwise* path (:func:`reciprocal_matches`, :func:`match_landmarks`,
  :func:`image_similarity`) works on one image pair in NumPy float64 and is the reference;
* :func:`similarity_matrix` scores every query x reference pair at once in torch: one float32
  matmul per block of queries x references, reciprocal test by argmax both ways, and a float64
  re-check of every near-tie so that the matches are exactly those of the pairwise path. Values
  agree with :func:`image_similarity` to ~1e-6 (float32 cosines), always within 1e-5.

Definitions (``../shared/DESIGN.md`` section 2):

* cosine distance ``d = 1 - cos``; a zero descriptor has ``cos = 0`` with everything
  (so ``d = 1``); cosines are clipped to ``[-1, 1]``.
* nearest neighbour: highest cosine; cosines within :data:`TIE_TOL` of the best count as tied and
  the lowest index wins (``argmax`` semantics, robust to last-bit float differences).
* shape penalty, Eq. (2): ``s = exp(0.5 * (|wi - wj| / max(wi, wj) + |hi - hj| / max(hi, hj)))``;
  a term whose ``max`` is 0 (both sides of zero size) counts as 0.
* image similarity, Eq. (1): ``sum over reciprocal pairs of (1 - d * s) / sqrt(na * nb)`` with
  ``na``, ``nb`` all landmarks of each image; 0 when either image has no landmark.
* soft-NMS (Algorithm 4, overlap reduction scheme 2): repeatedly take the remaining pair with the
  highest (current) score (ties: lowest pair index, pairs ordered by query landmark), remove it,
  and multiply each remaining pair whose overlap with it is ``> t`` by ``exp(-overlap^2 / sigma)``,
  where the overlap of two pairs is ``min(IoU of their query boxes, IoU of their reference boxes)``.
  The pair scores at removal time replace ``1 - d * s`` in Eq. (1).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Union

import numpy as np
import torch

from .landmarks import box_iou
from .utils import progress

__all__ = [
    "NMS_TIE_TOL",
    "TIE_TOL",
    "MatchResult",
    "cosine_distance",
    "cosine_similarity",
    "image_similarity",
    "match_landmarks",
    "match_overlaps",
    "pair_scores",
    "reciprocal_matches",
    "shape_penalty",
    "similarity_matrix",
    "soft_nms_scores",
]

#: Cosine similarities closer than this to the row/column best are ties (lowest index wins).
TIE_TOL = 1e-9
#: Soft-NMS: current pair scores closer than this to the best are ties (lowest pair index wins).
NMS_TIE_TOL = 1e-9

ArrayLike = Union[np.ndarray, Sequence]  # noqa: UP007
LandmarkSets = Union[np.ndarray, Sequence[np.ndarray]]  # noqa: UP007


# ------------------------------------------------------------------------------------------
# input checks
# ------------------------------------------------------------------------------------------


def _check_desc(desc: ArrayLike, name: str) -> np.ndarray:
    d = np.asarray(desc, dtype=np.float64)
    if d.ndim != 2:
        raise ValueError(f"{name} must be a (K, D) descriptor array, got shape {d.shape}")
    if not np.all(np.isfinite(d)):
        raise ValueError(f"{name} contains NaN or inf")
    return d


def _check_boxes(boxes: ArrayLike, name: str, k: int | None = None) -> np.ndarray:
    b = np.asarray(boxes, dtype=np.float64)
    if b.ndim == 1 and b.size == 0:
        b = b.reshape(0, 4)
    if b.ndim != 2 or b.shape[1] != 4:
        raise ValueError(f"{name} must be a (K, 4) array of (x, y, w, h) boxes, got shape {b.shape}")
    if not np.all(np.isfinite(b)):
        raise ValueError(f"{name} contains NaN or inf")
    if np.any(b[:, 2:] < 0):
        raise ValueError(f"{name} has negative widths or heights")
    if k is not None and b.shape[0] != k:
        raise ValueError(f"{name} has {b.shape[0]} boxes but the descriptors have {k} rows")
    return b


def _check_pair(desc_a, boxes_a, desc_b, boxes_b):
    a = _check_desc(desc_a, "desc_a")
    b = _check_desc(desc_b, "desc_b")
    if a.shape[1] != b.shape[1]:
        raise ValueError(f"descriptor dimensions differ: desc_a D={a.shape[1]}, desc_b D={b.shape[1]}")
    ba = _check_boxes(boxes_a, "boxes_a", a.shape[0])
    bb = _check_boxes(boxes_b, "boxes_b", b.shape[0])
    return a, ba, b, bb


def _check_soft_nms(soft_nms_iou: float | None, sigma: float) -> None:
    if soft_nms_iou is not None and not (0.0 <= float(soft_nms_iou) <= 1.0):
        raise ValueError(f"soft_nms_iou must be in [0, 1] or None, got {soft_nms_iou}")
    if not float(sigma) > 0:
        raise ValueError(f"sigma must be > 0, got {sigma}")


# ------------------------------------------------------------------------------------------
# pairwise path (NumPy float64, the reference)
# ------------------------------------------------------------------------------------------


def _normalize(d: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(d, axis=1, keepdims=True)
    return d / np.where(n > 0, n, 1.0)


def cosine_similarity(desc_a: ArrayLike, desc_b: ArrayLike) -> np.ndarray:
    """Cosine similarity of every landmark pair.

    Args:
        desc_a: ``(Ka, D)`` descriptors.
        desc_b: ``(Kb, D)`` descriptors.

    Returns:
        ``(Ka, Kb)`` float64 cosines clipped to ``[-1, 1]``; 0 where either vector is zero.
    """
    a = _check_desc(desc_a, "desc_a")
    b = _check_desc(desc_b, "desc_b")
    if a.shape[1] != b.shape[1]:
        raise ValueError(f"descriptor dimensions differ: desc_a D={a.shape[1]}, desc_b D={b.shape[1]}")
    return np.clip(_normalize(a) @ _normalize(b).T, -1.0, 1.0)


def cosine_distance(desc_a: ArrayLike, desc_b: ArrayLike) -> np.ndarray:
    """Cosine distance ``d = 1 - cos`` of every landmark pair (zero vectors: ``cos = 0``, d = 1).

    Args:
        desc_a: ``(Ka, D)`` descriptors.
        desc_b: ``(Kb, D)`` descriptors.

    Returns:
        ``(Ka, Kb)`` float64 distances in ``[0, 2]``.
    """
    return 1.0 - cosine_similarity(desc_a, desc_b)


def _nn_with_ties(sim: np.ndarray, axis: int) -> np.ndarray:
    """Index of the best entry along ``axis``; entries within TIE_TOL of the best tie -> lowest."""
    best = sim.max(axis=axis, keepdims=True)
    return np.argmax(sim >= best - TIE_TOL, axis=axis)


def _reciprocal_from_sim(sim: np.ndarray) -> np.ndarray:
    ka, kb = sim.shape
    if ka == 0 or kb == 0:
        return np.zeros((0, 2), dtype=np.int64)
    nn_a = _nn_with_ties(sim, axis=1)  # (Ka,) best j for each i
    nn_b = _nn_with_ties(sim, axis=0)  # (Kb,) best i for each j
    i = np.arange(ka)
    keep = nn_b[nn_a] == i
    return np.stack([i[keep], nn_a[keep]], axis=1).astype(np.int64)


def reciprocal_matches(desc_a: ArrayLike, desc_b: ArrayLike) -> np.ndarray:
    """Reciprocal (mutual) nearest-neighbour matches under the cosine distance.

    ``(i, j)`` is kept when ``j`` is ``i``'s nearest neighbour in ``b`` and ``i`` is ``j``'s in
    ``a``. Ties (cosines within :data:`TIE_TOL`) go to the lowest index.

    Args:
        desc_a: ``(Ka, D)`` descriptors.
        desc_b: ``(Kb, D)`` descriptors.

    Returns:
        ``(P, 2)`` int64 ``(i, j)`` pairs sorted by ``i``.
    """
    return _reciprocal_from_sim(cosine_similarity(desc_a, desc_b))


def _shape_terms(wa, wb, ha, hb, xp=np):
    def term(u, v):
        m = xp.maximum(u, v)
        safe = xp.where(m > 0, m, xp.ones_like(m))
        return xp.where(m > 0, xp.abs(u - v) / safe, xp.zeros_like(m))

    return xp.exp(0.5 * (term(wa, wb) + term(ha, hb)))


def shape_penalty(boxes_a: ArrayLike, boxes_b: ArrayLike) -> np.ndarray:
    """Shape penalty of Eq. (2) for every landmark pair.

    ``s_ij = exp(0.5 * (|wi - wj| / max(wi, wj) + |hi - hj| / max(hi, hj)))`` in ``[1, e]``
    (identical sizes give 1; a term with both sizes 0 counts as 0).

    Args:
        boxes_a: ``(Ka, 4)`` ``(x, y, w, h)`` boxes.
        boxes_b: ``(Kb, 4)`` boxes.

    Returns:
        ``(Ka, Kb)`` float64.
    """
    a = _check_boxes(boxes_a, "boxes_a")
    b = _check_boxes(boxes_b, "boxes_b")
    return _shape_terms(a[:, None, 2], b[None, :, 2], a[:, None, 3], b[None, :, 3])


def match_overlaps(boxes_a: ArrayLike, boxes_b: ArrayLike, matches: ArrayLike) -> np.ndarray:
    """Overlap of every two matches: ``min(IoU of their a-boxes, IoU of their b-boxes)``.

    Args:
        boxes_a: ``(Ka, 4)`` boxes of image a.
        boxes_b: ``(Kb, 4)`` boxes of image b.
        matches: ``(P, 2)`` ``(i, j)`` index pairs.

    Returns:
        ``(P, P)`` float64 overlaps in ``[0, 1]`` (diagonal 1 for non-empty boxes).
    """
    a = _check_boxes(boxes_a, "boxes_a")
    b = _check_boxes(boxes_b, "boxes_b")
    m = np.asarray(matches, dtype=np.int64).reshape(-1, 2)
    # Full per-image IoU matrices, then gather: the batched path does the same, so the values
    # compared against the threshold are bit-identical in both paths.
    iou_a = box_iou(a, a)
    iou_b = box_iou(b, b)
    i, j = m[:, 0], m[:, 1]
    return np.minimum(iou_a[np.ix_(i, i)], iou_b[np.ix_(j, j)])


def soft_nms_scores(scores: ArrayLike, overlaps: ArrayLike, iou_threshold: float,
                    sigma: float = 0.5) -> np.ndarray:
    """Algorithm 4 (overlap reduction scheme 2): Gaussian soft-NMS of match scores.

    Repeatedly takes the remaining pair with the highest current score (scores within
    :data:`NMS_TIE_TOL` tie; the lowest index wins),
    fixes its score, removes it, and multiplies every remaining pair ``k`` with
    ``overlaps[m, k] > iou_threshold`` by ``exp(-overlaps[m, k]**2 / sigma)``.

    Args:
        scores: ``(P,)`` pair scores ``1 - d * s``.
        overlaps: ``(P, P)`` symmetric pair overlaps (see :func:`match_overlaps`).
        iou_threshold: ``t``; strictly greater overlaps are decayed.
        sigma: Gaussian width (the paper uses 0.5).

    Returns:
        ``(P,)`` float64 rescaled scores (each pair's score when it was removed).
    """
    _check_soft_nms(iou_threshold, sigma)
    cur = np.array(scores, dtype=np.float64).reshape(-1)
    p = cur.shape[0]
    o = np.asarray(overlaps, dtype=np.float64)
    if o.shape != (p, p):
        raise ValueError(f"overlaps must be ({p}, {p}) for {p} scores, got {o.shape}")
    decay = np.where(o > iou_threshold, np.exp(-(o**2) / sigma), 1.0)
    out = np.empty(p, dtype=np.float64)
    alive = np.ones(p, dtype=bool)
    for _ in range(p):
        masked = np.where(alive, cur, -np.inf)
        m = int(np.argmax(masked >= masked.max() - NMS_TIE_TOL))  # lowest tied index
        out[m] = cur[m]
        alive[m] = False
        cur *= decay[m]  # removed pairs keep their fixed value in `out`
    return out


@dataclass
class MatchResult:
    """Landmark matches of one image pair and their Eq. (1) scores.

    Attributes:
        matches: ``(P, 2)`` int64 reciprocal ``(i, j)`` pairs, sorted by ``i``.
        distances: ``(P,)`` cosine distances ``d_ij``.
        shape: ``(P,)`` shape penalties ``s_ij`` (Eq. 2).
        scores: ``(P,)`` pair scores entering Eq. (1): ``1 - d * s``, after soft-NMS if enabled.
        similarity: Eq. (1) image similarity ``scores.sum() / sqrt(na * nb)``.
        raw_scores: ``(P,)`` ``1 - d * s`` before soft-NMS.
        n_a: number of landmarks of image a.
        n_b: number of landmarks of image b.
    """

    matches: np.ndarray
    distances: np.ndarray
    shape: np.ndarray
    scores: np.ndarray
    similarity: float
    raw_scores: np.ndarray
    n_a: int
    n_b: int


def match_landmarks(desc_a: ArrayLike, boxes_a: ArrayLike, desc_b: ArrayLike, boxes_b: ArrayLike,
                    soft_nms_iou: float | None = None, sigma: float = 0.5) -> MatchResult:
    """Match the landmarks of two images and score them (Eq. 1-2, optional Algorithm 4).

    Args:
        desc_a: ``(Ka, D)`` descriptors of image a (query).
        boxes_a: ``(Ka, 4)`` ``(x, y, w, h)`` boxes of image a.
        desc_b: ``(Kb, D)`` descriptors of image b (reference).
        boxes_b: ``(Kb, 4)`` boxes of image b.
        soft_nms_iou: soft-NMS threshold ``t`` (Algorithm 4) or None for plain Eq. (1).
        sigma: soft-NMS Gaussian width.

    Returns:
        :class:`MatchResult`.
    """
    _check_soft_nms(soft_nms_iou, sigma)
    a, ba, b, bb = _check_pair(desc_a, boxes_a, desc_b, boxes_b)
    cos = cosine_similarity(a, b)
    m = _reciprocal_from_sim(cos)
    i, j = m[:, 0], m[:, 1]
    dist = 1.0 - cos[i, j]
    shp = _shape_terms(ba[i, 2], bb[j, 2], ba[i, 3], bb[j, 3])
    raw = 1.0 - dist * shp
    scores = raw
    if soft_nms_iou is not None and len(m) > 1:
        scores = soft_nms_scores(raw, match_overlaps(ba, bb, m), soft_nms_iou, sigma)
    na, nb = a.shape[0], b.shape[0]
    sim = float(scores.sum() / math.sqrt(na * nb)) if na * nb > 0 else 0.0
    return MatchResult(m, dist, shp, np.array(scores, dtype=np.float64), sim, raw, na, nb)


def pair_scores(desc_a: ArrayLike, boxes_a: ArrayLike, desc_b: ArrayLike, boxes_b: ArrayLike,
                soft_nms_iou: float | None = None, sigma: float = 0.5
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Reciprocal matches and their per-pair scores ``1 - d * s``.

    Args:
        desc_a, boxes_a, desc_b, boxes_b, soft_nms_iou, sigma: as :func:`match_landmarks`.

    Returns:
        ``(matches (P, 2), raw_scores (P,), scores (P,))``: scores before and after soft-NMS
        (equal when ``soft_nms_iou`` is None).
    """
    r = match_landmarks(desc_a, boxes_a, desc_b, boxes_b, soft_nms_iou, sigma)
    return r.matches, r.raw_scores, r.scores


def image_similarity(desc_a: ArrayLike, boxes_a: ArrayLike, desc_b: ArrayLike, boxes_b: ArrayLike,
                     soft_nms_iou: float | None = None, sigma: float = 0.5) -> float:
    """Eq. (1) similarity of two images from their landmarks.

    ``S = sum over reciprocal pairs (1 - d_ij * s_ij) / sqrt(na * nb)``; with ``soft_nms_iou``
    the pair scores are first rescaled by Algorithm 4.

    Args:
        desc_a: ``(Ka, D)`` descriptors of image a.
        boxes_a: ``(Ka, 4)`` boxes of image a.
        desc_b: ``(Kb, D)`` descriptors of image b.
        boxes_b: ``(Kb, 4)`` boxes of image b.
        soft_nms_iou: soft-NMS IoU threshold ``t`` or None.
        sigma: soft-NMS Gaussian width.

    Returns:
        The similarity (float; 0 if an image has no landmark).
    """
    return match_landmarks(desc_a, boxes_a, desc_b, boxes_b, soft_nms_iou, sigma).similarity


# ------------------------------------------------------------------------------------------
# batched path (torch)
# ------------------------------------------------------------------------------------------

_PAD = -4.0  # below any cosine: padded landmarks never win an argmax


@dataclass
class _Side:
    """Padded landmark sets of one side (query or reference)."""

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

    def unit64(self, rows: torch.Tensor) -> torch.Tensor:
        """``(t, D)`` float64 unit descriptors of flat rows (same arithmetic as the pairwise path)."""
        x = self.raw.index_select(0, rows).double()
        n = torch.linalg.vector_norm(x, dim=1, keepdim=True)
        return x / torch.where(n > 0, n, torch.ones_like(n))

    _unit64: torch.Tensor | None = None

    def unit_rows64(self, start: int, stop: int) -> torch.Tensor:
        """``(stop - start, D)`` float64 unit descriptors of a range of flat rows (cached)."""
        if self._unit64 is None:
            self._unit64 = self.raw.double() / self.norm64()[:, None]
        return self._unit64[start:stop]

    def norm64(self) -> torch.Tensor:
        """``(N*K,)`` float64 descriptor norms (1 for zero rows), computed once."""
        if self._norm64 is None:
            n = torch.linalg.vector_norm(self.raw, dim=1, dtype=torch.float64)
            self._norm64 = torch.where(n > 0, n, torch.ones_like(n))
        return self._norm64


def _as_list(x: LandmarkSets, name: str, kind: str) -> list[np.ndarray]:
    if isinstance(x, (np.ndarray, torch.Tensor)):
        arr = np.asarray(x.detach().cpu() if isinstance(x, torch.Tensor) else x)
        if arr.ndim != 3:
            raise ValueError(f"{name} as one array must be (N, K, {kind}), got shape {arr.shape}")
        return list(arr)
    try:
        return [np.asarray(v) for v in x]
    except TypeError as e:
        raise ValueError(f"{name} must be a sequence of arrays or one (N, K, ...) array") from e


def _prepare(desc: LandmarkSets, boxes: LandmarkSets, side: str, mm_dtype: torch.dtype,
             device: torch.device) -> _Side:
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
    for i, (c, b) in enumerate(zip(counts, bl)):
        b = _check_boxes(b, f"{side}_boxes[{i}]", c)
        bs.append(b)
        wh[i, :c] = b[:, 2:]
        mask[i, :c] = True
    return _Side(
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


def _iou_stack(side: _Side, device: torch.device) -> torch.Tensor:
    """(N, K, K) float64 per-image IoU matrices (zero padded), via ``landmarks.box_iou``."""
    out = np.zeros((side.n, side.k, side.k), dtype=np.float64)
    for i, b in enumerate(side.boxes):
        c = b.shape[0]
        if c:
            out[i, :c, :c] = box_iou(b, b)
    return torch.from_numpy(out).to(device)


def _resolve(vals: torch.Tensor, best: torch.Tensor, margin: float, sim64_fn):
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
        sims[s:s + step] = sim64_fn(rows[s:s + step], cols[s:s + step])
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


def _soft_nms_batched(scores: torch.Tensor, alive: torch.Tensor, oq: torch.Tensor,
                      orf: torch.Tensor, t: float, sigma: float) -> torch.Tensor:
    """Algorithm 4 on G image pairs in lockstep.

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


def similarity_matrix(query_desc: LandmarkSets, query_boxes: LandmarkSets,
                      reference_desc: LandmarkSets, reference_boxes: LandmarkSets,
                      soft_nms_iou: float | None = None, sigma: float = 0.5,
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
    _check_soft_nms(soft_nms_iou, sigma)
    if matmul_dtype not in ("float32", "float64"):
        raise ValueError(f"matmul_dtype must be 'float32' or 'float64', got {matmul_dtype!r}")
    dev = torch.device(device)
    mm_dtype = torch.float32 if matmul_dtype == "float32" else torch.float64
    q = _prepare(query_desc, query_boxes, "query", mm_dtype, dev)
    r = _prepare(reference_desc, reference_boxes, "reference", mm_dtype, dev)
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
        nms = (_iou_stack(q, dev), _iou_stack(r, dev), float(soft_nms_iou), float(sigma))
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


def _cos64(q: _Side, qrows: torch.Tensor, r: _Side, rrows: torch.Tensor) -> torch.Tensor:
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


_INDEX_ONES: dict = {}


def _index_ones(k: int, dtype: torch.dtype, device: torch.device) -> torch.Tensor:
    """``(2, k)`` rows ``index`` and ``1`` (cached): times a 0/1 map, index sums and counts."""
    key = (k, dtype, device)
    if key not in _INDEX_ONES:
        _INDEX_ONES[key] = torch.stack(
            [torch.arange(k, dtype=dtype, device=device), torch.ones(k, dtype=dtype, device=device)])
    return _INDEX_ONES[key]


def _score_block(s: torch.Tensor, q: _Side, r: _Side, q0: int, q1: int, r0: int, r1: int,
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
            return _cos64(q, qrow[rows], r, rbase[rows] + cols)

        if iq.numel():
            nn, sim = _resolve(vals, best, margin, f_row)
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
            return _cos64(q, qbase[rows] + cols, r, rrow[rows])

        if iq.numel():
            nn, _ = _resolve(vals, best, margin, f_col)
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
        shp = _shape_terms(wq[:, 0], wr[:, 0], wq[:, 1], wr[:, 1], xp=torch)
        total = torch.zeros(nq * nr, dtype=torch.float64, device=s.device)
        total.index_add_(0, g * nr + rr, 1.0 - (1.0 - cos) * shp)
        return total.view(nq, nr) / norm
    cos = rv.permute(0, 2, 1).clamp(-1.0, 1.0)
    wh_q = q.wh[q0:q1].unsqueeze(1)  # (nq, 1, Kq, 2)
    wh_r = r.wh[r0:r1].unsqueeze(0).expand(nq, -1, -1, -1)  # (nq, nr, Kr, 2)
    wh_r = wh_r.gather(2, ri_p.unsqueeze(3).expand(-1, -1, -1, 2))  # (nq, nr, Kq, 2)
    shp = _shape_terms(wh_q[..., 0], wh_r[..., 0], wh_q[..., 1], wh_r[..., 1], xp=torch)
    score = 1.0 - (1.0 - cos) * shp
    iou_q, iou_r, t, sigma = nms
    score = _nms_block(score, shp, recip, ri_p, s64, iou_q[q0:q1], iou_r[r0:r1], t, sigma)
    total = torch.where(recip, score, torch.zeros_like(score)).sum(2)
    return total / norm


def _nms_block(score: torch.Tensor, shp: torch.Tensor, recip: torch.Tensor, ri_p: torch.Tensor,
               s64: torch.Tensor, iou_q: torch.Tensor, iou_r: torch.Tensor, t: float,
               sigma: float, group: int = 1024) -> torch.Tensor:
    """Soft-NMS for a block of image pairs.

    Pair scores are recomputed from float64 cosines so that ties break as in the pairwise path.

    Args:
        score: ``(nq, nr, Kq)`` pair scores per query landmark.
        shp: ``(nq, nr, Kq)`` shape penalties.
        recip: ``(nq, nr, Kq)`` bool, query landmark is reciprocally matched.
        ri_p: ``(nq, nr, Kq)`` matched reference landmark.
        s64: ``(nq, Kq, nr, Kr)`` float64 cosines of the block.
        iou_q: ``(nq, Kq, Kq)``; iou_r: ``(nr, Kr, Kr)`` per-image box IoUs.
        t, sigma: soft-NMS parameters.

    Returns:
        ``(nq, nr, Kq)`` rescaled scores (unchanged where not matched).
    """
    npair = recip.sum(2)
    qi, rj = (npair > 1).nonzero(as_tuple=True)  # soft-NMS is the identity below 2 matches
    if qi.numel() == 0:
        return score
    score = score.clone()
    for s0 in range(0, qi.numel(), group):
        gq, gr = qi[s0:s0 + group], rj[s0:s0 + group]
        alive0 = recip[gq, gr]  # (G, Kq)
        p = int(npair[gq, gr].max().item())
        # compact matched landmarks to the front, keeping query-landmark order (pair index)
        order = torch.argsort((~alive0).to(torch.int8), dim=1, stable=True)[:, :p]
        alive = alive0.gather(1, order)
        ii = order
        jj = ri_p[gq, gr].gather(1, order)
        # float64 cosines of the matched pairs: the argmax of Algorithm 4 is discontinuous at
        # ties, so the scores must equal the pairwise path's to ~1e-15, not just ~1e-7
        cos = s64[gq[:, None], ii, gr[:, None], jj][alive].clamp(-1.0, 1.0)
        sc = torch.zeros(alive.shape, dtype=torch.float64, device=score.device)
        sc[alive] = 1.0 - (1.0 - cos) * shp[gq, gr].gather(1, order)[alive]
        oq = iou_q[gq[:, None, None], ii[:, :, None], ii[:, None, :]]
        orf = iou_r[gr[:, None, None], jj[:, :, None], jj[:, None, :]]
        new = _soft_nms_batched(sc, alive, oq, orf, t, sigma)
        rows = score[gq, gr]
        rows.scatter_(1, order, torch.where(alive, new, sc))
        score[gq, gr] = rows
    return score
