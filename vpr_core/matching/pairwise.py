"""Eq. (1)-(2) for ONE image pair, in float64 NumPy: the reference that reads like the paper.

The paper (Sec. 2.1): landmarks are matched by nearest-neighbour search on the cosine distance,
only reciprocal matches count, and two images score

    S = 1 / sqrt(n_a * n_b) * sum over matches (i, j) of 1 - d_ij * s_ij           (1)
    s_ij = exp(1/2 * (|w_i - w_j| / max(w_i, w_j) + |h_i - h_j| / max(h_i, h_j)))  (2)

with Algorithm 4 (soft-NMS) rescaling the match scores first when it is on. The block engine
(:mod:`.core`) computes the same numbers for blocks of image pairs (one matmul per block);
tests/test_pairwise.py checks that the two agree on every study method. The public one-pair
functions (:func:`~.similarity.match_landmarks`, :func:`~.similarity.image_similarity`) check
their input and call :func:`match_pair`; definitions in docs/DEFINITIONS.md (Matching).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..boxes import box_iou
from ._sides import normalised_centres, rescale_rows
from .core import NMS_TIE_TOL, SPATIAL_TAU
from .reciprocal import TIE_TOL
from .spec import Matching

__all__ = [
    "MatchResult",
    "cosine_similarity",
    "match_pair",
    "reciprocal_pairs",
    "shape_similarity",
    "soft_nms",
]


@dataclass
class MatchResult:
    """Landmark matches of one image pair and their Eq. (1) terms.

    Attributes:
        matches: ``(P, 2)`` int64 reciprocal ``(i, j)`` pairs, sorted by ``i``.
        distances: ``(P,)`` cosine distances ``d_ij``.
        shape: ``(P,)`` shape penalties ``s_ij`` (Eq. 2).
        scores: ``(P,)`` pair scores entering Eq. (1): ``1 - d * s``, times ``spatial_weights``,
            after soft-NMS if enabled.
        similarity: Eq. (1) image similarity ``scores.sum() / sqrt(na * nb)``.
        raw_scores: ``(P,)`` ``1 - d * s`` before any weight and soft-NMS.
        n_a: number of landmarks of image a.
        n_b: number of landmarks of image b.
        spatial_weights: ``(P,)`` geometry weights (not in the paper; all 1 with ``spatial=None``).
        weights: ``(P,)`` database weights (not in the paper; the block engine's
            :func:`~.similarity.weighted_matches`), None without a weighting.
    """

    matches: np.ndarray
    distances: np.ndarray
    shape: np.ndarray
    scores: np.ndarray
    similarity: float
    raw_scores: np.ndarray
    n_a: int
    n_b: int
    spatial_weights: np.ndarray
    weights: np.ndarray | None = None


def cosine_similarity(desc_a: np.ndarray, desc_b: np.ndarray) -> np.ndarray:
    """``(Ka, Kb)`` cosines ``cos(i, j)``, so ``d_ij = 1 - cos(i, j)``; a zero descriptor has
    cosine 0 with everything."""

    def unit(x: np.ndarray) -> np.ndarray:
        x = rescale_rows(np.asarray(x, dtype=np.float64))  # a power of two: no norm overflows
        norm = np.linalg.norm(x, axis=1, keepdims=True)
        return x / np.where(norm > 0, norm, 1.0)

    return np.clip(unit(desc_a) @ unit(desc_b).T, -1.0, 1.0)


def _nearest(cos: np.ndarray, axis: int) -> np.ndarray:
    """Each row's (``axis=1``) or column's (``axis=0``) nearest neighbour: the lowest index whose
    cosine is within ``TIE_TOL`` (1e-9) of the best, so that float rounding never decides a tie
    (the block engine decides near-ties so too: :mod:`.reciprocal`)."""
    best = cos.max(axis=axis, keepdims=True)
    return np.argmax(cos >= best - TIE_TOL, axis=axis)


def reciprocal_pairs(cos: np.ndarray) -> np.ndarray:
    """``(P, 2)`` int64 reciprocal nearest neighbours ``(i, j)``: i's nearest is j and j's is i."""
    ka, kb = cos.shape
    if ka == 0 or kb == 0:
        return np.zeros((0, 2), dtype=np.int64)
    j_of_i = _nearest(cos, axis=1)
    i_of_j = _nearest(cos, axis=0)
    i = np.arange(ka)
    mutual = i_of_j[j_of_i] == i
    return np.stack([i[mutual], j_of_i[mutual]], axis=1).astype(np.int64)


def shape_similarity(wh_a: np.ndarray, wh_b: np.ndarray) -> np.ndarray:
    """Eq. (2) ``s_ij`` of row-wise paired box sizes ``(P, 2)`` ``(w, h)``; a 0/0 term counts 0."""
    top = np.abs(wh_a - wh_b)
    m = np.maximum(wh_a, wh_b)
    ratio = np.divide(top, m, out=np.zeros_like(top), where=m > 0)
    return np.exp(0.5 * (ratio[:, 0] + ratio[:, 1]))  # Eq. (2)


def _consistency_weights(boxes_a: np.ndarray, boxes_b: np.ndarray, m: np.ndarray) -> np.ndarray:
    """(Not in the paper) ``spatial="consistency"``: ``exp(-|delta - median delta|^2 / (2 tau^2))``
    of each match's displacement ``delta`` (box centres in units of each image's landmark extent;
    the median per coordinate, over this pair's matches)."""
    delta = normalised_centres(boxes_a)[m[:, 0]] - normalised_centres(boxes_b)[m[:, 1]]
    if len(delta) == 0:
        return np.ones(0)
    dev2 = ((delta - np.median(delta, axis=0)) ** 2).sum(axis=1)
    return np.exp(-dev2 / (2.0 * SPATIAL_TAU**2))


