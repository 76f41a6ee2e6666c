"""Bootstrap intervals over queries for the table metrics, paired differences with p-values and
the queries a verdict needs (definitions: docs/DEFINITIONS.md, "Uncertainty"). Each resample is
a weighted cumulative sum over queries sorted once by score: 1,000 resamples take seconds."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..checks import check_int
from .curves import Scored, evaluate
from .ranks import query_scores, ranked, true_rank
from .spec import BOOTSTRAP_PROTOCOLS, N_BOOTSTRAP, Evaluation

__all__ = [
    "BOOTSTRAP_PROTOCOLS",
    "IDENTICAL",
    "N_BOOTSTRAP",
    "ON_PAR_MARGIN",
    "VERDICT_WORDS",
    "Difference",
    "MIN_QUERIES",
    "bootstrap_columns",
    "bootstrap_metrics",
    "claim_verdict",
    "difference_verdict",
    "format_interval",
    "metrics_and_intervals",
    "needs_text",
    "paired_bootstrap",
    "VERDICTS",
]

#: The verdict of a run against a baseline it is identical to (the same similarity matrix, or
#: the same curve and metrics): no number of queries could tell them apart. ``compare`` and
#: the findings table say it in these words.
IDENTICAL = "not testable (identical results)"

#: ``queries_needed`` beyond this: "not decidable on any realistic set" (:func:`needs_text`).
REALISTIC_QUERIES = 100_000
#: Below this many queries a paired difference is "too few queries", never higher or lower
#: (docs/DEFINITIONS.md, "Verdicts": an exact sign test reaches p < 0.05 from 6 queries on).
MIN_QUERIES = 6


class Difference(tuple):
    """A paired difference: unpacks as ``(delta, low, high, p)`` like a 4-tuple, and carries
    ``.se`` (standard error of the difference) and ``.queries_needed`` (float; inf when
    ``delta = 0``; NaN without resamples)."""

    se: float
    queries_needed: float

    def __new__(
        cls,
        delta: float,
        low: float,
        high: float,
        p: float,
        se: float = np.nan,
        queries_needed: float = np.nan,
    ):
        self = super().__new__(cls, (float(delta), float(low), float(high), float(p)))
        self.se, self.queries_needed = float(se), float(queries_needed)
        return self

    def __getnewargs__(self):
        return (*self, self.se, self.queries_needed)

    def __repr__(self) -> str:
        return (
            "Difference(delta={:.4g}, low={:.4g}, high={:.4g}, p={:.4g}, ".format(*self)
            + f"se={self.se:.4g}, queries_needed={self.queries_needed:.4g})"
        )


#: Resamples evaluated at once (bounds memory: ``chunk x queries`` float64 per array).
_CHUNK = 250


@dataclass
class _PerQuery:
    """One method's per-query quantities on the queries with ground truth (``n`` of them)."""

    protocol: str
    counted: np.ndarray  # (n,) bool: counted by the curve (vpr_bench: ranked; else all)
    rk: np.ndarray  # (n,) bool: counted by R@K (with ground truth)
    order: np.ndarray  # (m,) indices into the n queries, kept ones sorted by acceptance order
    correct: np.ndarray  # (m,) float64 best match correct, in `order`
    run_end: np.ndarray  # (m,) bool: last query of a run of equal scores, in `order`
    hits: dict[int, np.ndarray]  # k -> (n,) float64 top-k hit (0 where not kept)


def _per_query(x: Scored, ks: tuple[int, ...]) -> _PerQuery:
    """Per-query quantities of one method on its resampled rows (:func:`_prepare`)."""
    s, gt, protocol = x.s, x.gt, x.protocol
    any_ranked = ranked(s)  # an unranked query is never accepted (not retrieved)
    idx = np.flatnonzero(any_ranked)
    score, correct = query_scores(s[any_ranked], gt[any_ranked], protocol == "ratio")
    # the same sort as curves._curve_from_scores: accepted in this order, equal scores together
    o = np.argsort(score if protocol == "ratio" else -score, kind="stable")
    sc = score[o]
    run_end = np.r_[sc[1:] != sc[:-1], True] if sc.size else np.zeros(0, dtype=bool)
    rank = true_rank(s, gt)
    hits = {k: (rank < k).astype(np.float64) for k in ks}  # no hit where nothing is ranked
    counted = any_ranked if protocol == "vpr_bench" else np.ones_like(any_ranked)
    has_gt = np.asarray(gt.any(axis=1))
    return _PerQuery(
        protocol, counted, has_gt, idx[o], correct[o].astype(np.float64), run_end, hits
    )


