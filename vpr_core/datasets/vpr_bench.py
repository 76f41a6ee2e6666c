"""VPR-Bench's dataset layout (Zaffar et al. IJCV 2021): ``query/``, ``ref/``,
``ground_truth_new.npy`` (a restricted, size-bounded pickle); :func:`load_vpr_bench` documents
the layout, the index order and the mask rows."""

from __future__ import annotations

import logging
import os
from pathlib import Path
from typing import Any

import numpy as np

from ..checks import check_choice, check_file
from ._layout import check_root, data_name, resolve_file, traverse_dir, widen
from .base import PlaceDataset
from .ground_truth import check_coverage, check_file_index, check_tolerance
from .images import list_images
from .safe_pickle import read_npy

__all__ = ["VPR_BENCH_LAYOUT", "load_vpr_bench", "read_vprbench_ground_truth"]

log = logging.getLogger("vpr_core")

VPR_BENCH_LAYOUT = (
    "<root>/query/*.jpg, <root>/ref/*.jpg, <root>/ground_truth_new.npy (pickled object array of "
    "rows [query index, [reference indices]])"
)
_ORDERS = ("natural", "lexicographic")


def _as_index(value: Any, path: Path, row: int, what: str) -> np.ndarray:
    """``int64 (k,)`` from a scalar or a list/array of integral numbers (not bools); ValueError
    otherwise."""
    arr = np.asarray(value, dtype=object).ravel()
    try:
        out = None if any(isinstance(v, (bool, np.bool_)) for v in arr) else arr.astype(np.float64)
    except (TypeError, ValueError, OverflowError):
        out = None
    if out is None or not np.all(np.isfinite(out)) or not np.all(out == np.round(out)):
        raise ValueError(
            f"{path}, row {row}: the {what} must be integer indices, got {repr(value)[:80]}; rows "
            "must be [query index, [reference indices]] as in VPR-Bench's ground_truth_new.npy."
        )
    return out.astype(np.int64)


def _mask_or_index(value: Any, path: Path, row: int, nr: int) -> np.ndarray:
    """Reference indices of a row, read from a boolean mask of length ``nr`` or from indices."""
    arr = np.asarray(value, dtype=object).ravel()
    if arr.size and all(isinstance(v, (bool, np.bool_)) for v in arr):
        if arr.size != nr:
            raise ValueError(
                f"{path}, row {row}: the references are a boolean mask of length {arr.size}, but "
                f"the ref folder has {nr} images; a mask needs one entry per reference (or write "
                "reference indices). Is this the file of another dataset, or are images missing?"
            )
        return np.flatnonzero(arr.astype(bool))
    refs = _as_index(value, path, row, "reference indices")
    if nr >= 3 and refs.size == nr and set(refs.tolist()) <= {0, 1}:
        raise ValueError(
            f"{path}, row {row}: the references are {nr} zeros and ones, one per reference: a 0/1 "
            "mask, not indices (which would repeat 0 and 1); write the mask as booleans "
            "(True/False) or the reference indices."
        )
    return refs


def _not_rows(where: str, got: str) -> ValueError:
    """The error of a ground-truth file that is not rows ``[query index, [reference indices]]``."""
    return ValueError(
        f"{where}: expected rows [query index, [reference indices]] as in VPR-Bench's "
        f"ground_truth_new.npy, got {got}."
    )


def _rows(path: Path) -> list:
    arr = read_npy(
        path,
        "a VPR-Bench ground-truth file: a numpy .npy object array of rows "
        "[query index, [reference indices]] (download it again)",
    )
    if isinstance(arr, np.ndarray) and arr.dtype == object and arr.ndim == 0:
        arr = arr.item()
    if isinstance(arr, np.ndarray) and arr.ndim not in (1, 2):
        raise _not_rows(str(path), f"an array of shape {arr.shape}")
    return list(arr)


