"""Compatibility module: the names :mod:`vpr_core.datasets.synthetic` imports from here.

The dataset model now lives in :mod:`.base` (:class:`PlaceDataset`) and the ground-truth rules in
:mod:`.ground_truth` (:func:`~.ground_truth.check_tolerance`, :func:`~.ground_truth.frame_aligned`);
import them from there.
"""

from __future__ import annotations

from .base import PlaceDataset
from .ground_truth import check_tolerance as _check_tolerance
from .ground_truth import frame_aligned as _frame_aligned

__all__ = ["PlaceDataset", "_check_tolerance", "_frame_aligned"]
