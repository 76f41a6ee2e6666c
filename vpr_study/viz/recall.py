"""VPR-Bench's RecallRate@N curve (N = 1..20) for several methods."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from types import SimpleNamespace

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from vpr_core.evaluation import recall_rate_at_n

from .styles import run_styles

__all__ = ["plot_recall_at_n"]


def plot_recall_at_n(
    results_or_curves: Sequence | Mapping, title: str | None = None, n_max: int = 20
) -> Figure:
    """RecallRate@N against N = 1..``n_max``, one line per run (``MethodResult``) or per
    ``{label: (n,) RecallRate@N}`` entry; legend outside the axes, right. Runs are told apart
    as in every figure (:func:`~vpr_study.viz.styles.run_styles`: colour by method, line style
    by weighting, marker by the other settings, labels that say what differs); an entry of a
    mapping takes the colour of the method its label names."""
    if isinstance(results_or_curves, Mapping):
        curves = {str(k): np.asarray(v, dtype=float) for k, v in results_or_curves.items()}
        runs: list = [SimpleNamespace(label=k) for k in curves]
    else:
        runs = list(results_or_curves)
        curves = {
            r.label: recall_rate_at_n(r.similarity, r.ground_truth, n_max)
            for r in results_or_curves
        }
    fig, ax = plt.subplots(figsize=(7.0, 3.8), constrained_layout=True)
    for run, style in zip(runs, run_styles(runs), strict=True):
        y = curves[run.label]
        kw = style.line()
        kw["marker"] = style.marker or "."  # each N marked; "." is no setting's marker
        ax.plot(np.arange(1, y.size + 1), y, ms=4, lw=1.5, label=style.label, **kw)
    ax.set_xlabel("N")
    ax.set_ylabel("RecallRate@N (VPR-Bench)")
    ax.set_ylim(0.0, 1.02)
    ax.grid(alpha=0.3)
    if title:
        ax.set_title(title)
    if curves:
        ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), frameon=False)
    return fig
