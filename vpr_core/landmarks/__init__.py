"""Landmark proposals: dense sampling, Edge Boxes, Table-1 scales, Algorithms 1-3, coverage.

Boxes are ``np.ndarray (K, 4)`` float64 ``(x, y, w, h)`` in pixels (continuous coordinates: a box
covers ``[x, x + w) x [y, y + h)``; area ``w * h``, no ``+1``), always in *proposal order* (for
Edge Boxes: descending objectness score). ``image_size`` is always ``(H, W)``.

=====================  ======================================================================
module                 paper item
=====================  ======================================================================
``scales``             Eq. (3) :func:`normalized_scale`, Table 1 :func:`scale_index`,
                       Fig. 6 :func:`scale_histogram`
``dense``              Sec. 4 / Fig. 9 :func:`dense_sampling`
``edge_boxes``         Sec. 2.1 :func:`edge_boxes` (OpenCV-contrib ``ximgproc``)
``selection``          Algorithms 1-3: :func:`select_min_scale`, :func:`select_scale_priority`,
                       :func:`reduce_overlap`; :func:`select_from_candidates` by scheme name
``coverage``           Fig. 14 :func:`landmark_coverage`
=====================  ======================================================================

:func:`box_iou` is re-exported from :mod:`vpr_core.boxes` (the one IoU of the code base).
"""

from __future__ import annotations

from ..boxes import box_iou
from .coverage import landmark_coverage
from .dense import dense_sampling
from .edge_boxes import EDGE_BOXES_DEFAULTS, EdgeBoxes, edge_boxes
from .scales import (
    N_SCALES,
    SCALE_EDGES,
    SCALE_LABELS,
    SCALE_RANGE_LABELS,
    SCALE_RANGES,
    normalized_scale,
    scale_distribution,
    scale_histogram,
    scale_index,
)
from .selection import (
    EDGE_BOX_SCHEMES,
    reduce_overlap,
    select_from_candidates,
    select_min_scale,
    select_scale_priority,
)

__all__ = [
    "EDGE_BOXES_DEFAULTS",
    "EDGE_BOX_SCHEMES",
    "N_SCALES",
    "SCALE_EDGES",
    "SCALE_LABELS",
    "SCALE_RANGES",
    "SCALE_RANGE_LABELS",
    "EdgeBoxes",
    "box_iou",
    "dense_sampling",
    "edge_boxes",
    "landmark_coverage",
    "normalized_scale",
    "reduce_overlap",
    "scale_distribution",
    "scale_histogram",
    "scale_index",
    "select_from_candidates",
    "select_min_scale",
    "select_scale_priority",
]
