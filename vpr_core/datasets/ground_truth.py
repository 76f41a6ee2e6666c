"""Ground truth: its checks (:func:`check_ground_truth`: shape and values; :func:`check_coverage`:
positive pairs), files (:func:`read_ground_truth`), the frame-aligned rule, and the pairs picked
from it (ground-truth and query-irrelevant references)."""

from __future__ import annotations

import contextlib
import csv
import io
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..checks import check_choice, check_file, check_int, check_shape
from ..notices import notice
from .safe_pickle import read_npy

__all__ = [
    "check_coverage",
    "check_file_index",
    "check_ground_truth",
    "check_tolerance",
    "frame_aligned",
    "ground_truth_coverage",
    "ground_truth_references",
    "ground_truth_text",
    "read_ground_truth",
    "sample_irrelevant_references",
]


def check_tolerance(tolerance: Any) -> int:
    """Return ``tolerance`` as an int >= 0 (frames); ValueError otherwise."""
    return check_int(tolerance, "tolerance (frames)")


def frame_aligned(nq: int, nr: int, tolerance: int) -> np.ndarray:
    """Frame-aligned ground truth ``bool (nq, nr)``: ``|q - r| <= tolerance``."""
    q = np.arange(nq)[:, None]
    r = np.arange(nr)[None, :]
    return np.abs(q - r) <= tolerance


# ----------------------------------------------------------------------------------------------
# Coverage
# ----------------------------------------------------------------------------------------------


def ground_truth_coverage(gt: np.ndarray) -> tuple[int, int]:
    """``(queries with at least one true reference, Nq)`` of a ``bool (Nq, Nr)`` ground truth."""
    gt = check_shape(gt, "Nq Nr", "ground truth")
    return int(gt.astype(bool).any(axis=1).sum()), int(gt.shape[0])


def ground_truth_text(ground_truth: np.ndarray, tolerance: object, from_file: bool) -> str:
    """How a dataset's ground truth was made, for tables and titles: ``"tolerance N"``, or for
    a file ``"ground truth from file: 1-5 correct references per query (median 5)"`` (plus
    ``", widened by N frames"`` when a tolerance was applied)."""
    if not from_file:
        return f"tolerance {tolerance}"
    counts = np.asarray(ground_truth, dtype=bool).sum(axis=1)
    counts = counts[counts > 0]
    if not len(counts):
        return "ground truth from file: no query has a correct reference"
    lo, hi, med = int(counts.min()), int(counts.max()), float(np.median(counts))
    span = f"{lo}" if lo == hi else f"{lo}-{hi}"
    noun = "reference" if hi == 1 else "references"
    text = f"ground truth from file: {span} correct {noun} per query (median {med:g})"
    if tolerance not in (0, None, "0"):
        text += f", widened by {tolerance} frames"
    return text


def check_ground_truth(gt: Any, shape: tuple[int, int], source: str) -> np.ndarray:
    """Return ``gt`` as a ``bool (Nq, Nr)`` match matrix: it must have ``shape = (Nq, Nr)`` (query
    x reference images) and hold bools or 0/1 numbers. ``source`` names it in the messages (a
    file, ``"of PlaceDataset 'x'"``)."""
    arr, want = np.asarray(gt), tuple(shape)
    if arr.ndim != 2 or arr.shape != want:
        need = "a (Nq, Nr) matrix (query x reference images)"
        if len(want) == 2:
            need = f"({want[0]}, {want[1]}) for {want[0]} query and {want[1]} reference images"
        raise ValueError(
            f"ground truth {source} has shape {arr.shape} but must be {need}; fix the ground "
            "truth or the image folders so they agree."
        )
    if arr.dtype != np.bool_ and (
        not np.issubdtype(arr.dtype, np.number) or not np.isin(arr, (0, 1)).all()
    ):
        raise ValueError(
            f"ground truth {source} must hold bools or 0/1 numbers, got dtype {arr.dtype} "
            "with other values; pass a bool matrix (gt.astype(bool) once it holds only 0/1)."
        )
    return arr.astype(bool, copy=False)


def check_coverage(gt: np.ndarray, source: str) -> tuple[int, int]:
    """Refuse ground truth without a positive pair; warn when it covers only some queries.

    Returns :func:`ground_truth_coverage`; ``source`` (a file or a rule) is named in messages.
    """
    covered, nq = ground_truth_coverage(gt)
    if covered == 0:
        raise ValueError(
            f"ground truth from {source} has no positive pair ({nq} queries x {np.shape(gt)[1]} "
            "references, all False), so no metric can be computed. Check that the file lists "
            "matching pairs for these image folders (names / 0-based indices), or use a larger "
            "tolerance."
        )
    if covered < nq:
        notice(
            f"ground truth from {source} covers {covered} of {nq} queries; the other "
            f"{nq - covered} are dropped from every metric"
        )
    return covered, nq


