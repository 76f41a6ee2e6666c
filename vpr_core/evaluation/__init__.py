"""Evaluation of a query x reference similarity matrix: curves and metrics (``curves``),
their chance level (``chance``), bootstrap intervals and paired differences (``bootstrap``),
the comparison table (``compare``)."""

from __future__ import annotations

from .bootstrap import (
    N_BOOTSTRAP,
    VERDICTS,
    bootstrap_metrics,
    difference_verdict,
    format_interval,
    metrics_and_intervals,
    needs_text,
    paired_bootstrap,
)
from .chance import chance, chance_precision
from .compare import (
    IDENTICAL,
    check_results,
    check_same_dataset,
    compact,
    compare,
    compare_pairs,
    identical_to,
)
from .curves import (
    PROTOCOLS,
    PRCurve,
    auc_pr,
    evaluate,
    ground_truth_coverage,
    pr_curve,
    recall_at_100_precision,
    recall_at_k,
    recall_rate_at_n,
)
from .ranks import best_two, query_scores, ranked, true_rank
from .spec import Evaluation, check_bootstrap_memory, refuse_tolerance

__all__ = [
    "IDENTICAL",
    "N_BOOTSTRAP",
    "PROTOCOLS",
    "VERDICTS",
    "Evaluation",
    "PRCurve",
    "auc_pr",
    "best_two",
    "bootstrap_metrics",
    "chance",
    "chance_precision",
    "check_bootstrap_memory",
    "check_results",
    "check_same_dataset",
    "compact",
    "compare",
    "compare_pairs",
    "difference_verdict",
    "evaluate",
    "format_interval",
    "ground_truth_coverage",
    "metrics_and_intervals",
    "identical_to",
    "needs_text",
    "paired_bootstrap",
    "pr_curve",
    "query_scores",
    "ranked",
    "recall_at_100_precision",
    "recall_at_k",
    "recall_rate_at_n",
    "refuse_tolerance",
    "true_rank",
]
