"""Bootstrap confidence intervals over queries for the table metrics, and paired differences.

Resampling unit: the query. Only queries with ground truth are resampled (with replacement, as
many as there are); a resampled query counts as often as it was drawn. Each method then evaluates
the resample exactly as :func:`~vpr_core.evaluation.curves.pr_curve` /
:func:`~vpr_core.evaluation.curves.recall_at_k` would evaluate the matrix with those rows repeated
(its own unranked, all-NaN queries left out). Per-query quantities (score, correctness of the best
match, top-k hit) are computed once; every resample's PR curve is then a weighted cumulative sum
over the queries sorted once by score, so 1,000 resamples of thousands of queries take seconds.

* Interval: 95% percentile interval (``np.percentile``, linear interpolation) of the resampled
  metric; the point value is the metric on all queries (not the resample mean).
* Paired difference ``a - b``: the same resampled queries for both methods. Two-sided p-value:
  ``p = min(1, 2 * (1 + m) / (1 + n))`` where ``m`` counts the resamples whose difference lies on
  the other side of 0 from the observed difference, or on 0 (``delta_b <= 0`` when the observed
  difference is > 0, ``delta_b >= 0`` when < 0); an observed difference of exactly 0 gives
  ``p = 1``. The ``+1`` keeps p above 0: the smallest reportable p is ``2 / (n + 1)``.

Metric keys: ``"auc"`` (area under the PR curve of ``protocol``), ``"r@100p"``, and ``"r@K"`` for each
K in ``ks``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from .curves import (
    PROTOCOLS,
    _check,
    _kept_queries,
    _query_scores,
    _true_rank,
    auc_pr,
    pr_curve,
    recall_at_100_precision,
    recall_at_k,
)

__all__ = ["N_BOOTSTRAP", "bootstrap_columns", "bootstrap_metrics", "difference_verdict", "format_interval",
           "paired_bootstrap"]

#: Bootstrap resamples of every interval and paired difference (the one home of this count).
N_BOOTSTRAP = 1000

#: Resamples evaluated at once (bounds memory: ``chunk x queries`` float64 per array).
_CHUNK = 250


@dataclass
class _PerQuery:
    """One method's per-query quantities on the queries with ground truth (``n`` of them)."""

    keep: np.ndarray  # (n,) bool: has a ranked reference (else left out)
    order: np.ndarray  # (m,) indices into the n queries, kept ones sorted by acceptance order
    correct: np.ndarray  # (m,) float64 best match correct, in `order`
    run_end: np.ndarray  # (m,) bool: last query of a run of equal scores, in `order`
    hits: dict[int, np.ndarray]  # k -> (n,) float64 top-k hit (0 where not kept)


def _check_args(n: int, protocol: str, ks: Sequence[int]) -> tuple[int, ...]:
    if int(n) < 1:
        raise ValueError(f"n (number of resamples) must be >= 1, got {n}")
    if protocol not in ("ratio", "best_match"):
        raise ValueError(f"bootstrap supports protocol 'ratio' or 'best_match' (per-query "
                         f"decisions), got {protocol!r}; valid protocols: {', '.join(PROTOCOLS)}")
    ks = tuple(int(k) for k in ks)
    if any(k < 1 for k in ks):
        raise ValueError(f"ks must be >= 1, got {ks}")
    return ks


def _per_query(s: np.ndarray, gt: np.ndarray, protocol: str, ks: tuple[int, ...]) -> _PerQuery:
    """Per-query quantities of one method; ``s``, ``gt``: rows of the queries with ground truth."""
    keep = ~np.isnan(s).all(axis=1)
    idx = np.flatnonzero(keep)
    score, correct = _query_scores(s[keep], gt[keep], protocol)
    # the same sort as curves._curve_from_scores: accepted in this order, equal scores together
    o = np.argsort(score if protocol == "ratio" else -score, kind="stable")
    sc = score[o]
    run_end = np.r_[sc[1:] != sc[:-1], True] if sc.size else np.zeros(0, dtype=bool)
    rank = _true_rank(s, gt)
    hits = {k: ((rank < k) & keep).astype(np.float64) for k in ks}
    return _PerQuery(keep, idx[o], correct[o].astype(np.float64), run_end, hits)