def soft_nms(scores: np.ndarray, overlap: np.ndarray, t: float, sigma: float) -> np.ndarray:
    """Algorithm 4 (overlap reduction Scheme 2): each match's score when it was taken.

    Repeatedly take the remaining match with the highest score (ties within ``NMS_TIE_TOL``:
    the lowest match index) and multiply each other match that overlaps it by more than ``t``
    by ``exp(-IoU^2 / sigma)``. ``overlap``: ``(P, P)`` IoU of two matches, the smaller of their
    a-boxes' and their b-boxes' IoU.
    """
    decay = np.where(overlap > t, np.exp(-(overlap**2) / sigma), 1.0)
    current, out = scores.copy(), scores.copy()
    left = np.ones(len(scores), dtype=bool)
    while left.any():
        masked = np.where(left, current, -np.inf)
        m = int(np.argmax(masked >= masked.max() - NMS_TIE_TOL))  # m <- argmax S
        out[m], left[m] = current[m], False  # M <- M - M(m)
        current = current * decay[m]  # S(i) <- S(i) * exp(-IoU^2 / sigma) where IoU > t
    return out


def match_pair(
    desc_a: np.ndarray,
    boxes_a: np.ndarray,
    desc_b: np.ndarray,
    boxes_b: np.ndarray,
    matching: Matching = Matching(),
) -> MatchResult:
    """Eq. (1) of one image pair with its terms: reciprocal matches, Eq. (2), Algorithm 4 when
    ``matching.soft_nms_iou`` is set and (not in the paper) ``spatial`` weights.

    Inputs are parsed (the public :func:`~.similarity.match_landmarks` checks them): ``desc_*``
    ``(K, D)`` float arrays of one ``D``, ``boxes_*`` ``(K, 4)`` float64 ``(x, y, w, h)``;
    ``matching`` without a weighting (its statistics come from every reference).
    """
    assert matching.weighting is None
    n_a, n_b = len(desc_a), len(desc_b)
    if min(n_a, n_b, desc_a.shape[1], desc_b.shape[1]) == 0:  # nothing to match: S = 0
        e = np.zeros(0)
        return MatchResult(np.zeros((0, 2), np.int64), e, e, e, 0.0, e, n_a, n_b, e)

    # Sec. 2.1: nearest neighbours on the cosine distance d = 1 - cos; reciprocal ones only
    cos = cosine_similarity(desc_a, desc_b)
    m = reciprocal_pairs(cos)
    i, j = m[:, 0], m[:, 1]
    d = 1.0 - cos[i, j]
    s = shape_similarity(boxes_a[i, 2:], boxes_b[j, 2:])  # Eq. (2)
    raw = 1.0 - d * s  # the summand of Eq. (1)

    # (not in the paper) geometry-aware weight of each term
    w = np.ones(len(m)) if matching.spatial is None else _consistency_weights(boxes_a, boxes_b, m)
    scores = raw * w

    # Algorithm 4 (soft-NMS) rescales the terms before the sum
    if matching.soft_nms_iou is not None and len(m) > 1:
        overlap = np.minimum(
            box_iou(boxes_a, boxes_a)[np.ix_(i, i)], box_iou(boxes_b, boxes_b)[np.ix_(j, j)]
        )
        scores = soft_nms(scores, overlap, matching.soft_nms_iou, matching.sigma)

    similarity = float(scores.sum() / math.sqrt(n_a * n_b))  # Eq. (1)
    return MatchResult(m, d, s, scores, similarity, raw, n_a, n_b, w)
