"""Pipeline stages: landmarks -> features -> similarity matrix -> metrics, all cached on disk.

One stage, one function (hloc habit). Notebooks and the CLI call :func:`run_method`, which
chains :func:`extract_landmarks` (:mod:`.landmark_stage`), :func:`extract_features`
(:mod:`.feature_stage`) and the matching/evaluation steps (:mod:`.run`). Cache entries are
written atomically and a damaged one is recomputed (:mod:`.cache`).
"""

from __future__ import annotations

from .feature_stage import extract_features, get_encoder
from .landmark_stage import edge_box_candidates, extract_landmarks, landmarks_for_image
from .result import MethodResult, peer_result
from .run import run_method

__all__ = [
    "MethodResult",
    "edge_box_candidates",
    "extract_features",
    "extract_landmarks",
    "get_encoder",
    "landmarks_for_image",
    "peer_result",
    "run_method",
]
