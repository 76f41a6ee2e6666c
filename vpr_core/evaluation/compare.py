"""The one comparison table: metrics with 95% intervals and paired differences with verdicts.

``compare(results, baseline=...)`` is what a notebook cell shows under a PR figure and what the
CLI prints and writes: one row per result (indexed by its label) with AUC, R@100P, R@1 and R@5
and their bootstrap intervals over queries, and, for every result but the baseline, the paired
bootstrap differences ``result - baseline`` (same resampled queries) with a verdict per metric:
``finding`` only when the 95% interval excludes 0. Context columns (dataset, root, tolerance,
protocol, backbone, pooling, package version) make a saved CSV self-describing; ``run`` is the
configuration's identity (:func:`vpr_core.methods.run_key`) that the paper's claims are matched
on. A result whose similarity matrix equals an earlier one's is marked in ``identical to``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd

from .bootstrap import N_BOOTSTRAP, bootstrap_columns, difference_verdict, paired_bootstrap

__all__ = ["DIFFERENCES", "compare", "identical_to"]

#: The paired differences of :func:`compare` (column prefix -> metric key).
DIFFERENCES = {"dAUC": "auc", "dR@100P": "r@100p", "dR@1": "r@1"}


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and bool(np.array_equal(a, b, equal_nan=True))


def _same_result(a: Any, b: Any) -> bool:
    """Same similarity matrix, or the same PR curve, metrics and per-query ranking decision
    (then nothing a table or figure shows can tell the two apart)."""
    if _same(np.asarray(a.similarity), np.asarray(b.similarity)):
        return True
    if getattr(a, "metrics", None) != getattr(b, "metrics", None):
        return False
    ca, cb = a.curve(), b.curve()
    return _same(np.asarray(ca.recall), np.asarray(cb.recall)) and _same(
        np.asarray(ca.precision), np.asarray(cb.precision)
    )


def identical_to(results: Sequence[Any]) -> list[str | None]:
    """Per result, the label of the first earlier result with the same similarity matrix, or
    the same metrics and PR curve (then the figure draws one curve and the table says so),
    else None."""
    out: list[str | None] = []
    for i, r in enumerate(results):
        out.append(next((p.label for p in results[:i] if _same_result(p, r)), None))
    return out


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("vpr-landmarks")
    except PackageNotFoundError:  # pragma: no cover - running from a bare source tree
        return "unknown"


def _context(r: Any) -> dict:
    enc = getattr(r, "encoder", {}) or {}
    return {
        "dataset": r.dataset,
        "root": getattr(r, "root", None),
        "tolerance": getattr(r, "tolerance", None),
        "protocol": getattr(r, "protocol", "ratio"),
        "backbone": enc.get("backbone"),
        "pooling": enc.get("pooling"),
        "version": _version(),
    }


def compare(
    results: Sequence[Any],
    baseline: str | int | None = None,
    n_bootstrap: int = N_BOOTSTRAP,
    seed: int = 0,
) -> pd.DataFrame:
    """Metrics with intervals for every result, and paired differences against a baseline.

    Args:
        results: :class:`~vpr_core.pipeline.MethodResult` objects (or peers from
            :func:`~vpr_core.pipeline.peer_result`) on the same dataset.
        baseline: the label (or position) of the result the others are compared with;
            default: the first.
        n_bootstrap: resamples of the paired bootstrap (0: differences without intervals,
            verdict ``not computed``).
        seed: seed of the resampling.

    Returns:
        DataFrame indexed by label: ``run``, ``AUC``/``AUC lo``/``AUC hi`` ... ``R@5 hi``,
        ``queries``, the cost columns, ``identical to``, ``baseline`` and for each of
        :data:`DIFFERENCES` the delta, ``lo``, ``hi``, ``p``, ``verdict`` and ``needs``
        (queries at which an inconclusive interval would exclude 0, where known), then the
        context columns and ``warnings``.

    Raises:
        ValueError: no results, duplicate labels, an unknown baseline, or results on different
            datasets (ground truths differ).
    """
    results = list(results)
    if not results:
        raise ValueError("compare() needs at least one result")
    labels = [r.label for r in results]
    dup = sorted({x for x in labels if labels.count(x) > 1})
    if dup:
        raise ValueError(
            f"compare(): labels must be unique, repeated: {dup}; pass label=... to "
            "run_method to tell the runs apart"
        )
    if baseline is None:
        base = results[0]
    elif isinstance(baseline, int):
        base = results[baseline]
    elif baseline in labels:
        base = results[labels.index(baseline)]
    else:
        raise ValueError(f"baseline {baseline!r} is not one of the results: {', '.join(labels)}")
    gt = np.asarray(base.ground_truth, dtype=bool)
    for r in results:
        if not _same(np.asarray(r.ground_truth, dtype=bool), gt):
            raise ValueError(
                f"compare(): {r.label!r} was evaluated on another ground truth than "
                f"{base.label!r}; compare runs of one dataset only"
            )
    protocols = sorted({getattr(r, "protocol", "ratio") for r in results})
    if len(protocols) > 1:
        raise ValueError(
            f"compare(): the results use different protocols ({', '.join(protocols)});"
            " run them all with the same protocol=..."
        )
    protocol = protocols[0]
    twins = identical_to(results)
    rows = []
    for r, twin in zip(results, twins, strict=False):
        row = {**r.row(), "identical to": twin, "baseline": None}
        if r is not base:
            row["baseline"] = base.label
            diff = paired_bootstrap(
                r.similarity,
                base.similarity,
                gt,
                n=n_bootstrap,
                seed=seed,
                ks=(1,),
                protocol=protocol,
            )
            cols = bootstrap_columns({k: diff[k] for k in DIFFERENCES.values()}, prefix="d")
            for name, key in DIFFERENCES.items():
                lo, hi = cols[f"{name} lo"], cols[f"{name} hi"]
                row.update(
                    {
                        name: cols[name],
                        f"{name} lo": lo,
                        f"{name} hi": hi,
                        f"{name} p": cols[f"{name} p"],
                        f"{name} verdict": difference_verdict(lo, hi),
                        f"{name} needs": getattr(diff[key], "queries_needed", np.nan),
                    }
                )
        row.update(_context(r))
        row["warnings"] = " | ".join(getattr(r, "warnings", []) or [])
        rows.append(row)
    return pd.DataFrame(rows).set_index("method")