def _resample_metrics(pq: _PerQuery, w: np.ndarray) -> dict[str, np.ndarray]:
    """Metrics of ``B`` resamples given per-query draw counts ``w`` ``(B, n)``.

    Equal to ``pr_curve`` / ``auc_pr`` / ``recall_at_100_precision`` / ``recall_at_k`` on the
    matrix whose rows are repeated ``w[b]`` times (queries drawn 0 times are absent).

    Returns:
        ``{"auc": (B,), "r@100p": (B,), "r@K": (B,)}``.
    """
    total = (w * pq.counted).sum(axis=1)  # (B,) counted queries in each resample
    ws = w[:, pq.order]  # (B, m) in acceptance order
    tp = np.cumsum(ws * pq.correct, axis=1)[:, pq.run_end]  # (B, T) at each distinct score
    acc = np.cumsum(ws, axis=1)[:, pq.run_end]
    if pq.protocol == "ratio":
        fn = total[:, None] - acc
    else:  # best_match: recall = TP / kept queries; vpr_bench: TP / correct top-1s (tp[:, -1])
        fn = (total[:, None] if pq.protocol == "best_match" else tp[:, -1:]) - tp
    with np.errstate(invalid="ignore", divide="ignore"):
        recall = np.where(tp + fn > 0, tp / np.maximum(tp + fn, 1), 0.0)
        precision = np.where(acc > 0, tp / np.maximum(acc, 1), 1.0)
    b = w.shape[0]
    recall = np.concatenate([np.zeros((b, 1)), recall], axis=1)
    precision = np.concatenate([np.ones((b, 1)), precision], axis=1)
    # vpr_bench's truncation at full recall drops only zero-width trapezoids: same AUC, R@100P
    out = {
        "auc": np.trapezoid(precision, recall, axis=1),
        "r@100p": np.where(precision >= 1.0, recall, 0.0).max(axis=1),
    }
    total_k = (w * pq.rk).sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        for k, h in pq.hits.items():
            out[f"r@{k}"] = (w * h).sum(axis=1) / total_k
    for v in out.values():
        v[total == 0] = np.nan  # vpr_bench: a resample of only unranked queries has no curve
    return out


def _draws(n_boot: int, n_queries: int, seed: int):
    """Yield ``(B, n_queries)`` draw counts, ``_CHUNK`` resamples at a time (seeded)."""
    rng = np.random.default_rng(seed)
    for start in range(0, n_boot, _CHUNK):
        b = min(_CHUNK, n_boot - start)
        idx = rng.integers(0, n_queries, size=(b, n_queries))
        flat = (np.arange(b)[:, None] * n_queries + idx).ravel()
        yield np.bincount(flat, minlength=b * n_queries).reshape(b, n_queries).astype(np.float64)


def _prepare(similarity, ground_truth, evaluation: Evaluation, ignore=None) -> Scored:
    """The checked inputs on the resampled queries: ``vpr_bench`` every query, else those with
    ground truth (raises without ground truth; warns once when queries are left out)."""
    s, gt, keep, _ = Scored.parse(similarity, ground_truth, evaluation, ignore)
    rows = np.ones(s.shape[0], dtype=bool) if evaluation.protocol == "vpr_bench" else gt.any(1)
    return Scored(s[rows], gt[rows], keep[rows], evaluation)


def _arguments(protocol: str, n: int, ks: Sequence[int]) -> tuple[Evaluation, tuple[int, ...]]:
    """The checked :class:`Evaluation` and ``ks`` of a bootstrap call. Its protocol must decide
    per query even without resamples (``n = 0``, which an Evaluation accepts for
    ``multi_match``): the resampled rows are the queries with ground truth."""
    evaluation = Evaluation(protocol, n_bootstrap=n)
    if not evaluation.n_bootstrap:
        evaluation.require_per_query("use ")
    return evaluation, tuple(check_int(k, "k", 1) for k in ks)


