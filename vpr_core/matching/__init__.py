"""Landmark matching: Eq. (1)-(2), reciprocal nearest neighbours and Algorithm 4, for one image
pair in :mod:`.pairwise` (the float64 reference that reads like the paper) and for blocks of pairs
in the torch engine (:mod:`.core`, the same numbers); the public functions are in
:mod:`.similarity`."""

from __future__ import annotations

from .pairwise import MatchResult
from .similarity import (
    check_pairs,
    cosine_distance,
    image_similarity,
    match_landmarks,
    reciprocal_matches,
    shape_penalty,
    similarity_matrix,
    similarity_pairs,
    weighted_matches,
)
from .spec import SPATIAL_OPTIONS, WEIGHTING_OPTIONS, Compute, Matching

__all__ = [
    "SPATIAL_OPTIONS",
    "WEIGHTING_OPTIONS",
    "Compute",
    "MatchResult",
    "Matching",
    "check_pairs",
    "cosine_distance",
    "image_similarity",
    "match_landmarks",
    "reciprocal_matches",
    "shape_penalty",
    "similarity_matrix",
    "similarity_pairs",
    "weighted_matches",
]
