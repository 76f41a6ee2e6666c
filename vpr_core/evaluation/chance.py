"""Chance level: each metric under a random ranking of the same ground truth, and the warning
when a set's metrics cannot tell runs from chance (docs/DEFINITIONS.md, "Chance level")."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from ..checks import check_int
from ..datasets.ground_truth import check_ground_truth, ground_truth_coverage
from ..notices import notice
from .curves import PRCurve, auc_pr, queries_with_ground_truth, recall_at_100_precision
from .spec import Evaluation, as_evaluation

__all__ = [
    "CHANCE_CHECKED",
    "CHANCE_RANKINGS",
    "SATURATION_SHARE",
    "chance",
    "chance_precision",
    "saturation_notice",
]


#: A ground truth where a random ranking's expected R@1 reaches this share saturates the metrics.
SATURATION_SHARE = 0.5

#: Seeded random rankings behind the chance AUC and R@100P of the per-query protocols.
CHANCE_RANKINGS = 1000

#: The metrics whose chance level :func:`saturation_notice` compares with every run's interval.
CHANCE_CHECKED = ("auc", "r@1")


def _soft_only(gt: np.ndarray, soft: np.ndarray | None) -> np.ndarray:
    """The pairs of ``soft`` (soft ground truth) outside ``gt``: neither right nor wrong."""
    return np.zeros(gt.shape, bool) if soft is None else np.asarray(soft, dtype=bool) & ~gt


def _chance_recall(gt: np.ndarray, k: int, soft: np.ndarray | None = None) -> float:
    """Exact R@k of a random ranking: mean of ``1 - C(Nr - c, k) / C(Nr, k)`` over queries with
    ground truth (``c`` correct references each; ``Nr`` without the query's soft-only ones,
    which the evaluation ranks last)."""
    nr = gt.shape[1] - _soft_only(gt, soft).sum(axis=1)
    counts = gt.sum(axis=1)
    kept = counts > 0
    pairs = list(zip(nr[kept].tolist(), counts[kept].tolist(), strict=True))

    def miss(n: int, c: int) -> float:
        kk = min(k, n)  # a list longer than the references holds them all
        return math.comb(n - c, kk) / math.comb(n, kk)

    table = {pair: miss(*pair) for pair in set(pairs)}
    return float(np.mean([1.0 - table[pair] for pair in pairs]))


def _p_correct(gt: np.ndarray, soft_only: np.ndarray, every_query: bool) -> np.ndarray:
    """Each counted query's chance ``c / Nr`` that a random top-1 is correct (``Nr`` without
    its soft-only references; ``every_query`` (``vpr_bench``), else those with ground truth)."""
    rows = np.ones(gt.shape[0], bool) if every_query else gt.any(axis=1)
    nr = gt.shape[1] - soft_only[rows].sum(axis=1)
    return gt[rows].sum(axis=1) / np.maximum(nr, 1)


def chance_precision(
    ground_truth: np.ndarray, evaluation: Evaluation | str = "ratio", soft: np.ndarray | None = None
) -> float:
    """The precision a random ranking keeps at every recall (the flat PR curve of chance).

    The share of decisions that are correct: ``c / Nr`` averaged over the queries the protocol
    (an :class:`~vpr_core.evaluation.Evaluation` or its name) counts (``vpr_bench``: every
    query; ``ratio`` / ``best_match``: those with ground truth), the share of ground-truth pairs
    for ``multi_match``. ``soft``: the soft ground truth, whose pairs outside ``ground_truth``
    are neither right nor wrong (left out of ``Nr``).
    """
    protocol = as_evaluation(evaluation).protocol
    gt = np.asarray(ground_truth, dtype=bool)
    soft_only = _soft_only(gt, soft)
    if protocol == "multi_match":
        return float(gt.sum() / max(gt.size - soft_only.sum(), 1))
    p = _p_correct(gt, soft_only, protocol == "vpr_bench")
    return float(p.mean()) if p.size else float("nan")


def _chance_multi_match(gt: np.ndarray, n: int) -> tuple[float, float]:
    """Exact expected ``(AUC, R@100P)`` of ``multi_match`` when the pairs come in random order.

    ``P`` ground-truth pairs of ``N``: the ``k``-th positive at 1-based position ``X_k`` adds a
    trapezoid of width ``1/P`` between precisions ``(k - 1) / (X_k - 1)`` (1 for ``X_1 = 1``)
    and ``k / X_k``; summing the expectations over positions gives
    ``(P + H_N + (P - 1)(N - H_N) / (N - 1)) / (2N)``. R@100P: ``E = (1/P) sum_k P(first k
    pairs all positive)``. ``n``: the pairs counted (soft-only ones left out).
    """
    pos = int(gt.sum())
    harmonic = float(np.sum(1.0 / np.arange(1, n + 1)))
    rest = (pos - 1) * (n - harmonic) / (n - 1) if n > 1 else 0.0
    auc = (pos + harmonic + rest) / (2 * n)
    j = np.arange(pos)
    r100p = float(np.cumprod((pos - j) / (n - j)).sum() / pos)
    return float(auc), r100p


def chance(
    ground_truth: np.ndarray,
    evaluation: Evaluation | str = "ratio",
    ks: Sequence[int] = (1, 5),
    n: int = CHANCE_RANKINGS,
    seed: int = 0,
    soft: np.ndarray | None = None,
) -> dict[str, float]:
    """Each table metric under a random ranking of the same ground truth (its chance level);
    exact values, printed rounded to 3 decimals.

    R@K is exact (docs/DEFINITIONS.md, "Chance level"); so are AUC and R@100P of
    ``multi_match``. AUC and R@100P of the per-query protocols are the mean over ``n`` seeded
    random rankings: each counted query's top-1 is correct with probability ``c / Nr``,
    independently of its score, and the scores order the queries at random.

    Args:
        ground_truth: ``(Nq, Nr)`` bool.
        evaluation: the protocol of AUC and R@100P: an
            :class:`~vpr_core.evaluation.Evaluation` or the name (a run's ``.protocol``) of one of
            :data:`~vpr_core.evaluation.PROTOCOLS`.
        ks: the K of R@K.
        n: random rankings of the per-query protocols (>= 1).
        seed: their seed (same seed, same values).
        soft: optional ``(Nq, Nr)`` bool soft ground truth (the dataset's
            ``ground_truth_soft``): its pairs outside ``ground_truth`` are neither right nor
            wrong, so a random ranking draws from the other references (the evaluation ranks
            them last).

    Returns:
        ``{"auc", "r@100p", "r@K"...}`` (the keys of :func:`evaluate`), a dict printed rounded.

    Raises:
        ValueError: no query with ground truth, bad protocol, ``n`` or ``ks``.
    """
    evaluation = as_evaluation(evaluation)
    protocol = evaluation.protocol
    n = check_int(n, "n (random rankings)", 1)
    ks = tuple(check_int(k, "k", 1) for k in ks)
    ground_truth_coverage(ground_truth)  # refuses what is not a (Nq, Nr) matrix
    gt = check_ground_truth(ground_truth, np.shape(ground_truth), "(ground_truth=)")
    queries_with_ground_truth(gt)  # raises without ground truth
    if soft is not None:
        soft = check_ground_truth(soft, gt.shape, "(soft=, the dataset's ground_truth_soft)")
    soft_only = _soft_only(gt, soft)
    if protocol == "multi_match":
        auc, r100p = _chance_multi_match(gt, int(gt.size - soft_only.sum()))
    else:
        p_correct = _p_correct(gt, soft_only, protocol == "vpr_bench")
        rng = np.random.default_rng(seed)
        values = []
        for _ in range(n):
            correct = rng.random(p_correct.size) < p_correct
            curve = PRCurve.from_query_scores(rng.random(p_correct.size), correct, evaluation, 0)
            values.append((auc_pr(curve), recall_at_100_precision(curve)))
        auc, r100p = (float(v) for v in np.mean(values, axis=0))
    out = _ChanceLevels(auc=auc, **{"r@100p": r100p})
    for k in ks:
        out[f"r@{k}"] = _chance_recall(gt, k, soft_only)
    return out


class _ChanceLevels(dict):
    """:func:`chance`'s exact values, printed rounded to 3 decimals (``0.1``, never
    ``0.09999999999999998``)."""

    def __repr__(self) -> str:
        return "{" + ", ".join(f"{k!r}: {round(v, 3)!r}" for k, v in self.items()) + "}"


def _inside(value: float, interval: Sequence[float]) -> bool:
    return len(interval) == 3 and bool(interval[1] <= value <= interval[2])


def saturation_notice(
    ground_truth: np.ndarray,
    intervals: Mapping | Sequence[Mapping] | None = None,
    evaluation: Evaluation | str = "ratio",
    soft: np.ndarray | None = None,
    labels: Sequence[str] | None = None,
    tolerance: int | None = None,
) -> str | None:
    """Warn (:func:`~vpr_core.notices.notice`) when the ground truth makes the metrics meaningless.

    Three cases: a random ranking's R@1 (:func:`chance`) is at least :data:`SATURATION_SHARE`;
    every interval of every run is ``[1, 1]``; or, given the runs of a comparison (a sequence),
    the chance level of a metric of :data:`CHANCE_CHECKED` lies inside every run's interval
    (the set cannot tell these runs from a random ranking; the notice names each run with its
    interval, so it can be read against the table). One run's intervals (a mapping) are not
    checked against chance: its table prints the chance level beside it.

    Args:
        ground_truth: ``bool (Nq, Nr)``.
        intervals: one run's ``{"auc": (value, lo, hi), ...}`` (:func:`bootstrap_metrics`), or a
            sequence of them (the runs being compared; a run without intervals: ``{}``).
        evaluation: the protocol of the intervals' AUC (an
            :class:`~vpr_core.evaluation.Evaluation` or its name).
        soft: optional soft ground truth (as :func:`chance`).
        labels: the runs' labels, in the order of ``intervals`` (default ``run 1``, ...).
        tolerance: the ground truth's frame tolerance, when known: a smaller one is advised
            only when it is above 0.

    Returns:
        The message, or None when the metrics are not saturated.
    """
    gt = np.asarray(ground_truth, dtype=bool)
    if not gt.any():
        return None
    share = _chance_recall(gt, 1, soft)
    if share >= SATURATION_SHARE:
        fix = (
            "a larger set (the tolerance is already 0)"
            if tolerance == 0
            else "a smaller tolerance (e.g. tolerance=0) or a larger set"
        )
        return notice(
            f"saturated ground truth: on average {share:.0%} of the {gt.shape[1]} "
            f"references count as correct for a query, so a random ranking gets R@1 "
            f"~{share:.2f} and AUC near 1; the metrics cannot rank methods. Use {fix}.",
            stacklevel=4,
        )
    runs = [intervals] if isinstance(intervals, Mapping) else list(intervals or [])
    ivs = [v for run in runs for v in run.values() if len(v) == 3 and np.isfinite(v[1])]
    harder = "a harder set or more places" + (", or tolerance=0" if tolerance else "")
    if ivs and all(lo == 1.0 and hi == 1.0 for _, lo, hi in ivs):
        if isinstance(intervals, Mapping):  # one run: a verdict against a lower run holds
            return notice(
                "saturated result: every metric of this run is 1.0 with interval [1.0, 1.0]; "
                "the set cannot rank it against another perfect run (a paired verdict against "
                f"a run below it still holds). To rank the best methods use {harder}.",
                stacklevel=4,
            )
        return notice(
            "saturated result: every metric of every run is 1.0 with interval [1.0, 1.0]; "
            f"this set cannot tell these runs apart. Use {harder}.",
            stacklevel=4,
        )
    if isinstance(intervals, Mapping) or not runs:
        return None
    evaluation = as_evaluation(evaluation)
    level = chance(gt, evaluation, ks=(1,), soft=soft)
    at_chance = [
        key
        for key in CHANCE_CHECKED
        if all(key in run and _inside(level[key], run[key]) for run in runs)
    ]
    if at_chance:
        names = list(labels) if labels is not None else [f"run {i + 1}" for i in range(len(runs))]
        named = ", ".join(f"{key.upper()} {level[key]:.3f}" for key in at_chance)
        each = "; ".join(
            f"{key.upper()}: "
            + ", ".join(
                f"{n} {run[key][0]:.3f} [{run[key][1]:.3f}, {run[key][2]:.3f}]"
                for n, run in zip(names, runs, strict=False)
            )
            for key in at_chance
        )
        return notice(
            f"at chance level: a random ranking of this ground truth scores {named} "
            f"(protocol {evaluation.protocol}), inside the 95% interval of every run ({each}); "
            "this set cannot tell these runs from chance on that metric. Use more queries or "
            "a harder set.",
            stacklevel=4,
        )
    return None
