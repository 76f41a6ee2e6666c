"""(Not in the paper.) What a step (a weighting, a normalisation; docs/DEFINITIONS.md) changed
for chosen queries: which references rose or fell in the ranking, and the numbers that moved
them (:func:`step_changes`)."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pandas as pd

from vpr_core import checks, step_between
from vpr_core.matching import weighted_matches, zscore

__all__ = ["CHANGE_COLUMNS", "changed_queries", "step_changes"]

#: The columns of :func:`step_changes`.
CHANGE_COLUMNS = (
    "query",
    "case",
    "reference",
    "correct",
    "rank before",
    "rank after",
    "score before",
    "score after",
    "why",
)


def _ranks(row: np.ndarray) -> np.ndarray:
    """1-based rank of each reference in a row (best first, ties by lowest index, NaN last)."""
    order = np.argsort(-np.where(np.isnan(row), -np.inf, row), kind="stable")
    ranks = np.empty(row.shape[0], dtype=np.int64)
    ranks[order] = np.arange(1, row.shape[0] + 1)
    return ranks


def _top1(sim: np.ndarray) -> np.ndarray:
    return np.argmax(np.where(np.isnan(sim), -np.inf, sim), axis=1)


def changed_queries(plain: Any, stepped: Any, n: int = 2) -> list[tuple[int, str]]:
    """Up to ``n`` ``(query, case)``: the first query whose top-1 the step made correct
    (``"fixed"``), the first it made wrong (``"broken"``), then other queries whose top-1 it
    changed, in query order; else the queries whose first correct reference moved most."""
    gt = np.asarray(plain.ground_truth, dtype=bool)
    a, b = np.asarray(plain.similarity), np.asarray(stepped.similarity)
    ta, tb = _top1(a), _top1(b)
    qs = np.flatnonzero(gt.any(1))
    ok_a, ok_b = gt[qs, ta[qs]], gt[qs, tb[qs]]
    fixed = [(int(q), "fixed") for q in qs[~ok_a & ok_b]]
    broken = [(int(q), "broken") for q in qs[ok_a & ~ok_b]]
    moved = [(int(q), "top-1 changed") for q in qs[(ta[qs] != tb[qs]) & (ok_a == ok_b)]]
    out = fixed[:1] + broken[:1] + fixed[1:] + broken[1:] + moved
    if not out:
        shift = [abs(int(_ranks(a[q])[gt[q]].min()) - int(_ranks(b[q])[gt[q]].min())) for q in qs]
        out = [(int(qs[i]), "rank of its place moved") for i in np.argsort(shift)[::-1]]
    return out[:n]


def _step_of(plain: Any, stepped: Any) -> tuple[str | None, str | None]:
    """``(weighting, normalise)`` that ``stepped`` adds to ``plain``; refuses other pairs
    (:func:`vpr_core.methods.step_between`: the same dataset, encoder, shortlist, options)."""
    step = step_between(plain, stepped, "step_changes")
    w, z = step.get("weighting"), step.get("normalise")
    mp = plain.config.matching
    if w is not None and (mp.weighting is not None or mp.normalise is not None):
        raise ValueError("for a weighting step, `plain` must be the paper's Eq. (1)")
    return w, z


def _weight_why(stepped: Any, weighting: str, pairs: list[tuple[int, int]]) -> list[str]:
    """Per pair: its matches and their mean weights (``two_sided``: ``w_q`` and ``w_r``)."""
    d, b = stepped.descriptors, stepped.boxes
    if d is None:
        raise ValueError(
            f"{stepped.label!r} kept no descriptors: run it with keep_descriptors=True"
        )
    sample = None if stepped.shortlist else np.arange(len(d["reference"]))
    m = dataclasses.replace(stepped.config.matching, normalise=None)
    args = (d["query"], b["query"], d["reference"], b["reference"], pairs)
    full = weighted_matches(*args, m, sample)
    wq = weighted_matches(*args, dataclasses.replace(m, weighting="contrast"), sample)
    out = []
    for f, c in zip(full, wq, strict=True):
        n = len(f.matches)
        if n == 0:
            out.append("no reciprocal match")
            continue
        assert f.weights is not None and c.weights is not None  # weighted_matches gives them
        if weighting == "two_sided":
            w_r = f.weights / (1.0 + c.weights) - 1.0
            out.append(
                f"{n} matches, plain sum {f.raw_scores.sum():.2f} -> {f.scores.sum():.2f}; "
                f"mean w_q {c.weights.mean():.2f} (query landmark rarer than usual), mean w_r "
                f"{w_r.mean():.2f} (reference landmark rarer than in other places)"
            )
        else:
            out.append(
                f"{n} matches, plain sum {f.raw_scores.sum():.2f} -> {f.scores.sum():.2f}; "
                f"mean weight {f.weights.mean():.2f}"
            )
    return out


def step_changes(plain: Any, stepped: Any, n_queries: int = 2, top: int = 5) -> pd.DataFrame:
    """(Not in the paper.) For up to ``n_queries`` queries (:func:`changed_queries`), the
    references in the top ``top`` before or after the step, with their ranks and scores before
    and after and why they moved.

    ``why``: a weighting (``stepped`` run with ``keep_descriptors=True``): the pair's matches
    and mean weights; ``query_batch``: the reference's row and column z-scores (a reference
    that scores high for every query of the batch falls); ``database``: ``rho_r``, its mean
    similarity to its nearest references (recovered as ``S - log S'``).

    Args:
        plain: a method's run; stepped: the same run with one more step.
        n_queries: queries shown; top: references per query from each ranking.

    Returns:
        A DataFrame with :data:`CHANGE_COLUMNS`, ``rank after`` ascending within a query.
    """
    n_queries, top = checks.check_int(n_queries, "n_queries", 1), checks.check_int(top, "top", 1)
    weighting, normalise = _step_of(plain, stepped)
    gt = np.asarray(plain.ground_truth, dtype=bool)
    a, b = np.asarray(plain.similarity), np.asarray(stepped.similarity)
    rows = []
    for q, case in changed_queries(plain, stepped, n_queries):
        ra, rb = _ranks(a[q]), _ranks(b[q])
        refs = sorted(set(np.flatnonzero(ra <= top)) | set(np.flatnonzero(rb <= top)))
        refs = sorted(refs, key=lambda r: rb[r])
        if weighting is not None:
            why = _weight_why(stepped, weighting, [(q, int(r)) for r in refs])
        elif normalise == "query_batch":
            zr, zc = zscore(a, 1), zscore(a, 0)
            why = [
                f"row z {zr[q, r]:+.2f}, column z {zc[q, r]:+.2f} (its mean over the query "
                f"batch {np.nanmean(a[:, r]):.3f})"
                for r in refs
            ]
        else:
            rho = np.nanmedian(a - np.log(b), axis=0)
            why = [f"rho {rho[r]:.3f} (mean similarity to its nearest references)" for r in refs]
        for r, text in zip(refs, why, strict=True):
            rows.append(
                {
                    "query": q,
                    "case": case,
                    "reference": int(r),
                    "correct": bool(gt[q, r]),
                    "rank before": int(ra[r]),
                    "rank after": int(rb[r]),
                    "score before": float(a[q, r]),
                    "score after": float(b[q, r]),
                    "why": text,
                }
            )
    return pd.DataFrame(rows, columns=list(CHANGE_COLUMNS))