def _resample_metrics(pq: _PerQuery, w: np.ndarray) -> dict[str, np.ndarray]:
    """Metrics of ``B`` resamples given per-query draw counts ``w`` ``(B, n)``.

    Equal to ``pr_curve`` / ``auc_pr`` / ``recall_at_100_precision`` / ``recall_at_k`` on the
    matrix whose rows are repeated ``w[b]`` times (queries drawn 0 times are absent).

    Returns:
        ``{"auc": (B,), "r@100p": (B,), "r@K": (B,)}``.
    """
    wk = w * pq.keep  # a method's unranked queries are left out
    total = wk.sum(axis=1)  # (B,) kept queries in each resample
    ws = w[:, pq.order]  # (B, m) in acceptance order
    tp = np.cumsum(ws * pq.correct, axis=1)[:, pq.run_end]  # (B, T) at each distinct score
    acc = np.cumsum(ws, axis=1)[:, pq.run_end]
    fn = total[:, None] - acc
    with np.errstate(invalid="ignore", divide="ignore"):
        recall = np.where(tp + fn > 0, tp / np.maximum(tp + fn, 1), 0.0)
        precision = np.where(acc > 0, tp / np.maximum(acc, 1), 1.0)
    b = w.shape[0]
    recall = np.concatenate([np.zeros((b, 1)), recall], axis=1)
    precision = np.concatenate([np.ones((b, 1)), precision], axis=1)
    out = {
        "auc": np.trapezoid(precision, recall, axis=1),
        "r@100p": np.where(precision >= 1.0, recall, 0.0).max(axis=1),
    }
    with np.errstate(invalid="ignore", divide="ignore"):
        for k, h in pq.hits.items():
            out[f"r@{k}"] = (w * h).sum(axis=1) / total
    for v in out.values():
        v[total == 0] = np.nan  # a resample of only unranked queries: no value (nanpercentile)
    return out


def _point(s: np.ndarray, gt: np.ndarray, protocol: str, ks: tuple[int, ...]) -> dict[str, float]:
    """Metrics on all queries, by the functions the tables use (no warning: logged already)."""
    curve = pr_curve(s, gt, protocol, warn=False)
    out = {"auc": auc_pr(curve), "r@100p": recall_at_100_precision(curve)}
    for k in ks:
        out[f"r@{k}"] = recall_at_k(s, gt, k, warn=False)
    return out


def _draws(n_boot: int, n_queries: int, seed: int):
    """Yield ``(B, n_queries)`` draw counts, ``_CHUNK`` resamples at a time (seeded)."""
    rng = np.random.default_rng(seed)
    for start in range(0, n_boot, _CHUNK):
        b = min(_CHUNK, n_boot - start)
        idx = rng.integers(0, n_queries, size=(b, n_queries))
        flat = (np.arange(b)[:, None] * n_queries + idx).ravel()
        yield np.bincount(flat, minlength=b * n_queries).reshape(b, n_queries).astype(np.float64)


def _prepare(similarity, ground_truth, protocol: str, ks, n: int):
    ks = _check_args(n, protocol, ks)
    s, gt = _check(similarity, ground_truth)
    if s.shape[1] < 2 and protocol == "ratio":
        raise ValueError(f"the ratio protocol needs at least 2 references, got {s.shape[1]}")
    _kept_queries(s, gt)  # raises without ground truth; warns once when queries are left out
    return s, gt, ks


def bootstrap_metrics(similarity: np.ndarray, ground_truth: np.ndarray, n: int = N_BOOTSTRAP,
                      seed: int = 0, protocol: str = "ratio", ks: Sequence[int] = (1, 5)
                      ) -> dict[str, tuple[float, float, float]]:
    """95% bootstrap intervals of AUC, R@100P and R@K, resampling queries.

    Args:
        similarity: ``(Nq, Nr)`` float; NaN = not ranked.
        ground_truth: ``(Nq, Nr)`` bool.
        n: number of resamples.
        seed: seed of the resampling (same seed, same intervals).
        protocol: ``"ratio"`` (paper) or ``"best_match"``.
        ks: the K of R@K.

    Returns:
        ``{"auc", "r@100p", "r@K"...: (value on all queries, low, high)}``.

    Raises:
        ValueError: no query with ground truth, bad ``n`` / ``protocol`` / ``ks`` / shapes.
    """
    s, gt, ks = _prepare(similarity, ground_truth, protocol, ks, n)
    has_gt = gt.any(axis=1)
    s, gt = s[has_gt], gt[has_gt]
    point = _point(s, gt, protocol, ks)
    pq = _per_query(s, gt, protocol, ks)
    draws = [_resample_metrics(pq, w) for w in _draws(n, s.shape[0], seed)]
    out = {}
    for key, value in point.items():
        vals = np.concatenate([d[key] for d in draws])
        lo, hi = np.nanpercentile(vals, [2.5, 97.5])
        out[key] = (float(value), float(lo), float(hi))
    return out


