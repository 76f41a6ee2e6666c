"""Manual match labels from a CSV (as the paper labelled Gardens Point by hand).

Header: ``query,reference,query_box_index,reference_box_index,correct`` (:data:`LABEL_COLUMNS`);
:func:`vpr_core.labels.append_labels` writes this format.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable
from os import PathLike
from typing import Any

import numpy as np

from ..boxes import check_boxes
from .exact import check_matches

__all__ = ["LABEL_COLUMNS", "label_matches_file", "read_label_file"]

#: Columns of a manual-label CSV, in order.
LABEL_COLUMNS = ("query", "reference", "query_box_index", "reference_box_index", "correct")


def _parse_bool(values: Iterable[Any]) -> np.ndarray:
    truthy = {"1", "true", "t", "yes", "y", "correct"}
    falsy = {"0", "false", "f", "no", "n", "incorrect", "wrong"}
    out = []
    for v in values:
        s = str(v).strip().lower()
        if s in ("1.0",):
            s = "1"
        if s in ("0.0",):
            s = "0"
        if s in truthy:
            out.append(True)
        elif s in falsy:
            out.append(False)
        else:
            raise ValueError(
                f"label file: 'correct' value {v!r} is not a boolean (use 1/0, true/false, yes/no)"
            )
    return np.asarray(out, dtype=bool)


def read_label_file(path: str | PathLike) -> Any:
    """Read and validate a manual-label CSV.

    The header must contain ``query,reference,query_box_index,reference_box_index,correct``
    (extra columns are ignored). ``correct`` accepts 1/0, true/false, yes/no.

    Args:
        path: the CSV file.

    Returns:
        pandas DataFrame with int columns ``query, reference, query_box_index,
        reference_box_index`` and bool ``correct``.

    Raises:
        FileNotFoundError: no such file.
        ValueError: missing columns (the message names the expected header), non-integer indices
            or non-boolean labels.
    """
    import pandas as pd

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
        col = out[c]
        try:
            num = col.astype(np.float64)
        except (TypeError, ValueError) as e:
            raise ValueError(f"label file {source}: column {c!r} must hold integers") from e
        if num.isna().any() or (num != np.round(num)).any():
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


def label_matches_file(
    labels: Any,
    q: int,
    r: int,
    boxes_q: np.ndarray,
    boxes_r: np.ndarray,
    matches: np.ndarray,
    on_unmatched: str = "warn",
) -> np.ndarray:
    """Labels looked up in a manual-label CSV (path or already-read DataFrame).

    Rules for rows of pair (q, r):

    * a box index outside ``0..K-1`` of its boxes -> ``ValueError`` (labels of another landmark
      set);
    * a match without a row -> ``ValueError`` listing the unlabelled matches;
    * two rows of the same match that disagree -> ``ValueError``; identical duplicates are fine;
    * a labelled pair that is not among the matches -> a ``UserWarning`` (``on_unmatched="warn"``,
      default; e.g. labels made with another matcher setting), ignored (``"ignore"``) or an error
      (``"error"``).

    Args:
        labels: CSV path or a DataFrame with :data:`LABEL_COLUMNS`.
        q: query index.
        r: reference index.
        boxes_q: ``(Kq, 4)`` query boxes.
        boxes_r: ``(Kr, 4)`` reference boxes.
        matches: ``(P, 2)`` (query box index, reference box index).
        on_unmatched: ``"warn"``, ``"ignore"`` or ``"error"`` (see above).

    Returns:
        ``(P,)`` bool labels.
    """
    bq, br = check_boxes(boxes_q, "boxes_q"), check_boxes(boxes_r, "boxes_r")
    m = check_matches(matches, len(bq), len(br))
    if on_unmatched not in ("warn", "ignore", "error"):
        raise ValueError(f"on_unmatched must be 'warn', 'ignore' or 'error', got {on_unmatched!r}")
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
