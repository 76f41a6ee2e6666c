"""Shared steps of the real-data loaders: checking the root, finding traverse folders, and
building a dataset from a correspondence file."""

from __future__ import annotations

import os
from pathlib import Path

from .base import PlaceDataset, list_images
from .ground_truth import check_ground_truth, read_ground_truth, widen

__all__ = ["check_root", "correspondence_dataset", "resolve_file", "traverse_dir"]


def check_root(root: str | os.PathLike | None, name: str, layout: str) -> Path:
    """Return ``root`` as a Path to an existing folder; a clear error naming the fix otherwise.

    Args:
        root: The folder the user passed (None: not passed).
        name: Dataset name, for the messages.
        layout: The expected layout, quoted in the messages.

    Raises:
        ValueError: ``root`` is None.
        FileNotFoundError: it does not exist or is not a folder.
    """
    from .download import DOWNLOADS

    if root is None:
        raise ValueError(
            f"dataset {name!r} needs root=<folder>: call load_dataset({name!r}, root='/path/to/"
            f"{name}'). Expected layout: {layout}"
        )
    root = Path(root).expanduser()
    if not root.exists():
        hint = f" or fetch it with download_dataset({name!r}, root)" if name in DOWNLOADS else ""
        raise FileNotFoundError(
            f"dataset root {root} does not exist: pass the folder that holds {name!r}{hint}. "
            f"Expected layout: {layout}"
        )
    if not root.is_dir():
        raise FileNotFoundError(f"dataset root {root} is not a folder. Expected layout: {layout}")
    return root


def traverse_dir(base: Path, sub: str, name: str, layout: str) -> Path:
    """``base / sub``, which must be a folder (the error lists the sub-folders present)."""
    d = base / sub
    if not d.is_dir():
        found = sorted(p.name for p in base.iterdir() if p.is_dir())
        raise FileNotFoundError(
            f"{name}: traverse folder {d} not found (subfolders present: {found or 'none'}). "
            f"Expected layout: {layout}; or pass the traverse names as options."
        )
    return d


def resolve_file(base: Path, path: str | os.PathLike) -> Path:
    """``path`` if absolute, else ``base / path``."""
    path = Path(path)
    return path if path.is_absolute() else base / path


def correspondence_dataset(
    name: str,
    base: Path,
    query_dir: Path,
    reference_dir: Path,
    gt_file: Path,
    tolerance: int,
    meta: dict,
) -> PlaceDataset:
    """A dataset whose ground truth is a correspondence file, widened by ``tolerance``.

    Args:
        name: Dataset name.
        base: The dataset's root folder.
        query_dir: Query image folder.
        reference_dir: Reference image folder.
        gt_file: ``.csv`` or ``.npy`` ground-truth file (see :mod:`.ground_truth`).
        tolerance: Frames by which the listed matches are widened along the reference axis.
        meta: Details stored in :attr:`PlaceDataset.meta`.

    Raises:
        ValueError: bad file contents, or no positive pair (see :func:`check_ground_truth`).
    """
    qp = list_images(query_dir, f"{name} query folder")
    rp = list_images(reference_dir, f"{name} reference folder")
    gt = widen(read_ground_truth(gt_file, qp, rp), tolerance)
    check_ground_truth(gt, str(gt_file))
    meta = dict(meta, ground_truth_file=str(gt_file), ground_truth_rule="correspondence file")
    return PlaceDataset(name, qp, rp, gt, tolerance, root=base, meta=meta)