def _interval(vals: list[np.ndarray]) -> tuple[float, float]:
    """95% percentile interval of the resampled values (NaN, NaN without resamples)."""
    if not vals:
        return np.nan, np.nan
    lo, hi = np.nanpercentile(np.concatenate(vals), [2.5, 97.5])
    return float(lo), float(hi)


def metrics_and_intervals(
    similarity: np.ndarray, ground_truth: np.ndarray, evaluation: Evaluation
) -> tuple[dict[str, float], dict[str, tuple[float, float, float]]]:
    """A matrix's :func:`~vpr_core.evaluation.curves.evaluate` metrics and, when
    ``evaluation.n_bootstrap`` > 0, their :func:`bootstrap_metrics` intervals (else ``{}``):
    the two fields of a result."""
    metrics = evaluate(similarity, ground_truth, evaluation)
    n, protocol = evaluation.n_bootstrap, evaluation.protocol
    return metrics, bootstrap_metrics(similarity, ground_truth, n=n, protocol=protocol) if n else {}


def bootstrap_metrics(
    similarity: np.ndarray,
    ground_truth: np.ndarray,
    n: int = N_BOOTSTRAP,
    seed: int = 0,
    protocol: str = "ratio",
    ks: Sequence[int] = (1, 5),
    ignore: np.ndarray | None = None,
) -> dict[str, tuple[float, float, float]]:
    """95% bootstrap intervals of AUC, R@100P and R@K, resampling queries.

    Args:
        similarity: ``(Nq, Nr)`` float; NaN = not ranked.
        ground_truth: ``(Nq, Nr)`` bool.
        n: number of resamples (0: no interval, low = high = NaN).
        seed: seed of the resampling (same seed, same intervals).
        protocol: ``"ratio"`` (paper), ``"best_match"`` or ``"vpr_bench"``.
        ks: the K of R@K.
        ignore: optional ``(Nq, Nr)`` bool soft ground truth (neither right nor wrong).

    Returns:
        ``{"auc", "r@100p", "r@K"...: (value on all queries, low, high)}`` (the keys of
        :func:`~vpr_core.evaluation.curves.evaluate`).

    Raises:
        ValueError: no query with ground truth, a protocol without intervals, bad ``ks`` or
            shapes.
    """
    evaluation, kt = _arguments(protocol, n, ks)
    x = _prepare(similarity, ground_truth, evaluation, ignore)
    point = x.metrics(kt, warn=False)
    pq = _per_query(x, kt)
    draws = [_resample_metrics(pq, w) for w in _draws(evaluation.n_bootstrap, len(x.s), seed)]
    return {
        key: (float(value), *_interval([d[key] for d in draws])) for key, value in point.items()
    }


def _p_value(delta: float, deltas: np.ndarray) -> float:
    """Two-sided bootstrap p-value of a difference (definition: module docstring)."""
    if delta == 0:
        return 1.0
    other = int((deltas <= 0).sum()) if delta > 0 else int((deltas >= 0).sum())
    return float(min(1.0, 2.0 * (1 + other) / (1 + deltas.size)))


def _queries_needed(delta: float, se: float, n_queries: int) -> float:
    """Queries at which ``delta +- 1.96 se`` would exclude 0 (formula: module docstring)."""
    if not np.isfinite(se):
        return np.nan
    if delta == 0:
        return np.inf
    return float(max(1, math.ceil(n_queries * (1.96 * se / abs(delta)) ** 2)))


