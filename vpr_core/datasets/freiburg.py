"""Freiburg Across Seasons (Naseer et al. AAAI 2014), Summer 2015 vs Winter 2012 (layout
unverified)."""

from __future__ import annotations

import os

from ._layout import check_root, correspondence_dataset, resolve_file, traverse_dir
from .base import PlaceDataset
from .ground_truth import check_tolerance

__all__ = ["FREIBURG_LAYOUT", "load_freiburg_across_seasons"]

FREIBURG_LAYOUT = (
    "<root>/summer2015/*.jpg, <root>/winter2012/*.jpg, <root>/ground_truth.csv with rows "
    "query,reference (layout documented by vpr-landmarks, not verified against the release)"
)


def load_freiburg_across_seasons(
    root: str | os.PathLike | None = None,
    query: str = "summer2015",
    reference: str = "winter2012",
    ground_truth: str | os.PathLike = "ground_truth.csv",
    tolerance: int = 0,
) -> PlaceDataset:
    """Freiburg Across Seasons (Naseer et al. AAAI 2014), Summer 2015 vs Winter 2012.

    The layout below is UNVERIFIED: it is documented by this project (the original release
    keeps several images per place; the paper keeps one per place and matches them with a
    correspondence file). Prepare the data as::

        <root>/summer2015/*.jpg          # one image per place
        <root>/winter2012/*.jpg
        <root>/ground_truth.csv          # rows "query,reference" (file names or 0-based indices)

    ``tolerance`` widens the listed matches along the reference sequence (frames).
    """
    tolerance = check_tolerance(tolerance)
    root = check_root(root, "freiburg_across_seasons", FREIBURG_LAYOUT)
    qd = traverse_dir(root, query, "freiburg_across_seasons", FREIBURG_LAYOUT)
    rd = traverse_dir(root, reference, "freiburg_across_seasons", FREIBURG_LAYOUT)
    gt_file = resolve_file(root, ground_truth)
    meta = {
        "query_traverse": query,
        "reference_traverse": reference,
        "layout": FREIBURG_LAYOUT,
        "layout_verified": False,
    }
    return correspondence_dataset("freiburg_across_seasons", root, qd, rd, gt_file, tolerance, meta)
