"""Mapillary Berlin (Sunderhauf et al. RSS 2015): query/reference folders and a correspondence
list."""

from __future__ import annotations

import os

from ._layout import check_root, correspondence_dataset, resolve_file, traverse_dir
from .base import PlaceDataset
from .ground_truth import check_tolerance

__all__ = ["MAPILLARY_BERLIN_LAYOUT", "load_mapillary_berlin"]

MAPILLARY_BERLIN_LAYOUT = (
    "<root>[/<sequence>]/query/*.jpg, <root>[/<sequence>]/reference/*.jpg, "
    "<root>[/<sequence>]/ground_truth.csv with rows query,reference"
)


def load_mapillary_berlin(
    root: str | os.PathLike | None = None,
    sequence: str | None = None,
    query: str = "query",
    reference: str = "reference",
    ground_truth: str | os.PathLike = "ground_truth.csv",
    tolerance: int = 0,
) -> PlaceDataset:
    """Mapillary Berlin (Sunderhauf et al. RSS 2015); layout documented by us.

    The paper's set has 157 query and 67 reference images from one Berlin street; the source
    has the sequences Halenseestrasse, Kudamm and A100, each with two traverses ``_1``/``_2``.
    The ground truth is a correspondence list (many queries may share one reference), not a
    frame alignment, so a file is required. Layout::

        <root>/query/*.jpg
        <root>/reference/*.jpg
        <root>/ground_truth.csv          # rows "query,reference" (file names or 0-based indices)

    With ``sequence="Kudamm"`` the same layout is read from ``<root>/Kudamm/``. To use the raw
    traverses directly, pass ``query="Kudamm_1", reference="Kudamm_2"`` (folder names).
    ``tolerance`` widens the listed matches along the reference sequence (frames).
    """
    tolerance = check_tolerance(tolerance)
    root = check_root(root, "mapillary_berlin", MAPILLARY_BERLIN_LAYOUT)
    base = (
        traverse_dir(root, sequence, "mapillary_berlin", MAPILLARY_BERLIN_LAYOUT)
        if sequence
        else root
    )
    qd = traverse_dir(base, query, "mapillary_berlin", MAPILLARY_BERLIN_LAYOUT)
    rd = traverse_dir(base, reference, "mapillary_berlin", MAPILLARY_BERLIN_LAYOUT)
    gt_file = resolve_file(base, ground_truth)
    meta = {
        "sequence": sequence,
        "query_traverse": query,
        "reference_traverse": reference,
        "layout": MAPILLARY_BERLIN_LAYOUT,
    }
    return correspondence_dataset("mapillary_berlin", base, qd, rd, gt_file, tolerance, meta)
