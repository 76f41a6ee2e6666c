"""Pipeline stages: landmarks -> features -> similarity matrix -> metrics, all cached on disk.

One stage, one function (hloc habit). Notebooks and the CLI call :func:`run_method`, which
chains :func:`extract_landmarks` (:mod:`.landmark_stage`), :func:`extract_features`
(:mod:`.feature_stage`) and the matching/evaluation steps (:mod:`.run`). Cache entries are
written atomically and a damaged one is recomputed (:mod:`.cache`).
"""

from __future__ import annotations

from ..evaluation.bootstrap import N_BOOTSTRAP
from ..methods import method_label
from .cache import SIDES, atomic_savez, dataset_fingerprint, load_npz
from .feature_stage import (
    _encoder_slug,
    encoder_kwargs,
    extract_features,
    features_for_image,
    get_encoder,
)
from .landmark_stage import (
    LANDMARK_SCHEMES,
    edge_box_candidates,
    extract_landmarks,
    landmarks_for_image,
)
from .result import INTERVAL_COLUMNS, MethodResult, peer_result
from .run import run_method

__all__ = [
    "INTERVAL_COLUMNS",
    "LANDMARK_SCHEMES",
    "N_BOOTSTRAP",
    "SIDES",
    "MethodResult",
    "_encoder_slug",
    "atomic_savez",
    "dataset_fingerprint",
    "edge_box_candidates",
    "encoder_kwargs",
    "extract_features",
    "extract_landmarks",
    "features_for_image",
    "get_encoder",
    "landmarks_for_image",
    "load_npz",
    "method_label",
    "peer_result",
    "run_method",
]
