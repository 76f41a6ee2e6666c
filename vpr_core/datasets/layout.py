"""Shared steps of the real-data loaders: checking the root, finding traverse folders, and
building a dataset from a correspondence file."""

from __future__ import annotations

import os
from pathlib import Path

from .base import PlaceDataset
from .download import DOWNLOADS
from .ground_truth import check_ground_truth, read_ground_truth, widen
from .images import list_images


def check_root(root: str | os.PathLike | None, name: str, layout: str) -> Path:
    """Return ``root`` as a Path to an existing folder; a clear error naming the fix otherwise
    (``name`` and the expected ``layout`` are quoted in the messages)."""
    if root is None or (isinstance(root, (str, os.PathLike)) and not str(root).strip()):
        raise ValueError(
            f"dataset {name!r} needs root=<folder>"
            + (" (got an empty string; use '.' for the current folder)" if root is not None else "")
            + f": call load_dataset({name!r}, root='/path/to/{name}'). Expected layout: {layout}"
        )
    if not isinstance(root, (str, os.PathLike)):
        raise ValueError(
            f"dataset {name!r}: root must be a folder path (str or Path), got "
            f"{type(root).__name__} {root!r}."
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


def data_name(folder: Path) -> str:
    """The name of a file-based dataset: its data folder's name (``corridor``,
    ``gardens_point_mini``), as outputs and titles call it; the loader is in ``meta["loader"]``."""
    resolved = folder.expanduser().resolve()
    return resolved.name or str(resolved)


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


def listed_paths(listing: Path, folder: Path, name: str) -> list[Path]:
    """The files a paths list names (one per line, relative to ``folder``; blank lines skipped).

    Raises:
        ValueError: an absolute path or one that leaves ``folder`` (``..``, a symlink out): listed
            paths stay under their folder.
    """
    lines = [s.strip() for s in listing.read_text(encoding="utf-8-sig").splitlines()]
    inside = folder.resolve()
    paths = []
    for n, line in enumerate(lines, 1):
        if not line:
            continue
        if "\0" in line:
            raise ValueError(
                f"{name}: {listing} line {n} holds a NUL character, which no file name can "
                "contain; the list is damaged or not a text file. Fix the line."
            )
        path = folder / line
        if Path(line).is_absolute() or not path.resolve().is_relative_to(inside):
            raise ValueError(
                f"{name}: {listing} line {n} names {line!r}, which is outside {folder}; paths in "
                "the list must be relative to that folder and stay inside it. Fix the line."
            )
        paths.append(path)
    return paths


def correspondence_dataset(
    name: str,
    base: Path,
    query_dir: Path,
    reference_dir: Path,
    gt_file: Path,
    tolerance: int,
    meta: dict,
) -> PlaceDataset:
    """A dataset whose ground truth is a correspondence file, widened by ``tolerance`` frames;
    ``name`` is the loader's (the dataset is named by :func:`data_name` of ``base``)."""
    qp = list_images(query_dir, f"{name} query folder")
    rp = list_images(reference_dir, f"{name} reference folder")
    gt = widen(read_ground_truth(gt_file, qp, rp), tolerance)
    check_ground_truth(gt, str(gt_file))
    meta = dict(
        meta, loader=name, ground_truth_file=str(gt_file), ground_truth_rule="correspondence file"
    )
    return PlaceDataset(data_name(base), qp, rp, gt, tolerance, root=base, meta=meta)
