"""The per-query view of one or more results: where each ranks the right place, and which queries
two runs decide differently (:func:`per_query`; the figures read its frame)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd

from ..matching.similarity import match_landmarks, weighted_matches
from ..matching.spec import Matching
from ..notices import notice
from .compare import check_results, check_same_dataset
from .ranks import best_two, query_scores, ranked, true_rank

__all__ = ["CONTRAST_COLUMN", "PER_QUERY_COLUMNS", "per_query"]

#: The columns of :func:`per_query`, in order.
PER_QUERY_COLUMNS = (
    "query",
    "run",
    "first correct rank",
    "top-1",
    "top-1 correct",
    "ratio",
    "top-1 matches",
    "wrong top-1 distance",
    "disagree",
)
#: (Not in the paper) the column :func:`per_query` adds with ``contrast=True``.
CONTRAST_COLUMN = "contrast zero share"


def _top1_matches(result: Any, queries: np.ndarray, top1: np.ndarray) -> np.ndarray:
    """``(n,)`` reciprocal landmark matches of each query's top-1 pair; NaN without descriptors
    (``keep_descriptors=False``, or a peer's matrix) or where nothing was retrieved."""
    out = np.full(len(queries), np.nan)
    desc = getattr(result, "descriptors", None)
    if desc is None:
        return out
    boxes = result.boxes
    for i, (q, r) in enumerate(zip(queries.tolist(), top1.tolist(), strict=True)):
        if r >= 0:
            m = match_landmarks(
                desc["query"][q], boxes["query"][q], desc["reference"][r], boxes["reference"][r]
            )
            out[i] = len(m.matches)
    return out


def _sequence(result: Any) -> bool:
    """Frame-aligned ground truth (``|q - r| <= tolerance``), not read from a file."""
    return result.tolerance is not None and not getattr(result, "ground_truth_from_file", False)


def _wrong_distance(gt: np.ndarray, top1: np.ndarray, correct: np.ndarray) -> np.ndarray:
    """``(n,)`` reference indices from each wrong top-1 to the nearest correct reference (NaN
    where the top-1 is correct, nothing was retrieved or the query has no correct reference)."""
    out = np.full(len(top1), np.nan)
    cols = np.arange(gt.shape[1])
    for i in np.flatnonzero(~correct & (top1 >= 0) & gt.any(axis=1)):
        out[i] = np.abs(cols[gt[i]] - top1[i]).min()
    return out


def _contrast_zero_share(result: Any, queries: np.ndarray, top1: np.ndarray) -> np.ndarray:
    """``(n,)`` share of the top-1 pair's reciprocal matches whose ``contrast`` weight is 0 (NaN
    without descriptors, without a top-1 or without a match); statistics as the run's matching
    would compute them (all references, or the shortlist's sample)."""
    out = np.full(len(queries), np.nan)
    desc = getattr(result, "descriptors", None)
    keep = top1 >= 0
    if desc is None or not keep.any():
        return out
    d, b = desc, result.boxes
    nr = len(d["reference"])
    sample = None if getattr(result, "shortlist", None) else np.arange(nr)
    pairs = np.stack([queries[keep], top1[keep]], axis=1)
    ms = weighted_matches(
        d["query"],
        b["query"],
        d["reference"],
        b["reference"],
        pairs,
        Matching(weighting="contrast"),
        sample,
    )
    out[keep] = [np.mean(m.weights == 0) if len(m.matches) else np.nan for m in ms]
    return out


def _one_run(result: Any, gt: np.ndarray, queries: np.ndarray, contrast: bool) -> pd.DataFrame:
    """The rows of one run on ``queries`` (indices of queries with ground truth)."""
    s = np.asarray(result.similarity, dtype=np.float64)[queries]
    g = gt[queries]
    rows = ranked(s)
    rank = true_rank(s, g).astype(np.float64)
    rank[rank == np.iinfo(np.int64).max] = np.nan  # no correct reference ranked
    top1 = np.full(len(queries), -1)
    ratio = np.full(len(queries), np.nan)
    if rows.any():
        top1[rows] = best_two(s[rows])[0]
        ratio[rows] = query_scores(s[rows], g[rows], ratio=True)[0]
    correct = rows & g[np.arange(len(queries)), np.maximum(top1, 0)]
    far = _wrong_distance(g, top1, correct) if _sequence(result) else np.full(len(queries), np.nan)
    table = pd.DataFrame(
        {
            "query": queries,
            "run": result.label,
            "first correct rank": pd.array(rank + 1, dtype="Int64"),
            "top-1": pd.array(np.where(top1 >= 0, top1, np.nan), dtype="Int64"),
            "top-1 correct": correct,
            "ratio": ratio,
            "top-1 matches": _top1_matches(result, queries, top1),
            "wrong top-1 distance": far,
        }
    )
    if contrast:
        table[CONTRAST_COLUMN] = _contrast_zero_share(result, queries, top1)
    return table


def per_query(results: Any | Sequence[Any], contrast: bool = False) -> pd.DataFrame:
    """For every query with ground truth and every run: how the run ranked it.

    Args:
        results: one or more :class:`~vpr_core.MethodResult` (or peers) of one dataset.
            The match counts need descriptors: run with ``run_method(...,
            keep_descriptors=True)``; without them the column is NaN and a warning says so.
        contrast: (not in the paper) add the column ``contrast zero share``: of the reciprocal
            matches of each query's top-1 pair, the share whose ``weighting="contrast"`` weight
            is 0 (docs/DEFINITIONS.md; needs descriptors, NaN without; it computes each
            query's statistics, so it takes about as long as the weighted matching).

    Returns:
        One row per (query, run), columns :data:`PER_QUERY_COLUMNS`: ``first correct rank``
        (1 = top-1; NA when no correct reference is ranked), ``top-1`` (reference index, NA when
        the query retrieved nothing: an image without landmarks), ``top-1 correct``, ``ratio``
        (the ratio protocol's score ``S2 / S1``: lower = more confident), ``top-1 matches``
        (reciprocal landmark matches of the top-1 pair), ``wrong top-1 distance`` (on
        frame-aligned data: reference indices from a wrong top-1 to the nearest correct
        reference, small = imprecise localisation, large = perceptual aliasing; NaN for a
        correct top-1 or ground truth from a file), ``disagree`` (the runs' top-1
        correctness differs for this query). Queries where the runs disagree come first, then
        by query index, runs in the given order.

    Raises:
        ValueError: no results, duplicate labels, or runs of different datasets.
    """
    one = hasattr(results, "similarity")
    runs = check_results([results] if one else results, "per_query", unique_labels=True)
    labels = [r.label for r in runs]
    gt = check_same_dataset(runs, runs[0], "per_query")
    queries = np.flatnonzero(gt.any(axis=1))
    table = pd.concat([_one_run(r, gt, queries, contrast) for r in runs], ignore_index=True)
    agree = table.groupby("query")["top-1 correct"].nunique() == 1
    table["disagree"] = ~table["query"].map(agree).astype(bool)
    table["_run"] = table["run"].map({label: i for i, label in enumerate(labels)})
    table = table.sort_values(["disagree", "query", "_run"], ascending=[False, True, True])
    columns = [*PER_QUERY_COLUMNS, *([CONTRAST_COLUMN] if contrast else [])]
    bare = [r.label for r in runs if getattr(r, "descriptors", None) is None]
    if bare:  # never a silent column of NaN
        notice(
            f"per_query: 'top-1 matches' is NaN for {', '.join(bare)}: no descriptors kept (a "
            "peer has none); run_method(..., keep_descriptors=True) counts the matches",
            stacklevel=2,
        )
    return table.drop(columns="_run").reset_index(drop=True)[columns]