def check_file_index(index: int, n: int, side: str, where: str, shown: str, hint: str = "") -> int:
    """Return ``index`` if a ground-truth file's cell indexes one of the ``n`` ``side`` images.

    ``where`` is the file and its line or row, ``shown`` the cell as written, ``hint`` an extra
    clue; the ValueError asks to fix the file or the image folder.
    """
    if not 0 <= index < n:
        raise ValueError(
            f"{where}: {side} index {shown} out of range (there are {n} {side} images, indices "
            f"0..{n - 1}){hint}; fix the file or the image folder (is it the file of another "
            "dataset, or are images missing?)."
        )
    return index


# ----------------------------------------------------------------------------------------------
# Files
# ----------------------------------------------------------------------------------------------


def _name_index(paths: Sequence[Path], base: Path | None) -> dict[str, int]:
    index: dict[str, int] = {}
    stems: dict[str, list[int]] = {}
    for i, p in enumerate(paths):
        index[p.name] = i
        stems.setdefault(p.stem, []).append(i)
        if base is not None:
            with contextlib.suppress(ValueError):
                index[p.relative_to(base).as_posix()] = i
    for stem, idx in stems.items():
        if len(idx) == 1:
            index.setdefault(stem, idx[0])
    return index


def _read_npy(path: Path, nq: int, nr: int) -> np.ndarray:
    arr = read_npy(path, f"a ({nq}, {nr}) bool or 0/1 matrix saved with np.save(path, matrix)")
    return check_ground_truth(arr, (nq, nr), str(path))


def _csv_rows(path: Path) -> list[tuple[int, str, str]]:
    """``(line, query cell, reference cell)`` of every data row of a correspondence CSV."""
    rows: list[tuple[int, str, str]] = []
    data = path.read_bytes()
    try:
        text = data.decode("utf-8-sig")  # a UTF-8 byte-order mark (Excel's "CSV UTF-8") is fine
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise ValueError(
            f"{path}, line {line}: not UTF-8 text (byte 0x{data[exc.start]:02x} cannot be "
            "decoded); ground-truth CSVs are read as UTF-8: save the file as UTF-8 (e.g. "
            "'CSV UTF-8' in a spreadsheet, or `iconv -f latin1 -t utf-8`)."
        ) from None
    for line, row in enumerate(csv.reader(io.StringIO(text, newline="")), start=1):
        cells = [c.strip() for c in row]
        if not cells or all(not c for c in cells) or cells[0].startswith("#"):
            continue
        if not rows and [c.lower() for c in cells] == ["query", "reference"]:
            continue
        if len(cells) != 2:
            raise ValueError(
                f"{path}, line {line}: expected 2 columns 'query,reference', got {len(cells)} "
                f"({row!r}); write one query,reference pair per row."
            )
        rows.append((line, cells[0], cells[1]))
    if not rows:
        raise ValueError(
            f"ground-truth file {path} has no query,reference rows; add one row per matching pair."
        )
    return rows


def _is_index(cell: str) -> bool:
    """True for a cell of ASCII digits (``str.isdigit`` also accepts ``²`` and other scripts)."""
    return cell.isascii() and cell.isdigit()


def _looks_one_based(path: Path, cells: list[str], paths: Sequence[Path], side: str) -> bool:
    """Warn when a side's numeric cells look 1-based; return True if they do."""
    values = {int(c) for c in cells if _is_index(c) and len(c) <= 18}
    if len(values) < 2 or 0 in values or max(values) != len(values):
        return False
    first = paths[1].name if len(paths) > 1 else "(none)"
    notice(
        f"{path}: the {side} cells are numbers 1..{max(values)} with no 0, which looks 1-based; "
        f"they were read as 0-based indices into the naturally sorted {side} images (cell '1' = "
        f"{first}). If they are 1-based numbers or file stems, subtract 1 or write file names.",
        stacklevel=5,
    )
    return True