def _p_value(delta: float, deltas: np.ndarray) -> float:
    """Two-sided bootstrap p-value of a difference (definition: module docstring)."""
    if delta == 0:
        return 1.0
    other = int((deltas <= 0).sum()) if delta > 0 else int((deltas >= 0).sum())
    return float(min(1.0, 2.0 * (1 + other) / (1 + deltas.size)))


def paired_bootstrap(sim_a: np.ndarray, sim_b: np.ndarray, ground_truth: np.ndarray,
                     n: int = N_BOOTSTRAP, seed: int = 0, protocol: str = "ratio",
                     ks: Sequence[int] = (1, 5)) -> dict[str, tuple[float, float, float, float]]:
    """Paired bootstrap of the difference ``a - b`` of two methods on the same queries.

    Args:
        sim_a: ``(Nq, Nr)`` similarities of method a; NaN = not ranked.
        sim_b: ``(Nq, Nr)`` similarities of method b.
        ground_truth: ``(Nq, Nr)`` bool.
        n: number of resamples (the same query resample for both methods).
        seed: seed of the resampling.
        protocol: ``"ratio"`` (paper) or ``"best_match"``.
        ks: the K of R@K.

    Returns:
        ``{"auc", "r@100p", "r@K"...: (delta on all queries, low, high, p)}``; identical inputs
        give ``(0, 0, 0, 1)``.
    """
    a, gt, ks = _prepare(sim_a, ground_truth, protocol, ks, n)
    b, _, _ = _prepare(sim_b, ground_truth, protocol, ks, n)
    if a.shape != b.shape:
        raise ValueError(f"sim_a and sim_b differ in shape: {a.shape} vs {b.shape}")
    has_gt = gt.any(axis=1)
    a, b, gt = a[has_gt], b[has_gt], gt[has_gt]
    pa, pb = _point(a, gt, protocol, ks), _point(b, gt, protocol, ks)
    qa, qb = _per_query(a, gt, protocol, ks), _per_query(b, gt, protocol, ks)
    deltas: dict[str, list[np.ndarray]] = {key: [] for key in pa}
    for w in _draws(n, a.shape[0], seed):
        ma, mb = _resample_metrics(qa, w), _resample_metrics(qb, w)
        for key, parts in deltas.items():
            parts.append(ma[key] - mb[key])
    out = {}
    for key in pa:
        d = np.concatenate(deltas[key])
        delta = pa[key] - pb[key]
        lo, hi = np.nanpercentile(d, [2.5, 97.5])
        out[key] = (float(delta), float(lo), float(hi), _p_value(delta, d[~np.isnan(d)]))
    return out


def difference_verdict(low: float, high: float) -> str:
    """``"finding"`` when the 95% interval of a difference excludes 0, else ``"inconclusive"``."""
    return "finding" if low > 0 or high < 0 else "inconclusive"


def format_interval(value: float, low: float, high: float, digits: int = 3) -> str:
    """``"0.812 [0.751, 0.866]"``: a value with its interval."""
    return f"{value:.{digits}f} [{low:.{digits}f}, {high:.{digits}f}]"


def _label(key: str) -> str:
    return {"auc": "AUC", "r@100p": "R@100P"}.get(key, key.upper())


def bootstrap_columns(result: Mapping[str, Sequence[float]], prefix: str = "") -> dict[str, float]:
    """Table columns from a :func:`bootstrap_metrics` or :func:`paired_bootstrap` result.

    Args:
        result: ``{key: (value, low, high)}`` or ``{key: (delta, low, high, p)}``.
        prefix: put before every column name (e.g. ``"d"`` for differences).

    Returns:
        Ordered ``{"AUC": v, "AUC lo": l, "AUC hi": h, "R@100P": ..., "R@1": ...}``, plus
        ``"<name> p"`` for paired results.
    """
    cols: dict[str, float] = {}
    for key, vals in result.items():
        if len(vals) not in (3, 4):
            raise ValueError(f"result[{key!r}] must be (value, low, high) or (delta, low, high, p), "
                             f"got {len(vals)} numbers")
        name = prefix + _label(key)
        cols[name], cols[f"{name} lo"], cols[f"{name} hi"] = (float(v) for v in vals[:3])
        if len(vals) == 4:
            cols[f"{name} p"] = float(vals[3])
    return cols
