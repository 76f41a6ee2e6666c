"""Ground truth: files, the frame-aligned rule, tolerance widening, coverage checks, and the
pairs picked from it (a query's ground-truth references, sampled query-irrelevant ones).

Ground-truth files accepted by the file-based loaders:

* ``*.npy``: a ``(Nq, Nr)`` matrix of bools or 0/1 numbers.
* ``*.csv`` (UTF-8, a byte-order mark allowed): rows ``query,reference`` (an optional header
  row ``query,reference``; ``#`` comments allowed). Each cell is a 0-based index into the
  naturally sorted image list (when it is all ASCII digits) or an image file name
  (``12.jpg``), a stem (``12`` is read as an index, so use the file name for numeric stems)
  or a path relative to the traverse folder.
  Several rows per query (one-to-many) and several queries per reference (many-to-one) are
  allowed; queries without a row have no ground truth (the evaluation drops them, and
  :func:`check_ground_truth` warns with the count). When one side's numeric cells look 1-based
  (at least two distinct values, no ``0`` among them, and the largest equals the number of
  distinct values, i.e. ``1..k``) a warning says that they were read as 0-based indices.

Tolerance: on frame-aligned traverses ``ground_truth[q, r] = |q - r| <= tolerance``
(:func:`frame_aligned`); on a correspondence file the listed matches are widened along the
reference sequence by ``tolerance`` frames (:func:`widen`; ``0``: exactly the listed pairs).
"""

from __future__ import annotations

import contextlib
import csv
import io
import os
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..notices import notice
from .safe_pickle import read_npy

__all__ = [
    "check_frame_pairs",
    "check_ground_truth",
    "check_tolerance",
    "frame_number",
    "frame_aligned",
    "ground_truth_coverage",
    "ground_truth_references",
    "ground_truth_text",
    "read_ground_truth",
    "sample_irrelevant_references",
    "widen",
]


def check_tolerance(tolerance: Any) -> int:
    """Return ``tolerance`` as an int >= 0 (frames); ValueError otherwise."""
    if isinstance(tolerance, bool) or not isinstance(tolerance, (int, np.integer)) or tolerance < 0:
        raise ValueError(f"tolerance must be an int >= 0 (frames), got {tolerance!r}.")
    return int(tolerance)


def frame_aligned(nq: int, nr: int, tolerance: int) -> np.ndarray:
    """Frame-aligned ground truth ``bool (nq, nr)``: ``|q - r| <= tolerance``."""
    q = np.arange(nq)[:, None]
    r = np.arange(nr)[None, :]
    return np.abs(q - r) <= tolerance


def frame_number(path: str | os.PathLike) -> int | None:
    """The frame number in a file name: its stem's last run of digits (``Image012.jpg`` -> 12)."""
    digits = re.findall(r"\d+", Path(path).stem)
    return int(digits[-1]) if digits and len(digits[-1]) <= 18 else None


def check_frame_pairs(
    query: Sequence[Path], reference: Sequence[Path], loader: str, strict: bool = True
) -> None:
    """Check that query ``i`` and reference ``i`` carry the same frame number in their names.

    The frame-aligned rule pairs by position; a frame missing on one side (and another on the
    other, so the counts still agree) would silently pair different places.

    Args:
        query: Query image files in dataset order.
        reference: Reference image files in dataset order.
        loader: The loader's name, for errors.
        strict: True (datasets named by frame number, e.g. Gardens Point): every name must carry
            a number. False (``folder``): checked only when every name on both sides carries a
            distinct number and the two sides share at least one (timestamps per traverse, or
            names without numbers, keep pairing by position).

    Raises:
        ValueError: the counts differ or a frame is missing on one side (the message names the
            missing frames and their files).
    """
    qn = [frame_number(p) for p in query]
    rn = [frame_number(p) for p in reference]
    numbered = None not in qn and None not in rn
    distinct = numbered and len(set(qn)) == len(qn) and len(set(rn)) == len(rn)
    if not strict and (not distinct or not set(qn) & set(rn)):
        return
    if strict and not distinct:
        bad = [str(p) for p, n in zip([*query, *reference], [*qn, *rn], strict=True) if n is None]
        raise ValueError(
            f"{loader}: pairing is by the frame number in the file name, but "
            + (f"{bad[0]} has none" if bad else "two files carry the same number")
            + "; restore the dataset's original file names."
        )
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
        + (" (or give a ground-truth file)." if not strict else ".")
    )


def widen(gt: np.ndarray, tolerance: int) -> np.ndarray:
    """Widen a ``bool (Nq, Nr)`` match matrix by ``tolerance`` frames along the reference axis."""
    out = gt.copy()
    for t in range(1, min(int(tolerance), gt.shape[1]) + 1):
        out[:, t:] |= gt[:, :-t]
        out[:, :-t] |= gt[:, t:]
    return out


# ----------------------------------------------------------------------------------------------
# Coverage
# ----------------------------------------------------------------------------------------------


def ground_truth_coverage(gt: np.ndarray) -> tuple[int, int]:
    """How many queries have ground truth.

    Args:
        gt: ``bool (Nq, Nr)`` ground truth.

    Returns:
        ``(n_queries_with_gt, n_queries)``: rows with at least one True, and ``Nq``.
    """
    gt = np.asarray(gt)
    if gt.ndim != 2:
        raise ValueError(f"ground truth must be a (Nq, Nr) matrix, got shape {gt.shape}.")
    return int(gt.astype(bool).any(axis=1).sum()), int(gt.shape[0])