def _resolve(
    path: Path, line: int, cell: str, names: dict[str, int], n: int, side: str, one_based: bool
) -> int:
    if _is_index(cell):
        j = int(cell) if len(cell) <= 18 else n  # int() refuses > 4,300 digits: out of range
        shown = cell[:20] + ("..." if len(cell) > 20 else "")
        hint = " (the cells look 1-based: subtract 1)" if one_based else ""
        return check_file_index(j, n, side, f"{path}, line {line}", shown, hint)
    if cell in names:
        return names[cell]
    raise ValueError(
        f"{path}, line {line}: {side} image {cell!r} is not in the {side} folder; use a file "
        f"name from that folder or a 0-based index."
    )


def _read_csv(
    path: Path, query_paths: Sequence[Path], reference_paths: Sequence[Path]
) -> np.ndarray:
    nq, nr = len(query_paths), len(reference_paths)
    rows = _csv_rows(path)
    q_one = _looks_one_based(path, [q for _, q, _ in rows], query_paths, "query")
    r_one = _looks_one_based(path, [r for _, _, r in rows], reference_paths, "reference")
    qnames = _name_index(query_paths, query_paths[0].parent if nq else None)
    rnames = _name_index(reference_paths, reference_paths[0].parent if nr else None)
    gt = np.zeros((nq, nr), dtype=bool)
    for line, qc, rc in rows:
        q = _resolve(path, line, qc, qnames, nq, "query", q_one)
        r = _resolve(path, line, rc, rnames, nr, "reference", r_one)
        gt[q, r] = True
    return gt


def read_ground_truth(
    path: str | os.PathLike,
    query_paths: Sequence[Path],
    reference_paths: Sequence[Path],
) -> np.ndarray:
    """Read a ground-truth file into a ``bool (Nq, Nr)`` match matrix (no tolerance applied).

    ``*.npy``: a ``(Nq, Nr)`` matrix of bools or 0/1 numbers. ``*.csv`` (UTF-8, a BOM allowed):
    rows ``query,reference`` (optional header, ``#`` comments); a cell is a 0-based index into
    the naturally sorted image list (all ASCII digits), a file name, a unique stem or a path
    relative to the traverse folder. One-to-many and many-to-one rows are allowed; queries
    without a row have no ground truth. Numeric cells that look 1-based (``1..k``, no ``0``)
    are read as 0-based, with a warning. See docs/DEFINITIONS.md for the tolerance rules.
    """
    path = Path(path)
    nq, nr = len(query_paths), len(reference_paths)
    if not check_file(path, "ground-truth file"):
        raise FileNotFoundError(
            f"ground-truth file not found: {path}; create it (a .npy (Nq, Nr) matrix or a .csv "
            "with query,reference rows) or pass ground_truth=<path> to the loader."
        )
    suffix = path.suffix.lower()
    if suffix == ".npy":
        return _read_npy(path, nq, nr)
    if suffix != ".csv":
        raise ValueError(
            f"unsupported ground-truth file {path}: use a .npy (Nq, Nr) matrix or a .csv with "
            "query,reference rows."
        )
    return _read_csv(path, query_paths, reference_paths)


def ground_truth_references(ground_truth: np.ndarray, q: int, mode: str = "center") -> list[int]:
    """Ground-truth references of query ``q`` used for the statistics (empty when none).

    ``mode="center"``: one reference, ``q`` itself when ``ground_truth[q, q]`` (frame-aligned
    datasets), else the middle of the true references; ``"all"``: every true reference.
    """
    check_choice(mode, "gt_pairs", ("center", "all"))
    row = np.flatnonzero(np.asarray(ground_truth, dtype=bool)[q])
    if len(row) == 0:
        return []
    if mode == "all":
        return [int(x) for x in row]
    if q in row:
        return [int(q)]
    return [int(row[(len(row) - 1) // 2])]


def sample_irrelevant_references(
    ground_truth: np.ndarray,
    n_irrelevant: int = 5,
    seed: int = 0,
    queries: Sequence[int] | None = None,
) -> dict[int, list[int]]:
    """``{q: sorted [r, ...]}``: per query (default all), ``n_irrelevant`` references with
    ``ground_truth[q, r] == False`` drawn without replacement (fewer when fewer exist), with one
    ``np.random.default_rng(seed)`` consumed query by query in increasing order."""
    gt = np.asarray(ground_truth, dtype=bool)
    rng = np.random.default_rng(seed)
    qs = range(gt.shape[0]) if queries is None else sorted(int(x) for x in queries)
    out: dict[int, list[int]] = {}
    for q in qs:
        cand = np.flatnonzero(~gt[q])
        k = min(int(n_irrelevant), len(cand))
        out[q] = sorted(int(x) for x in rng.choice(cand, size=k, replace=False)) if k else []
    return out
