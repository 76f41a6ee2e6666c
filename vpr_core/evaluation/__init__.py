"""Evaluation of a query x reference similarity matrix.

* :mod:`~vpr_core.evaluation.curves`: precision-recall curves (``ratio``, ``best_match``,
  ``multi_match`` protocols), AUC, R@100P, R@K, ground-truth coverage, NaN = unranked.
* :mod:`~vpr_core.evaluation.bootstrap`: bootstrap intervals over queries and paired differences
  with p-values, and helpers that format them for tables.
"""

from __future__ import annotations

from .bootstrap import (
    N_BOOTSTRAP,
    bootstrap_columns,
    bootstrap_metrics,
    difference_verdict,
    format_interval,
    paired_bootstrap,
)
from .curves import (
    PROTOCOLS,
    PRCurve,
    auc_pr,
    evaluate,
    ground_truth_coverage,
    metrics_table,
    pr_curve,
    recall_at_100_precision,
    recall_at_k,
)

__all__ = [
    "N_BOOTSTRAP",
    "PROTOCOLS",
    "PRCurve",
    "auc_pr",
    "bootstrap_columns",
    "bootstrap_metrics",
    "difference_verdict",
    "evaluate",
    "format_interval",
    "ground_truth_coverage",
    "metrics_table",
    "paired_bootstrap",
    "pr_curve",
    "recall_at_100_precision",
    "recall_at_k",
]
