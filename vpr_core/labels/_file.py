"""Manual match labels in a CSV (:data:`LABEL_COLUMNS`): read, validate, look up, append."""

from __future__ import annotations

import csv
import warnings
from collections.abc import Iterable
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ..checks import check_choice, check_file

__all__ = ["LABEL_COLUMNS", "append_labels", "label_pair_file", "read_label_file"]

#: Columns of a manual-label CSV, in order.
LABEL_COLUMNS = ("query", "reference", "query_box_index", "reference_box_index", "correct")


_TRUTH = dict.fromkeys(("1", "1.0", "true", "t", "yes", "y", "correct"), True)
_TRUTH |= dict.fromkeys(("0", "0.0", "false", "f", "no", "n", "incorrect", "wrong"), False)


def _parse_bool(values: Iterable[Any]) -> np.ndarray:
    out = [_TRUTH.get(str(v).strip().lower()) for v in values]
    if None in out:
        v = list(values)[out.index(None)]
        raise ValueError(
            f"label file: 'correct' value {v!r} is not a boolean (use 1/0, true/false, yes/no)"
        )
    return np.asarray(out, dtype=bool)


def read_label_file(path: str | PathLike) -> Any:
    """Read and validate a manual-label CSV (extra columns ignored): a DataFrame with int
    ``query, reference, query_box_index, reference_box_index`` and bool ``correct``."""
    if not check_file(path, "label file"):
        raise FileNotFoundError(
            f"label file not found: {path}; give the path of the CSV of manual labels."
        )
    df = pd.read_csv(path, skipinitialspace=True)
    df.columns = [str(c).strip() for c in df.columns]
    return _validate_label_frame(df, source=str(path))


def _validate_label_frame(df: Any, source: str = "labels") -> Any:
    missing = [c for c in LABEL_COLUMNS if c not in df.columns]
    if missing:
        raise ValueError(
            f"label file {source}: missing column(s) {missing}; expected header "
            f"'{','.join(LABEL_COLUMNS)}' (got {list(df.columns)})"
        )
    out = df[list(LABEL_COLUMNS)].copy()
    for c in LABEL_COLUMNS[:4]:
        try:
            num = out[c].astype(np.float64)
        except (TypeError, ValueError):
            num = None
        if num is None or num.isna().any() or (num != np.round(num)).any():
            raise ValueError(f"label file {source}: column {c!r} must hold integers")
        out[c] = num.astype(np.int64)
    out["correct"] = _parse_bool(out["correct"])
    return out


def _pair_table(df: Any, q: int, r: int, n_q: int, n_r: int) -> dict[tuple[int, int], bool]:
    """``{(query_box_index, reference_box_index): correct}`` of the rows of pair (q, r)."""
    rows = df[(df["query"] == q) & (df["reference"] == r)]
    qi = rows["query_box_index"].to_numpy()
    ri = rows["reference_box_index"].to_numpy()
    cv = rows["correct"].to_numpy(dtype=bool)
    bad = (qi < 0) | (qi >= n_q) | (ri < 0) | (ri >= n_r)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise ValueError(
            f"label file: pair (q={q}, r={r}) has {int(bad.sum())} row(s) with a box index out "
            f"of range (e.g. query_box_index={qi[k]}, reference_box_index={ri[k]}; the pair has "
            f"{n_q} query and {n_r} reference boxes): labels of another landmark set?"
        )
    table: dict[tuple[int, int], bool] = {}
    for a, b, c in zip(qi.tolist(), ri.tolist(), cv.tolist(), strict=False):
        if (a, b) in table and table[(a, b)] != c:
            raise ValueError(
                f"label file: pair (q={q}, r={r}) labels match ({a}, {b}) both "
                "correct and incorrect"
            )
        table[(a, b)] = c
    return table


def label_pair_file(
    labels: Any,
    q: int,
    r: int,
    bq: np.ndarray,
    br: np.ndarray,
    m: np.ndarray,
    on_unmatched: str = "warn",
) -> np.ndarray:
    """``method="file"`` of :func:`vpr_core.labels.label_matches` on boxes and matches a caller
    already parsed; ``labels``: a CSV path or DataFrame; ``on_unmatched``: a labelled pair not
    among the matches."""
    check_choice(on_unmatched, "on_unmatched", ("warn", "ignore", "error"))
    if labels is None:
        raise ValueError(
            f"method='file' needs labels=<path to CSV> with header '{','.join(LABEL_COLUMNS)}'"
        )
    if isinstance(labels, (str, PathLike)):
        df = read_label_file(labels)
    else:
        df = _validate_label_frame(labels)
    table = _pair_table(df, q, r, len(bq), len(br))
    keys = [(int(a), int(b)) for a, b in m]
    missing = [k for k in keys if k not in table]
    if missing:
        raise ValueError(
            f"label file: {len(missing)} of {len(keys)} matches of pair (q={q}, "
            f"r={r}) have no label row, e.g. {missing[:5]} "
            "(query_box_index, reference_box_index)"
        )
    extra = sorted(set(table) - set(keys))
    if extra:
        msg = (
            f"label file: {len(extra)} labelled pair(s) of (q={q}, r={r}) are not among the "
            f"matches, e.g. {extra[:5]}; ignored"
        )
        if on_unmatched == "error":
            raise ValueError(msg)
        if on_unmatched == "warn":
            warnings.warn(msg, UserWarning, stacklevel=3)
    return np.asarray([table[k] for k in keys], dtype=bool)


def append_labels(
    path: str | PathLike, q: int, r: int, matches: np.ndarray, correct: np.ndarray
) -> Path:
    """Append to (or create) a labels CSV one row per match ``(P, 2)`` of pair ``(q, r)``."""
    matches = np.asarray(matches, dtype=np.int64).reshape(-1, 2)
    correct = np.asarray(correct, dtype=bool).reshape(-1)
    if len(matches) != len(correct):
        raise ValueError(
            f"{len(matches)} matches but {len(correct)} labels: give one label per match."
        )
    path = Path(path)
    new = not path.exists()
    with path.open("a", newline="") as f:
        w = csv.writer(f)
        if new:
            w.writerow(LABEL_COLUMNS)
        for (i, j), c in zip(matches, correct, strict=True):
            w.writerow([q, r, int(i), int(j), int(bool(c))])
    return path
