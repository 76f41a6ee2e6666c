"""Gardens Point Walking (Glover 2014): three frame-aligned traverses of one campus walk."""

from __future__ import annotations

import logging
import os

from ..checks import check_choice
from ._layout import check_frame_pairs, check_root, data_name, traverse_dir
from .base import PlaceDataset
from .ground_truth import check_tolerance, frame_aligned
from .images import list_images

__all__ = ["GARDENS_POINT_LAYOUT", "GARDENS_POINT_TRAVERSES", "load_gardens_point"]

log = logging.getLogger("vpr_core")


GARDENS_POINT_LAYOUT = (
    "<root>/day_left/Image000.jpg..Image199.jpg, <root>/day_right/..., <root>/night_right/... "
    "(frame i of one traverse is frame i of the others)"
)
GARDENS_POINT_TRAVERSES = ("day_left", "day_right", "night_right")


def load_gardens_point(
    root: str | os.PathLike | None = None,
    query: str = "day_left",
    reference: str = "night_right",
    tolerance: int = 2,
) -> PlaceDataset:
    """Gardens Point Walking (Glover 2014; Zenodo doi 10.5281/zenodo.4590133).

    Layout (the published one)::

        <root>/day_left/Image000.jpg ... Image199.jpg
        <root>/day_right/Image000.jpg ...
        <root>/night_right/Image000.jpg ...

    A root that holds a single ``GardensPointWalking/`` folder with that layout (as extracted
    from the archive) is accepted too. The traverses are frame-aligned: ground truth is
    ``|q - r| <= tolerance``, paired by the frame number in the file names (a frame missing on
    one side is named in an error). Tolerances in use differ (0, +-2 in VPR-Bench, +-3 in IROS-2015
    reproductions): always report the tolerance beside a number.
    """
    tolerance = check_tolerance(tolerance)
    root = check_root(root, "gardens_point", GARDENS_POINT_LAYOUT)
    for t in (query, reference):
        check_choice(t, "gardens_point traverse", GARDENS_POINT_TRAVERSES)
    base = root
    if not (root / query).is_dir() and (root / "GardensPointWalking" / query).is_dir():
        base = root / "GardensPointWalking"
        log.info("gardens_point: using %s (the archive's top folder)", base)
    where = "gardens_point"
    qp, rp = (
        list_images(traverse_dir(base, t, where, GARDENS_POINT_LAYOUT), f"{where} {t} folder")
        for t in (query, reference)
    )
    check_frame_pairs(qp, rp, f"gardens_point {query} vs {reference}")
    gt = frame_aligned(len(qp), len(rp), tolerance)
    meta = {
        "query_traverse": query,
        "reference_traverse": reference,
        "ground_truth_rule": f"frame-aligned |q-r|<={tolerance}",
        "frame_aligned": True,
        "layout": GARDENS_POINT_LAYOUT,
    }
    meta["loader"] = "gardens_point"
    return PlaceDataset(data_name(base), qp, rp, gt, tolerance, root=base, meta=meta)
