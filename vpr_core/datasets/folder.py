"""Any ``query/`` + ``reference/`` folder pair, ground truth from a file or frame-aligned."""

from __future__ import annotations

import os
from typing import Any

from ..checks import check_file
from ._layout import check_frame_pairs, check_root, data_name, resolve_file, traverse_dir, widen
from .base import PlaceDataset
from .ground_truth import check_coverage, check_tolerance, frame_aligned, read_ground_truth
from .images import list_images, scan_images

__all__ = ["FOLDER_LAYOUT", "load_folder"]

FOLDER_LAYOUT = (
    "<root>/query/*, <root>/reference/*, optional <root>/ground_truth.npy ((Nq, Nr) bool) or "
    "<root>/ground_truth.csv (query,reference rows); without one, query i <-> reference i"
)

#: Skipped files that cannot be a frame (notes, lists, arrays): they do not block the
#: frame-aligned rule; any other skipped file (an unreadable image format, a broken link) does.
_NOT_FRAMES = {".txt", ".csv", ".json", ".md", ".xml", ".yaml", ".yml", ".log", ".npy", ".npz"}
_NOT_FRAMES |= {".mat", ".ini", ".db", ".pdf"}


def load_folder(
    root: str | os.PathLike | None = None,
    ground_truth: str | os.PathLike | None = None,
    tolerance: int = 0,
    query: str = "query",
    reference: str = "reference",
) -> PlaceDataset:
    """Any ``query/`` + ``reference/`` folder pair.

    Layout::

        <root>/query/*.jpg|png|...       # naturally sorted: 2.jpg before 10.jpg
        <root>/reference/*.jpg|png|...
        <root>/ground_truth.npy          # optional (Nq, Nr) bool / 0-1 matrix, or
        <root>/ground_truth.csv          # optional rows "query,reference"

    Ground truth: ``ground_truth=`` (relative to root or absolute) if given, else
    ``ground_truth.npy`` or ``ground_truth.csv`` in root (not both), else frame-aligned
    ``|q - r| <= tolerance``, which needs as many query as reference images and no skipped file
    that could be a frame. ``tolerance`` also widens a file's matches (frames).
    """
    tolerance = check_tolerance(tolerance)
    root = check_root(root, "folder", FOLDER_LAYOUT)
    qdir = traverse_dir(root, query, "folder", FOLDER_LAYOUT)
    rdir = traverse_dir(root, reference, "folder", FOLDER_LAYOUT)
    qp, rp = list_images(qdir, "query folder"), list_images(rdir, "reference folder")
    if ground_truth is None:
        names = ("ground_truth.npy", "ground_truth.csv")
        found = [root / f for f in names if check_file(root / f, "folder: ground-truth file")]
        if len(found) > 1:
            raise ValueError(
                f"folder: both {found[0].name} and {found[1].name} exist in {root}; remove one "
                "or choose with ground_truth=<path>."
            )
        gt_file = found[0] if found else None
    else:
        gt_file = resolve_file(root, ground_truth)
    meta: dict[str, Any] = {
        "query_traverse": query,
        "reference_traverse": reference,
        "layout": FOLDER_LAYOUT,
    }
    if gt_file is not None:
        gt = widen(read_ground_truth(gt_file, qp, rp), tolerance)
        check_coverage(gt, str(gt_file))
        meta.update(ground_truth_file=str(gt_file), ground_truth_rule="file")
    else:
        if len(qp) != len(rp):
            raise ValueError(
                f"folder: {len(qp)} query but {len(rp)} reference images in {root}, so the "
                "frame-aligned rule (query i <-> reference i) does not apply; supply a ground-"
                "truth file (ground_truth.npy or ground_truth.csv in root, or ground_truth=<path>)."
            )
        skipped = [
            p
            for p in scan_images(qdir)[1] + scan_images(rdir)[1]
            if p.suffix.lower() not in _NOT_FRAMES
        ]
        if skipped:
            raise ValueError(
                f"folder: {len(skipped)} file(s) in the image folders were skipped as not images "
                f"({', '.join(str(p) for p in skipped[:5])}), so query i <-> reference i would "
                "pair images of different places; give a ground-truth file (ground_truth.npy / "
                ".csv in root, or ground_truth=<path>) or remove those files."
            )
        check_frame_pairs(qp, rp, "folder", strict=False)
        gt = frame_aligned(len(qp), len(rp), tolerance)
        meta.update(ground_truth_rule=f"frame-aligned |q-r|<={tolerance}", frame_aligned=True)
    meta["loader"] = "folder"
    return PlaceDataset(data_name(root), qp, rp, gt, tolerance, root=root, meta=meta)
