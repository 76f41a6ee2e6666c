"""Evaluation of a query x reference similarity matrix: curves and metrics (``curves``),
their chance level (``chance``), bootstrap intervals and paired differences (``bootstrap``),
the comparison table (``compare``), the per-query view (``queries``) and what a step changed
(``steps``, ``whitening``)."""

from __future__ import annotations

from .bootstrap import (
    IDENTICAL,
    N_BOOTSTRAP,
    ON_PAR_MARGIN,
    VERDICT_WORDS,
    VERDICTS,
    bootstrap_metrics,
    claim_verdict,
    difference_verdict,
    format_interval,
    metrics_and_intervals,
    needs_text,
    paired_bootstrap,
)
from .chance import chance, chance_precision
from .compare import (
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
from .queries import per_query
from .ranks import best_two, query_scores, ranked, true_rank
from .spec import Evaluation, refuse_tolerance
from .steps import carried_landmarks, step_changes
from .whitening import whitening_changes

__all__ = [
    "IDENTICAL",
    "N_BOOTSTRAP",
    "ON_PAR_MARGIN",
    "PROTOCOLS",
    "VERDICTS",
    "VERDICT_WORDS",
    "Evaluation",
    "PRCurve",
    "auc_pr",
    "best_two",
    "bootstrap_metrics",
    "chance",
    "claim_verdict",
    "chance_precision",
    "carried_landmarks",
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
    "per_query",
    "pr_curve",
    "query_scores",
    "ranked",
    "recall_at_100_precision",
    "recall_at_k",
    "recall_rate_at_n",
    "refuse_tolerance",
    "step_changes",
    "true_rank",
    "whitening_changes",
]
