"""Landmark matching and image similarity: Eq. (1)-(2), reciprocal NN, soft-NMS (Algorithm 4).

Two paths compute the same numbers:

* :mod:`~vpr_core.matching.pairwise`: one image pair in NumPy float64, the reference
  (:func:`reciprocal_matches`, :func:`shape_penalty`, :func:`soft_nms_scores`,
  :func:`match_landmarks`, :func:`pair_scores`, :func:`image_similarity`);
* :mod:`~vpr_core.matching.batched`: many pairs at once in torch (:func:`similarity_matrix` for
  every query x reference pair, :func:`similarity_pairs` for a list of pairs, e.g. a shortlist),
  equal to the pairwise path to 1e-5 with exactly the same matches.

The batched path's core is :mod:`~vpr_core.matching.scoring` (padded landmark sets, float64
re-decision of float32 near-ties, Eq. (1) per block of image pairs: what the results come from),
with :mod:`~vpr_core.matching.soft_nms` (Algorithm 4 on many pairs in lockstep).
"""

from __future__ import annotations

from .batched import similarity_matrix, similarity_pairs
from .pairwise import (
    MatchResult,
    cosine_distance,
    cosine_similarity,
    image_similarity,
    match_landmarks,
    match_overlaps,
    pair_scores,
    reciprocal_matches,
    shape_penalty,
    soft_nms_scores,
)

__all__ = [
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
    "similarity_pairs",
    "soft_nms_scores",
]