def ground_truth_text(ground_truth: np.ndarray, tolerance: object, from_file: bool) -> str:
    """How a dataset's ground truth was made, for tables and titles.

    Args:
        ground_truth: ``bool (Nq, Nr)``.
        tolerance: the dataset's tolerance (frames, or e.g. ``"25 m"``).
        from_file: the correct pairs were read from a file (``meta["ground_truth_file"]``).

    Returns:
        ``"ground truth from file: 1-5 correct references per query (median 5)"`` for a file
        (``", widened by N frames"`` when a tolerance was applied), else ``"tolerance N"``.
    """
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


def check_ground_truth(gt: np.ndarray, source: str) -> tuple[int, int]:
    """Refuse ground truth that cannot support a metric; warn when it covers only some queries.

    Args:
        gt: ``bool (Nq, Nr)`` ground truth (tolerance applied).
        source: Where it came from (a file path or a rule), named in the messages.

    Returns:
        ``(n_queries_with_gt, n_queries)`` as :func:`ground_truth_coverage`.

    Raises:
        ValueError: no positive pair at all (every metric would be 0 or undefined).
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
    arr = np.asarray(
        read_npy(path, f"a ({nq}, {nr}) bool or 0/1 matrix saved with np.save(path, matrix)")
    )
    if arr.shape != (nq, nr):
        raise ValueError(
            f"ground truth {path} has shape {arr.shape} but the dataset has {nq} query and "
            f"{nr} reference images, so it must be ({nq}, {nr}); fix the matrix or the image "
            "folders so they agree."
        )
    if arr.dtype != np.bool_ and (
        not np.issubdtype(arr.dtype, np.number) or not np.isin(arr, (0, 1)).all()
    ):
        raise ValueError(
            f"ground truth {path} must hold bools or 0/1 numbers, got dtype {arr.dtype} "
            "with other values; save a bool matrix (gt.astype(bool))."
        )
    return arr.astype(bool)


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
        if j >= n:
            hint = " (the cells look 1-based: subtract 1)" if one_based else ""
            raise ValueError(
                f"{path}, line {line}: {side} index {cell[:20]}{'...' if len(cell) > 20 else ''} "
                f"out of range (the dataset has {n} "
                f"{side} images, indices 0..{n - 1}){hint}; fix the file or the image folder."
            )
        return j
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
    """Read a ground-truth file (``.npy`` matrix or ``.csv`` correspondence list).

    Args:
        path: ``*.npy`` with a ``(Nq, Nr)`` bool or 0/1 matrix, or ``*.csv`` with
            ``query,reference`` rows (indices or file names, see the module docstring).
        query_paths: The ``Nq`` query files (names resolve CSV cells).
        reference_paths: The ``Nr`` reference files.

    Returns:
        ``bool (Nq, Nr)`` match matrix (no tolerance applied, coverage not checked: the loaders
        call :func:`check_ground_truth` after widening).

    Raises:
        FileNotFoundError: no such file.
        ValueError: unknown format, a shape that does not fit the images, bad values or rows.
    """
    path = Path(path)
    nq, nr = len(query_paths), len(reference_paths)
    if not path.is_file():
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
    """Ground-truth references of query ``q`` used for the statistics.

    Args:
        ground_truth: ``(Nq, Nr)`` bool.
        q: query index.
        mode: ``"center"``: one reference per query — ``q`` itself when ``ground_truth[q, q]``
            (frame-aligned datasets), else the middle of the true references (the centre of the
            tolerance window / correspondence list). ``"all"``: every true reference.

    Returns:
        list of reference indices (empty when the query has no ground truth).
    """
    row = np.flatnonzero(np.asarray(ground_truth, dtype=bool)[q])
    if len(row) == 0:
        return []
    if mode == "all":
        return [int(x) for x in row]
    if mode != "center":
        raise ValueError(f"gt_pairs must be 'center' or 'all', got {mode!r}")
    if q in row:
        return [int(q)]
    return [int(row[(len(row) - 1) // 2])]


def sample_irrelevant_references(
    ground_truth: np.ndarray,
    n_irrelevant: int = 5,
    seed: int = 0,
    queries: Sequence[int] | None = None,
) -> dict[int, list[int]]:
    """Query-irrelevant references: per query, ``n_irrelevant`` references with
    ``ground_truth[q, r] == False`` drawn without replacement (fewer when fewer exist), with one
    ``np.random.default_rng(seed)`` consumed query by query in increasing order; returned sorted.

    Args:
        ground_truth: ``(Nq, Nr)`` bool.
        n_irrelevant: references per query.
        seed: RNG seed.
        queries: the queries to sample for (default all).

    Returns:
        ``{q: [r, ...]}``.
    """
    gt = np.asarray(ground_truth, dtype=bool)
    rng = np.random.default_rng(seed)
    qs = range(gt.shape[0]) if queries is None else sorted(int(x) for x in queries)
    out: dict[int, list[int]] = {}
    for q in qs:
        cand = np.flatnonzero(~gt[q])
        k = min(int(n_irrelevant), len(cand))
        out[q] = sorted(int(x) for x in rng.choice(cand, size=k, replace=False)) if k else []
    return out
