"""Shared steps of the real-data loaders (package-private): checking the root, finding traverse
folders, pairing frames by the numbers in their names, widening a file's ground truth, and
building a dataset from a correspondence file. The loaders pass parsed input."""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..paths import find_input
from .base import PlaceDataset
from .ground_truth import check_coverage, read_ground_truth
from .images import check_folder, list_images

__all__ = [
    "DOWNLOADABLE",
    "check_frame_pairs",
    "check_root",
    "correspondence_dataset",
    "data_name",
    "listed_paths",
    "resolve_file",
    "traverse_dir",
    "widen",
]


#: The datasets :func:`vpr_study.download_dataset` can fetch (its ``DOWNLOADS``; a test keeps the
#: two equal): their missing-root error says so.
DOWNLOADABLE = frozenset({"gardens_point"})


def check_root(root: str | os.PathLike | None, name: str, layout: str) -> Path:
    """Return ``root`` as a Path to an existing folder, a relative one read from the cwd, else from
    the project root (:func:`vpr_core.paths.find_input`); a clear error naming the fix otherwise
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
    try:
        found = find_input(root)
        problem = "" if found.is_dir() else f"{str(found)!r} is a file, not a folder"
    except FileNotFoundError as exc:
        problem = str(exc)
    if problem:
        hint = (
            f"; or fetch it with vpr_study.download_dataset({name!r}, root)"
            if name in DOWNLOADABLE
            else ""
        )
        raise FileNotFoundError(
            f"dataset {name!r}: root {problem}{hint}. Expected layout: {layout}"
        )
    return found


def data_name(folder: Path) -> str:
    """The name of a file-based dataset: its data folder's name (``corridor``,
    ``gardens_point_mini``), as outputs and titles call it; the loader is in ``meta["loader"]``."""
    resolved = folder.expanduser().resolve()
    return resolved.name or str(resolved)


def traverse_dir(base: Path, sub: str, name: str, layout: str) -> Path:
    """``base / sub``, which must be a folder (the error lists the folders present; a root in
    the ``folder`` layout is pointed to that loader, whose call the message gives)."""
    fix = f"Expected layout: {layout}; or pass the traverse names as options."
    if (base / "query").is_dir() and (base / "reference").is_dir():
        fix = (
            f"{base} holds query/ and reference/ folders, the 'folder' layout: load it with "
            f"load_dataset('folder', root={str(base)!r}). Expected layout of {name}: {layout}."
        )
    return check_folder(base / sub, f"{name}: traverse folder", fix)


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
    check_coverage(gt, str(gt_file))
    meta = dict(
        meta, loader=name, ground_truth_file=str(gt_file), ground_truth_rule="correspondence file"
    )
    return PlaceDataset(data_name(base), qp, rp, gt, tolerance, root=base, meta=meta)


def _frame_number(path: str | os.PathLike) -> int | None:
    """The frame number in a file name: its stem's last run of digits (``Image012.jpg`` -> 12)."""
    digits = re.findall(r"\d+", Path(path).stem)
    return int(digits[-1]) if digits and len(digits[-1]) <= 18 else None


def check_frame_pairs(
    query: Sequence[Path], reference: Sequence[Path], loader: str, strict: bool = True
) -> None:
    """Check that query ``i`` and reference ``i`` carry the same frame number in their names.

    The frame-aligned rule pairs by position; a frame missing on one side (and another on the
    other) would silently pair different places. ``strict``: every name must carry a number
    (Gardens Point); else (``folder``) checked only when every name on both sides carries a
    distinct number and the sides share one. ValueError names the missing frames and files.
    """
    qn = [_frame_number(p) for p in query]
    rn = [_frame_number(p) for p in reference]
    fix = " (or give a ground-truth file)." if not strict else "."
    if None in qn or None in rn:
        if not strict:
            return
        bad = [p for p, n in zip([*query, *reference], [*qn, *rn], strict=True) if n is None]
        raise ValueError(
            f"{loader}: pairing is by the frame number in the file name, but {bad[0]} has "
            "none; restore the dataset's original file names."
        )
    twins: list[tuple[Path, Path, int | None]] = []  # (first file, second file, their number)
    for paths, nums in ((query, qn), (reference, rn)):
        seen: dict[int | None, Path] = {}
        for p, n in zip(paths, nums, strict=True):
            if n in seen:
                twins.append((seen[n], p, n))
            seen.setdefault(n, p)
    if twins and (strict or set(qn) & set(rn)):
        a, b, n = twins[0]
        raise ValueError(
            f"{loader}: pairing is by the frame number in the file name (its stem's last run of "
            f"digits), but {a} and {b} both read as frame {n}, so which one pairs with frame "
            f"{n} of the other side is ambiguous; rename or remove one of them" + fix
        )
    if twins or (not strict and not set(qn) & set(rn)):
        return
    if qn == rn:
        return
    q_nums = [n for n in qn if n is not None]  # all numbered here
    r_nums = [n for n in rn if n is not None]
    q_files = dict(zip(q_nums, query, strict=True))
    r_files = dict(zip(r_nums, reference, strict=True))
    only_q = sorted(set(q_nums) - set(r_nums))
    only_r = sorted(set(r_nums) - set(q_nums))
    parts = []
    for side, only, files in (("query", only_r, r_files), ("reference", only_q, q_files)):
        if only:
            listed = ", ".join(f"{n} ({files[n].name})" for n in only[:5])
            more = " ..." if len(only) > 5 else ""
            parts.append(f"{side} side lacks frame(s) {listed}{more}")
    if not parts:
        parts.append("the two sides list the same frames in a different order")
    raise ValueError(
        f"{loader}: query i and reference i must be the same frame, but the "
        + "; the ".join(parts)
        + ". Restore the missing images, or remove their counterparts from the other side"
        + fix
    )


def widen(gt: np.ndarray, tolerance: int) -> np.ndarray:
    """Widen a ``bool (Nq, Nr)`` match matrix by ``tolerance`` frames along the reference axis."""
    out = gt.copy()
    for t in range(1, min(int(tolerance), gt.shape[1]) + 1):
        out[:, t:] |= gt[:, :-t]
        out[:, :-t] |= gt[:, t:]
    return out
