"""(Not in the paper.) What a step (a weighting, a normalisation; docs/DEFINITIONS.md) changed for
chosen queries: which references moved in the ranking and why (:func:`step_changes`), and which
landmarks carried a top-1 a weighting changed (:func:`carried_landmarks`); the figures read them."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pandas as pd

from .. import checks
from ..matching.normalise import NORMALISATIONS, zscore
from ..matching.pairwise import cosine_similarity
from ..matching.similarity import weighted_matches
from ..matching.weighting import WEIGHTINGS
from ..methods import step_between
from .ranks import best_two, ranked

__all__ = [
    "CARRIED_COLUMNS",
    "CHANGE_COLUMNS",
    "SILENT_WEIGHT",
    "carried_landmarks",
    "changed_queries",
    "step_changes",
]

#: A database weight at or below this counts as silenced: the weighting took the term out.
SILENT_WEIGHT = 1e-6

#: The columns of :func:`carried_landmarks`, in order.
CARRIED_COLUMNS = (
    "query",
    "case",
    "role",
    "reference",
    "reference correct",
    "rank",
    "query landmark",
    "reference landmark",
    "cosine",
    "weight",
    "plain term",
    "weighted term",
    "also matches",
    "its cosine",
    "also matches correct",
)

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
    if "whiten" in step:
        raise ValueError(
            f"step_changes: {stepped.label!r} adds the whitening of the descriptors, which "
            "step_changes does not explain: use vpr_core.whitening_changes(plain, whitened) "
            "(or vpr_study.viz.plot_whitening)"
        )
    w, z = step.get("weighting"), step.get("normalise")
    mp = plain.config.matching
    if w is not None and (mp.weighting is not None or mp.normalise is not None):
        raise ValueError("for a weighting step, `plain` must be the paper's Eq. (1)")
    return w, z


def _weight_why(stepped: Any, weighting: str, pairs: list[tuple[int, int]]) -> list[str]:
    """Per pair: its matches and their mean weights (a weighting with a reference side, as
    ``two_sided``: ``w_q`` and ``w_r``)."""
    d, b = stepped.descriptors, stepped.boxes
    if d is None:
        raise ValueError(
            f"{stepped.label!r} kept no descriptors: run it with keep_descriptors=True"
        )
    sample = None if stepped.shortlist else np.arange(len(d["reference"]))
    m = dataclasses.replace(stepped.config.matching, normalise=None, whiten=None)  # kept: whitened
    args = (d["query"], b["query"], d["reference"], b["reference"], pairs)
    full = weighted_matches(*args, m, sample)
    two = WEIGHTINGS[weighting].reference_side
    wq = (
        weighted_matches(*args, dataclasses.replace(m, weighting="contrast"), sample)
        if two
        else full
    )
    out = []
    for f, c in zip(full, wq, strict=True):
        n = len(f.matches)
        if n == 0:
            out.append("no reciprocal match")
            continue
        assert f.weights is not None and c.weights is not None  # weighted_matches gives them
        if two:
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


def _normalise_why(how: str, a: np.ndarray, b: np.ndarray, q: int, refs: list) -> list[str]:
    """Per reference of query ``q``: what a normalisation read (``query_batch``: its row and
    column z-scores; one that needs the database: ``rho_r``, recovered as ``S - log S'``; any
    other: the score before and after)."""
    entry = NORMALISATIONS[how]
    if entry.needs_query_batch:
        zr, zc = zscore(a, 1), zscore(a, 0)
        return [
            f"row z {zr[q, r]:+.2f}, column z {zc[q, r]:+.2f} (its mean over the query "
            f"batch {np.nanmean(a[:, r]):.3f})"
            for r in refs
        ]
    if entry.needs_database:
        rho = np.nanmedian(a - np.log(b), axis=0)
        return [f"rho {rho[r]:.3f} (mean similarity to its nearest references)" for r in refs]
    return [f"normalised by {how}: {a[q, r]:.3f} -> {b[q, r]:.3f}" for r in refs]


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
        else:
            why = _normalise_why(str(normalise), a, b, q, refs)
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


# ---- which landmarks carried a top-1 a weighting changed (notebook 07) ------------------------
def _top1_ranked(run: Any) -> np.ndarray:
    """``(Nq,)`` each query's top-1 reference (ties: lowest index; -1: nothing ranked), as the
    metrics pick it."""
    s = np.asarray(run.similarity, dtype=np.float64)
    out = np.full(s.shape[0], -1, dtype=np.int64)
    rows = ranked(s)
    if rows.any():
        out[rows] = best_two(s[rows])[0]
    return out


def _carried_queries(plain: Any, weighted: Any, gt: np.ndarray, n: int) -> list[tuple[int, str]]:
    """Up to ``n`` ``(query, case)`` whose top-1 the weighting changed: the first query it
    fixed, then the first it broke (if any), then the other fixed, broken and changed ones, in
    query order."""
    tp, tw = _top1_ranked(plain), _top1_ranked(weighted)
    rows = np.arange(len(tp))
    has = gt.any(axis=1) & (tp >= 0) & (tw >= 0) & (tp != tw)
    ok_p = gt[rows, np.maximum(tp, 0)]
    ok_w = gt[rows, np.maximum(tw, 0)]
    fixed = [int(q) for q in np.flatnonzero(has & ~ok_p & ok_w)]
    broken = [int(q) for q in np.flatnonzero(has & ok_p & ~ok_w)]
    other = [int(q) for q in np.flatnonzero(has & ~ok_p & ~ok_w)]
    order = [*fixed[:1], *broken[:1], *fixed[1:], *broken[1:], *other]
    case = {q: "fixed" for q in fixed} | {q: "broken" for q in broken}
    case |= {q: "changed, both wrong" for q in other}
    return [(q, case[q]) for q in order[:n]]


def _also_matches(run: Any, q: int, landmarks: np.ndarray, shown: int) -> tuple:
    """For query ``q``'s ``landmarks``: the reference other than ``shown`` where each has its
    best cosine ``b_i(r)`` (``(k,)`` indices) and that cosine (``(k,)``)."""
    refs = run.descriptors["reference"]
    counts = np.array([len(d) for d in refs])
    k = len(landmarks)
    if not k or counts.sum() == 0:
        return np.full(k, -1), np.full(k, np.nan)
    cos = cosine_similarity(
        np.asarray(run.descriptors["query"][q])[landmarks],
        np.concatenate([np.asarray(d).reshape(len(d), -1) for d in refs if len(d)]),
    )
    best = np.full((k, len(refs)), -np.inf)
    starts = np.concatenate([[0], np.cumsum(counts[counts > 0])[:-1]])
    best[:, counts > 0] = np.maximum.reduceat(cos, starts, axis=1)
    best[:, shown] = -np.inf
    other = np.argmax(best, axis=1)
    value = best[np.arange(k), other]
    return np.where(np.isfinite(value), other, -1), np.where(np.isfinite(value), value, np.nan)


def _run_matches(run: Any, pairs: list[tuple[int, int]]) -> list:
    """Each pair's matches with the weights the weighted ``run`` (it kept its descriptors,
    whitened where it was: ``whiten`` is then already applied) used."""
    d, b = run.descriptors, run.boxes
    sample = None if run.shortlist else np.arange(len(d["reference"]))
    args = (d["query"], b["query"], d["reference"], b["reference"], pairs)
    return weighted_matches(*args, dataclasses.replace(run.config.matching, whiten=None), sample)


def _carried_rows(
    run: Any, gt: np.ndarray, q: int, case: str, pairs: list, ms: list, k: int
) -> list[dict]:
    """The table rows of one query: the ``k`` largest weighted terms of the weighted top-1
    pair (``carried``), the ``k`` largest plain terms with weight about 0 of the plain top-1
    pair (``silenced``)."""
    rows = []
    for role, (_, r), m in zip(("carried", "silenced"), pairs, ms, strict=True):
        plain_term = m.raw_scores * m.spatial_weights
        if role == "carried":
            keep = np.flatnonzero(m.scores > 0)
            keep = keep[np.argsort(-m.scores[keep], kind="stable")][:k]
        else:
            keep = np.flatnonzero(m.weights <= SILENT_WEIGHT)
            keep = keep[np.argsort(-plain_term[keep], kind="stable")][:k]
        also, also_cos = _also_matches(run, q, m.matches[keep, 0], r)
        for rank, (idx, o, oc) in enumerate(zip(keep, also, also_cos, strict=True), start=1):
            i, j = (int(v) for v in m.matches[idx])
            rows.append(
                {
                    "query": q,
                    "case": case,
                    "role": role,
                    "reference": r,
                    "reference correct": bool(gt[q, r]),
                    "rank": rank,
                    "query landmark": i,
                    "reference landmark": j,
                    "cosine": 1.0 - float(m.distances[idx]),
                    "weight": float(m.weights[idx]),
                    "plain term": float(plain_term[idx]),
                    "weighted term": float(m.scores[idx]),
                    "also matches": int(o),
                    "its cosine": float(oc),
                    "also matches correct": bool(o >= 0 and gt[q, o]),
                }
            )
    return rows


def carried_landmarks(plain: Any, weighted: Any, n_queries: int = 2, k: int = 5) -> pd.DataFrame:
    """(Not in the paper.) Why a database weighting changed a query's top-1, landmark by landmark.

    For up to ``n_queries`` queries whose top-1 the weighting changed (the first it fixed, then
    the first it broke, if any, then others, in query order): the ``k`` reciprocal matches with
    the largest weighted Eq. (1) terms in the weighted run's top-1 pair (role ``carried``), then
    the ``k`` with the largest plain terms in the plain run's top-1 pair whose weight is at most
    :data:`SILENT_WEIGHT` (``silenced``); each with its cosine, weight and the other reference
    where its query landmark matches best (``also matches``). The weights are those the
    weighted run used (:func:`~vpr_core.matching.weighted_matches`).

    Args:
        plain: a method's run without weighting; weighted: the same run with ``weighting=``
            and ``keep_descriptors=True``.
        n_queries: queries shown; k: landmarks per role (1 to 10).

    Returns:
        One row per landmark (:data:`CARRIED_COLUMNS`); ``attrs["queries"]`` lists each chosen
        ``(query, case, weighted top-1, plain top-1)`` (a role may have no row) and
        ``attrs["changed"]`` the queries whose top-1 the weighting changed.
    """
    n_queries = checks.check_int(n_queries, "n_queries", 1)
    k = int(
        checks.check_range(checks.check_int(k, "k", 1), "k (landmarks a figure row fits)", 1, 10)
    )
    _check_carried(plain, weighted)
    gt = np.asarray(plain.ground_truth, dtype=bool)
    chosen = _carried_queries(plain, weighted, gt, n_queries)
    tp, tw = _top1_ranked(plain), _top1_ranked(weighted)
    rows, queries = [], []
    for q, case in chosen:
        pairs = [(q, int(tw[q])), (q, int(tp[q]))]
        rows += _carried_rows(weighted, gt, q, case, pairs, _run_matches(weighted, pairs), k)
        queries.append((q, case, int(tw[q]), int(tp[q])))
    table = pd.DataFrame(rows, columns=list(CARRIED_COLUMNS))
    table.attrs["queries"] = queries
    table.attrs["changed"] = int(
        np.count_nonzero(gt.any(axis=1) & (tp != tw) & (tp >= 0) & (tw >= 0))
    )
    return table


def _check_carried(plain: Any, weighted: Any) -> None:
    """Refuse runs :func:`carried_landmarks` cannot explain: ``weighted`` without a weighting
    or descriptors, ``plain`` with a weighting, runs that differ in more than the weighting."""
    matching = getattr(getattr(weighted, "config", None), "matching", None)
    if matching is None or not matching.weighting:
        raise ValueError(
            f"{getattr(weighted, 'label', weighted)!r} has no weighting: pass the run of "
            "run_method(..., weighting='contrast', keep_descriptors=True) as `weighted`"
        )
    m_p = getattr(getattr(plain, "config", None), "matching", None)
    if m_p is None or m_p.weighting:
        raise ValueError(
            f"`plain` must be the paper's Eq. (1) (no weighting), got "
            f"{getattr(plain, 'label', plain)!r}: run the same method without weighting"
        )
    checks.check_descriptors_kept(weighted, "carried_landmarks")
    step = step_between(plain, weighted, "carried_landmarks", "the weighting")
    if set(step) != {"weighting"}:  # a normalisation too: not what the figure explains
        raise ValueError(
            f"carried_landmarks: {plain.label!r} and {weighted.label!r} differ in more than "
            "the weighting (normalise): pass one method run without and with weighting= alone"
        )
