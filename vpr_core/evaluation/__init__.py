"""Evaluation of a query x reference similarity matrix.

* :mod:`~vpr_core.evaluation.curves`: precision-recall curves (``ratio``, ``best_match``,
  ``vpr_bench``, ``multi_match`` protocols), AUC, R@100P, R@K, VPR-Bench's RecallRate@N,
  ground-truth coverage, NaN = unranked, soft ground truth (``ignore=``).
* :mod:`~vpr_core.evaluation.bootstrap`: bootstrap intervals over queries and paired differences
  with p-values, standard errors and the queries a verdict needs, and helpers that format them.
"""

from __future__ import annotations

from .bootstrap import (
    N_BOOTSTRAP,
    Difference,
    bootstrap_columns,
    bootstrap_metrics,
    difference_verdict,
    format_interval,
    needs_text,
    paired_bootstrap,
)
from .compare import compare
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
    recall_rate_at_n,
    saturation_notice,
)

__all__ = [
    "N_BOOTSTRAP",
    "PROTOCOLS",
    "Difference",
    "PRCurve",
    "auc_pr",
    "bootstrap_columns",
    "bootstrap_metrics",
    "compare",
    "difference_verdict",
    "evaluate",
    "format_interval",
    "ground_truth_coverage",
    "metrics_table",
    "needs_text",
    "paired_bootstrap",
    "pr_curve",
    "recall_at_100_precision",
    "recall_at_k",
    "recall_rate_at_n",
    "saturation_notice",
]