def read_vprbench_ground_truth(path: str | os.PathLike, nq: int, nr: int) -> np.ndarray:
    """Read VPR-Bench's ``ground_truth_new.npy`` into a ``bool (nq, nr)`` matrix (no tolerance).

    The file is a pickled object array (or list) of rows ``[q, refs]``: ``q`` an integer, ``refs``
    an integer, a list/array of integers (possibly empty) or a boolean mask of length ``nr``.
    """
    path = Path(path)
    if not check_file(path, "VPR-Bench ground-truth file"):
        raise FileNotFoundError(
            f"VPR-Bench ground-truth file not found: {path}; every VPR-Bench dataset ships one "
            f"(ground_truth_new.npy beside query/ and ref/). Expected layout: {VPR_BENCH_LAYOUT}"
        )
    gt = np.zeros((nq, nr), dtype=bool)
    for k, row in enumerate(_rows(path)):
        if not isinstance(row, (list, tuple, np.ndarray)) or len(row) != 2:
            raise _not_rows(f"{path}, row {k}", f"a {type(row).__name__} {repr(row)[:80]}")
        q = _as_index(row[0], path, k, "query index")
        refs = _mask_or_index(row[1], path, k, nr)
        where = f"{path}, row {k}"
        qi = check_file_index(
            int(q[0]) if q.size == 1 else -1, nq, "query", where, repr(row[0])[:80]
        )
        bad = refs[(refs < 0) | (refs >= nr)]
        if bad.size:
            check_file_index(int(bad[0]), nr, "reference", where, str(bad[0]))
        gt[qi, refs] = True
    return gt


def _ordered(paths: list[Path], order: str, side: str) -> list[Path]:
    lexi = sorted(paths, key=lambda p: p.name)
    if lexi != paths:
        log.warning(
            "vpr_bench: the %s file names sort differently naturally and lexicographically "
            "(%s...); ground-truth indices are read against the %s order (order=%r)",
            side,
            ", ".join(p.name for p in paths[:3]),
            order,
            order,
        )
    return lexi if order == "lexicographic" else paths


def load_vpr_bench(
    root: str | os.PathLike | None = None,
    tolerance: int = 0,
    query: str = "query",
    reference: str = "ref",
    ground_truth: str | os.PathLike = "ground_truth_new.npy",
    order: str = "natural",
) -> PlaceDataset:
    """A dataset in VPR-Bench's layout (Gardens Point, SPEDTest, ESSEX3IN1, 17places, ...)::

        <root>/query/*.jpg
        <root>/ref/*.jpg
        <root>/ground_truth_new.npy      # pickled numpy object array, one row per query:
                                         # [query index, [reference indices]]

    The indices in ``ground_truth_new.npy`` index the sorted image lists. Which sort VPR-Bench
    uses could not be checked here, so they are read against the **naturally** sorted lists
    (``2.jpg`` before ``10.jpg``) by default; ``order="lexicographic"`` reads them against plain
    string order instead; when the two orders differ for a folder, loading says so. The file is
    read with the restricted, size-bounded unpickler (:func:`read_vprbench_ground_truth`).
    ``tolerance`` widens the listed matches along the reference sequence (frames).
    """
    tolerance = check_tolerance(tolerance)
    check_choice(order, "vpr_bench order", _ORDERS)
    root = check_root(root, "vpr_bench", VPR_BENCH_LAYOUT)
    qp = _ordered(
        list_images(
            traverse_dir(root, query, "vpr_bench", VPR_BENCH_LAYOUT), "vpr_bench query folder"
        ),
        order,
        "query",
    )
    rp = _ordered(
        list_images(
            traverse_dir(root, reference, "vpr_bench", VPR_BENCH_LAYOUT), "vpr_bench ref folder"
        ),
        order,
        "reference",
    )
    gt_file = resolve_file(root, ground_truth)
    gt = widen(read_vprbench_ground_truth(gt_file, len(qp), len(rp)), tolerance)
    check_coverage(gt, str(gt_file))
    meta = {
        "dataset": root.name,
        "query_traverse": query,
        "reference_traverse": reference,
        "order": order,
        "layout": VPR_BENCH_LAYOUT,
        "ground_truth_file": str(gt_file),
        "ground_truth_rule": "VPR-Bench ground_truth_new.npy",
    }
    meta["loader"] = "vpr_bench"
    return PlaceDataset(data_name(root), qp, rp, gt, tolerance, root=root, meta=meta)
