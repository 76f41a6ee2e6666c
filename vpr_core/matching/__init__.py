"""Landmark matching: Eq. (1)-(2), reciprocal nearest neighbours and Algorithm 4, for one image
pair in :mod:`.pairwise` (the float64 reference that reads like the paper) and for blocks of pairs
in the torch engine (:mod:`.core`, the same numbers); the public functions are in
:mod:`.similarity`. The engine's inputs are parsed in the package-private :mod:`._sides`; the
shortlist is :mod:`.shortlist`; the rooms of the steps not in the paper: :mod:`.weighting`
(:data:`WEIGHTINGS`), :mod:`.normalise` (:data:`NORMALISATIONS`) and :mod:`.whiten` (the
descriptor steps, :data:`DESCRIPTOR_STEPS`)."""

from __future__ import annotations

from ._sides import landmark_lists
from .core import Problem
from .normalise import (
    NORMALISATIONS,
    Normalisation,
    needs_query_batch,
    normalise_matrix,
    zscore,
)
from .pairwise import cosine_similarity
from .shortlist import rerank, shortlist_pairs, split_whole_image, with_whole_image_boxes
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
from .spec import SPATIAL_OPTIONS, Compute, Matching
from .weighting import (
    CONTRAST_SAMPLE,
    WEIGHTING_SAMPLE,
    WEIGHTINGS,
    Weighting,
    clear_reference_cache,
    reference_stats,
    sample_matches,
    weighting_sample,
)
from .whiten import (
    DESCRIPTOR_STEPS,
    WHITEN_K,
    clear_whitening_cache,
    fit_whitening,
    whiten_landmarks,
)

__all__ = [
    "CONTRAST_SAMPLE",
    "DESCRIPTOR_STEPS",
    "NORMALISATIONS",
    "SPATIAL_OPTIONS",
    "WEIGHTINGS",
    "WEIGHTING_SAMPLE",
    "WHITEN_K",
    "Compute",
    "Matching",
    "Normalisation",
    "Weighting",
    "Problem",
    "check_pairs",
    "cosine_distance",
    "cosine_similarity",
    "image_similarity",
    "landmark_lists",
    "match_landmarks",
    "needs_query_batch",
    "normalise_matrix",
    "reciprocal_matches",
    "rerank",
    "reference_stats",
    "clear_reference_cache",
    "clear_whitening_cache",
    "fit_whitening",
    "sample_matches",
    "shape_penalty",
    "shortlist_pairs",
    "similarity_matrix",
    "similarity_pairs",
    "split_whole_image",
    "weighted_matches",
    "zscore",
    "weighting_sample",
    "whiten_landmarks",
    "with_whole_image_boxes",
]