def paired_bootstrap(
    sim_a: np.ndarray,
    sim_b: np.ndarray,
    ground_truth: np.ndarray,
    n: int = N_BOOTSTRAP,
    seed: int = 0,
    protocol: str = "ratio",
    ks: Sequence[int] = (1, 5),
    ignore: np.ndarray | None = None,
) -> dict[str, Difference]:
    """Paired bootstrap of the difference ``a - b`` of two methods on the same queries.

    Args:
        sim_a: ``(Nq, Nr)`` similarities of method a; NaN = not ranked.
        sim_b: ``(Nq, Nr)`` similarities of method b.
        ground_truth: ``(Nq, Nr)`` bool.
        n: number of resamples (the same query resample for both methods; 0: no interval,
            low = high = p = NaN).
        seed: seed of the resampling.
        protocol: ``"ratio"`` (paper), ``"best_match"`` or ``"vpr_bench"``.
        ks: the K of R@K.
        ignore: optional ``(Nq, Nr)`` bool soft ground truth (neither right nor wrong).

    Returns:
        ``{"auc", "r@100p", "r@K"...: Difference(delta on all queries, low, high, p)}``: each
        unpacks as a 4-tuple and has ``.se`` and ``.queries_needed`` (module docstring);
        identical inputs give ``(0, 0, 0, 1)``.
    """
    evaluation, kt = _arguments(protocol, n, ks)
    a = _prepare(sim_a, ground_truth, evaluation, ignore)
    b = _prepare(sim_b, ground_truth, evaluation, ignore)  # same shape: both checked against it
    pa, pb = a.metrics(kt, warn=False), b.metrics(kt, warn=False)
    qa, qb = _per_query(a, kt), _per_query(b, kt)
    deltas: dict[str, list[np.ndarray]] = {key: [] for key in pa}
    for w in _draws(evaluation.n_bootstrap, len(a.s), seed):
        ma, mb = _resample_metrics(qa, w), _resample_metrics(qb, w)
        for key, parts in deltas.items():
            parts.append(ma[key] - mb[key])
    out = {}
    for key in pa:
        delta = pa[key] - pb[key]
        if not evaluation.n_bootstrap:
            out[key] = Difference(delta, np.nan, np.nan, np.nan)
            continue
        d = np.concatenate(deltas[key])
        lo, hi = np.nanpercentile(d, [2.5, 97.5])
        d = d[~np.isnan(d)]
        se = float(np.std(d, ddof=1)) if d.size > 1 else np.nan
        out[key] = Difference(
            delta, lo, hi, _p_value(delta, d), se, _queries_needed(delta, se, len(a.s))
        )
    return out


#: The verdict words of a paired difference (docs/DEFINITIONS.md, "Verdicts"): the same in
#: :func:`~vpr_core.evaluation.compare`, the findings table and the README.
VERDICTS = ("higher", "lower", "inconclusive", "too few queries")


def difference_verdict(low: float, high: float, queries: float | None = None) -> str:
    """``"higher"`` when the 95% interval of a difference ``a - b`` lies above 0, ``"lower"`` when
    it lies below, ``"inconclusive"`` when it contains 0, ``"not computed"`` when a bound is not
    finite (no resamples), ``"too few queries (n < 6)"`` when ``queries`` (with ground truth;
    None or NaN: unknown) is below :data:`MIN_QUERIES`."""
    if not (np.isfinite(low) and np.isfinite(high)):
        return "not computed"
    if queries is not None and queries < MIN_QUERIES:  # NaN compares False: unknown
        return f"too few queries ({int(queries)} < {MIN_QUERIES})"
    if low > 0:
        return "higher"
    return "lower" if high < 0 else "inconclusive"


def needs_text(queries_needed: float) -> str:
    """``"needs ~1,200 queries"`` (2 significant digits); beyond ``REALISTIC_QUERIES``
    ``"needs over 100,000 queries: not decidable on any realistic set"``; NaN:
    ``"not computed"``."""
    q = float(queries_needed)
    if np.isnan(q):
        return "not computed"
    if q > REALISTIC_QUERIES:
        return f"needs over {REALISTIC_QUERIES:,} queries: not decidable on any realistic set"
    return f"needs ~{int(float(f'{math.ceil(q):.2g}')):,} queries"


