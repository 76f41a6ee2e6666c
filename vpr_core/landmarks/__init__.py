"""Landmarks: Edge Boxes and the dense grid, Table-1 scales, Algorithms 1-3, coverage, and the
schemes (one frozen dataclass each) the pipeline runs. Boxes are ``(K, 4)`` ``(x, y, w, h)``
(docs/DEFINITIONS.md); the module map is docs/ARCHITECTURE.md."""

from __future__ import annotations

from ..boxes import box_iou
from .coverage import landmark_coverage
from .dense import dense_sampling
from .edge_boxes import edge_boxes
from .scales import normalized_scale, scale_distribution, scale_index
from .schemes import (
    Dense,
    EdgeBoxesTop,
    LandmarkScheme,
    MinScale,
    ReduceOverlap,
    ScalePriority,
    WholeImage,
)
from .selection import reduce_overlap, select_min_scale, select_scale_priority
from .stage import extract_landmarks, landmarks_for_image

__all__ = [
    "Dense",
    "EdgeBoxesTop",
    "LandmarkScheme",
    "MinScale",
    "ReduceOverlap",
    "ScalePriority",
    "WholeImage",
    "box_iou",
    "dense_sampling",
    "edge_boxes",
    "extract_landmarks",
    "landmark_coverage",
    "landmarks_for_image",
    "normalized_scale",
    "reduce_overlap",
    "scale_distribution",
    "scale_index",
    "select_min_scale",
    "select_scale_priority",
]
