"""Pairwise reference path: Eq. (1)-(2), reciprocal nearest neighbours, soft-NMS (Algorithm 4).

NumPy float64 on one image pair at a time; :mod:`vpr_core.matching.batched` computes the same numbers
for many pairs at once and is tested against this module.

Definitions (``docs/PAPER_MAP.md``; ``DESIGN.md`` section 2):

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

from ..boxes import box_iou, check_boxes
from ..paper import SOFT_NMS_SIGMA

__all__ = [
    "NMS_TIE_TOL",
    "TIE_TOL",
    "ArrayLike",
    "MatchResult",
    "check_soft_nms",
    "cosine_distance",
    "cosine_similarity",
    "image_similarity",
    "match_landmarks",
    "match_overlaps",
    "pair_scores",
    "reciprocal_matches",
    "shape_penalty",
    "shape_terms",
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


def _check_pair(desc_a, boxes_a, desc_b, boxes_b):
    a = _check_desc(desc_a, "desc_a")
    b = _check_desc(desc_b, "desc_b")
    if a.shape[1] != b.shape[1]:
        raise ValueError(
            f"descriptor dimensions differ: desc_a D={a.shape[1]}, desc_b D={b.shape[1]}"
        )
    ba = check_boxes(boxes_a, "boxes_a", a.shape[0])
    bb = check_boxes(boxes_b, "boxes_b", b.shape[0])
    return a, ba, b, bb


def check_soft_nms(soft_nms_iou: float | None, sigma: float) -> None:
    """Raise a ValueError unless ``soft_nms_iou`` is None or in ``[0, 1]`` and ``sigma > 0``."""
    if soft_nms_iou is not None and not (0.0 <= float(soft_nms_iou) <= 1.0):
        raise ValueError(f"soft_nms_iou must be in [0, 1] or None, got {soft_nms_iou}")
    if not float(sigma) > 0:
        raise ValueError(f"sigma must be > 0, got {sigma}")


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
        raise ValueError(
            f"descriptor dimensions differ: desc_a D={a.shape[1]}, desc_b D={b.shape[1]}"
        )
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


def shape_terms(wa, wb, ha, hb, xp=np):
    """Eq. (2) from broadcastable widths and heights (``xp``: ``numpy`` or ``torch``)."""

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
    a = check_boxes(boxes_a, "boxes_a")
    b = check_boxes(boxes_b, "boxes_b")
    return shape_terms(a[:, None, 2], b[None, :, 2], a[:, None, 3], b[None, :, 3])


def match_overlaps(boxes_a: ArrayLike, boxes_b: ArrayLike, matches: ArrayLike) -> np.ndarray:
    """Overlap of every two matches: ``min(IoU of their a-boxes, IoU of their b-boxes)``.

    Args:
        boxes_a: ``(Ka, 4)`` boxes of image a.
        boxes_b: ``(Kb, 4)`` boxes of image b.
        matches: ``(P, 2)`` ``(i, j)`` index pairs.

    Returns:
        ``(P, P)`` float64 overlaps in ``[0, 1]`` (diagonal 1 for non-empty boxes).
    """
    a = check_boxes(boxes_a, "boxes_a")
    b = check_boxes(boxes_b, "boxes_b")
    m = np.asarray(matches, dtype=np.int64).reshape(-1, 2)
    # Full per-image IoU matrices, then gather: the batched path does the same, so the values
    # compared against the threshold are bit-identical in both paths.
    iou_a = box_iou(a, a)
    iou_b = box_iou(b, b)
    i, j = m[:, 0], m[:, 1]
    return np.minimum(iou_a[np.ix_(i, i)], iou_b[np.ix_(j, j)])


def soft_nms_scores(
    scores: ArrayLike, overlaps: ArrayLike, iou_threshold: float, sigma: float = SOFT_NMS_SIGMA
) -> np.ndarray:
    """Algorithm 4 (overlap reduction scheme 2): Gaussian soft-NMS of match scores.

    Repeatedly takes the remaining pair with the highest current score (scores within
    :data:`NMS_TIE_TOL` tie; the lowest index wins),
    fixes its score, removes it, and multiplies every remaining pair ``k`` with
    ``overlaps[m, k] > iou_threshold`` by ``exp(-overlaps[m, k]**2 / sigma)``.

    Args:
        scores: ``(P,)`` pair scores ``1 - d * s``.
        overlaps: ``(P, P)`` symmetric pair overlaps (see :func:`match_overlaps`).
        iou_threshold: ``t``; strictly greater overlaps are decayed.
        sigma: Gaussian width (default: the paper's ``SOFT_NMS_SIGMA``).

    Returns:
        ``(P,)`` float64 rescaled scores (each pair's score when it was removed).
    """
    check_soft_nms(iou_threshold, sigma)
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


def match_landmarks(
    desc_a: ArrayLike,
    boxes_a: ArrayLike,
    desc_b: ArrayLike,
    boxes_b: ArrayLike,
    soft_nms_iou: float | None = None,
    sigma: float = SOFT_NMS_SIGMA,
) -> MatchResult:
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
    check_soft_nms(soft_nms_iou, sigma)
    a, ba, b, bb = _check_pair(desc_a, boxes_a, desc_b, boxes_b)
    cos = cosine_similarity(a, b)
    m = _reciprocal_from_sim(cos)
    i, j = m[:, 0], m[:, 1]
    dist = 1.0 - cos[i, j]
    shp = shape_terms(ba[i, 2], bb[j, 2], ba[i, 3], bb[j, 3])
    raw = 1.0 - dist * shp
    scores = raw
    if soft_nms_iou is not None and len(m) > 1:
        scores = soft_nms_scores(raw, match_overlaps(ba, bb, m), soft_nms_iou, sigma)
    na, nb = a.shape[0], b.shape[0]
    sim = float(scores.sum() / math.sqrt(na * nb)) if na * nb > 0 else 0.0
    return MatchResult(m, dist, shp, np.array(scores, dtype=np.float64), sim, raw, na, nb)


def pair_scores(
    desc_a: ArrayLike,
    boxes_a: ArrayLike,
    desc_b: ArrayLike,
    boxes_b: ArrayLike,
    soft_nms_iou: float | None = None,
    sigma: float = SOFT_NMS_SIGMA,
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


def image_similarity(
    desc_a: ArrayLike,
    boxes_a: ArrayLike,
    desc_b: ArrayLike,
    boxes_b: ArrayLike,
    soft_nms_iou: float | None = None,
    sigma: float = SOFT_NMS_SIGMA,
) -> float:
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
