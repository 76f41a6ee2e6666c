"""Evaluation of a query x reference similarity matrix: curves and metrics (``curves``),
their chance level (``chance``), bootstrap intervals and paired differences (``bootstrap``),
the comparison table (``compare``), the per-query view (``insight``)."""

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
from .chance import chance, saturation_notice
from .compare import ComparisonTable, compact, compact_text, compare, compare_pairs
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
)
from .insight import per_query
from .spec import Evaluation

__all__ = [
    "N_BOOTSTRAP",
    "PROTOCOLS",
    "ComparisonTable",
    "Difference",
    "Evaluation",
    "PRCurve",
    "auc_pr",
    "bootstrap_columns",
    "bootstrap_metrics",
    "chance",
    "compact",
    "compact_text",
    "compare",
    "compare_pairs",
    "difference_verdict",
    "evaluate",
    "format_interval",
    "ground_truth_coverage",
    "metrics_table",
    "needs_text",
    "paired_bootstrap",
    "per_query",
    "pr_curve",
    "recall_at_100_precision",
    "recall_at_k",
    "recall_rate_at_n",
    "saturation_notice",
]
