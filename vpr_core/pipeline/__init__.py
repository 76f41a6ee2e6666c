"""Pipeline stages: landmarks -> features -> similarity matrix -> metrics, all cached on disk;
:func:`run_method` chains them (notebooks and the CLI call it)."""

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