def format_interval(value: float, low: float, high: float, digits: int = 3) -> str:
    """``"0.812 [0.751, 0.866]"``: a value with its interval; ``"0.812 [not computed]"`` when a
    bound is not finite (no resamples)."""
    if not (np.isfinite(low) and np.isfinite(high)):
        return f"{value:.{digits}f} [not computed]"
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
        ``"<name> p"`` for paired results and ``"<name> se"``, ``"<name> needed"`` (queries a
        verdict needs) for :class:`Difference` values.
    """
    cols: dict[str, float] = {}
    for key, vals in result.items():
        if len(vals) not in (3, 4):
            raise ValueError(
                f"result[{key!r}] must be (value, low, high) or (delta, low, high, p), "
                f"got {len(vals)} numbers"
            )
        name = prefix + _label(key)
        cols[name], cols[f"{name} lo"], cols[f"{name} hi"] = (float(v) for v in vals[:3])
        if len(vals) == 4:
            cols[f"{name} p"] = float(vals[3])
        if isinstance(vals, Difference):
            cols[f"{name} se"], cols[f"{name} needed"] = vals.se, vals.queries_needed
    return cols


#: The equivalence margin of a claim "on par" in AUC (docs/DEFINITIONS.md, "Verdicts"), fixed
#: before looking at the results: the claim holds only when the whole 95% interval of the
#: difference lies inside ``[-ON_PAR_MARGIN, +ON_PAR_MARGIN]``.
ON_PAR_MARGIN = 0.05

#: The leading words of every verdict :func:`claim_verdict` gives.
VERDICT_WORDS = (*VERDICTS, "on par", "not testable", "not computed")

_PAPER = {">": "higher", "<": "lower", "~": "on par"}


def _on_par_needs(delta: float, lo: float, hi: float, queries: float) -> str:
    """``"on par needs ~N queries"``: the queries at which an interval of today's half-width,
    shrinking as ``1 / sqrt(n)``, would fit inside the margin around ``delta``; empty when
    ``|delta|`` is at or beyond the margin (more queries would then show a difference) or the
    queries are unknown."""
    room = ON_PAR_MARGIN - abs(delta)
    if room <= 0 or not np.isfinite(queries) or queries <= 0:
        return ""
    return "on par " + needs_text(queries * ((hi - lo) / 2 / room) ** 2)


def claim_verdict(
    expect: str,
    lo: float,
    hi: float,
    delta: float | None = None,
    needs: float = np.nan,
    queries: float = np.nan,
) -> str:
    """The verdict on a claim about a difference ``a - b`` (docs/DEFINITIONS.md, "Verdicts"):
    the observed word (:func:`difference_verdict`; ``on par`` for a claim of parity whose
    interval lies inside :data:`ON_PAR_MARGIN`; :data:`IDENTICAL` for identical results), then
    how it stands to the claim: ``(as the paper says)`` or ``(paper: <word>)``; an inconclusive
    one names the queries a verdict would need where known.

    Args:
        expect: the claim: ``">"`` (higher), ``"<"`` (lower), ``"~"`` (on par), else none.
        lo, hi: the difference's 95% interval; delta: the difference.
        needs: the queries an inconclusive verdict would need (NaN: unknown).
        queries: the queries with ground truth (fewer than 6: too few).
    """
    if not (np.isfinite(lo) and np.isfinite(hi)):
        return "not run"
    if delta == 0 and lo == 0 and hi == 0:
        return IDENTICAL  # compare's words for the same case
    word = difference_verdict(lo, hi, queries)
    if word.startswith("too few"):
        return word
    # strictly inside: a table's bounds are rounded to 6 decimals, and one that rounds to the
    # margin may lie beyond it (0.0500004 is stored as 0.050000)
    if expect == "~" and lo > -ON_PAR_MARGIN and hi < ON_PAR_MARGIN:
        word = "on par"
    if word == "inconclusive":
        notes = [] if np.isnan(needs) else [needs_text(needs)]
        par = _on_par_needs(delta, lo, hi, queries) if expect == "~" and delta is not None else ""
        notes = [par] if par else notes
        return f"{word} ({'; '.join(notes)})" if notes else word
    if expect in _PAPER:
        paper = _PAPER[expect]
        return f"{word} ({'as the paper says' if word == paper else f'paper: {paper}'})"
    return word
