"""Where one run wins and the other loses: per query, each run's top-1 with its matched landmarks
and the correct reference (the figure of :func:`~vpr_core.evaluation.per_query`)."""

from __future__ import annotations

from typing import Any

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from ..datasets.ground_truth import ground_truth_references
from ..evaluation import per_query
from ..labels import pair_matches
from ..pipeline.cache import dataset_fingerprint
from .curves import dataset_line
from .matches import plot_labelled_matches

__all__ = ["plot_disagreements"]


def _panel_title(row: pd.Series, pm: Any) -> str:
    """``"dense: top-1 r4 wrong, first correct rank 4, ratio 0.96"`` and a line on the matches."""
    rank = row["first correct rank"]
    verdict = "correct" if row["top-1 correct"] else "wrong"
    head = (
        f"{row['run']}: top-1 r{row['top-1']} {verdict}, first correct rank "
        f"{'-' if pd.isna(rank) else rank}, ratio {row['ratio']:.2f}"
    )
    if pm.labels is None:
        return f"{head}\n{len(pm.matches)} matches (unlabelled: no verified pair geometry)"
    if not pm.ground_truth:
        return f"{head}\n{len(pm.matches)} matches, all wrong (another place)"
    return f"{head}\n{len(pm.matches)} matches: {int(pm.labels.sum())} correct (green)"


def _run_panel(ax, ds, run: Any, row: pd.Series, img_q: np.ndarray) -> None:
    """One run's top-1 pair of query ``row["query"]`` with its labelled matches."""
    q = int(row["query"])
    if pd.isna(row["top-1"]):
        ax.imshow(img_q)
        ax.set_axis_off()
        ax.set_title(f"{row['run']}: nothing retrieved (query without landmarks)", fontsize=8)
        return
    r = int(row["top-1"])
    pm = pair_matches(ds, run, q, r)
    plot_labelled_matches(
        img_q,
        ds.load_image("reference", r),
        run.boxes["query"][q],
        run.boxes["reference"][r],
        pm.matches,
        pm.labels,
        ax=ax,
        lw=0.6,
        title=_panel_title(row, pm),
    )
    ax.title.set_fontsize(8)
    ax.title.set_color("darkgreen" if row["top-1 correct"] else "firebrick")


def plot_disagreements(
    ds: Any, run_a: Any, run_b: Any, n: int = 6
) -> tuple[matplotlib.figure.Figure, pd.DataFrame]:
    """Queries where two runs decide differently: the query and each run's top-1 side by side
    with the matched landmarks (green correct, red wrong, yellow unlabelled; labels from
    :func:`~vpr_core.labels.label_matches`, method ``auto``), and the correct reference.

    Args:
        ds: the runs' :class:`~vpr_core.datasets.PlaceDataset`.
        run_a, run_b: :class:`~vpr_core.pipeline.MethodResult` of ``ds`` run with
            ``keep_descriptors=True`` (the matches are recomputed from the descriptors).
        n: queries shown (rows): those where the runs disagree first (:func:`per_query`'s
            order), then agreeing ones when fewer disagree.

    Returns:
        ``(figure, table)``: ``table`` is :func:`~vpr_core.evaluation.per_query` of the two runs
        on the queries shown.

    Raises:
        ValueError: ``n < 1``, runs without descriptors, or runs of another dataset.
    """
    if int(n) < 1:
        raise ValueError(f"n (queries shown) must be >= 1, got {n}")
    for run in (run_a, run_b):
        if getattr(run, "descriptors", None) is None:
            raise ValueError(
                f"plot_disagreements needs the descriptors of {run.label!r}: run it with "
                "run_method(..., keep_descriptors=True)"
            )
        if getattr(run, "dataset_fingerprint", None) not in (None, dataset_fingerprint(ds)):
            raise ValueError(
                f"plot_disagreements: {run.label!r} was run on another dataset than {ds.name!r} "
                "(their fingerprints differ); pass the dataset the runs were computed on"
            )
    full = per_query([run_a, run_b])
    shown = list(dict.fromkeys(full["query"]))[: int(n)]
    table = full[full["query"].isin(shown)].reset_index(drop=True)
    n_disagree = full.loc[full["disagree"], "query"].nunique()
    gt = np.asarray(ds.ground_truth, dtype=bool)
    h, w = ds.load_image("query", shown[0]).shape[:2]
    row_h = 5.2 * h / (2 * w) + 0.55  # a pair panel is 2/5 of 14 in wide, plus its 2-line title
    fig, axes = plt.subplots(
        len(shown),
        3,
        figsize=(14.0, row_h * len(shown) + 0.6),
        gridspec_kw={"width_ratios": [2, 2, 1]},
        squeeze=False,
    )
    for axrow, q in zip(axes, shown, strict=True):
        img_q = ds.load_image("query", q)
        rows = table[table["query"] == q]
        for ax, run, (_, row) in zip(axrow[:2], (run_a, run_b), rows.iterrows(), strict=True):
            _run_panel(ax, ds, run, row, img_q)
        ref = ground_truth_references(gt, q)[0]
        axrow[2].imshow(ds.load_image("reference", ref))
        axrow[2].set_axis_off()
        agree = "" if rows["disagree"].iloc[0] else " (the runs agree)"
        axrow[2].set_title(f"query {q}{agree}: correct reference r{ref}", fontsize=8)
    fig.suptitle(
        f"Where {run_a.label} wins and where it loses against {run_b.label}: {n_disagree} of "
        f"{full['query'].nunique()} queries disagree (top-1 correct in one run only; "
        f"{len(shown)} shown, disagreements first)\n{dataset_line([run_a])}; matches: green "
        "correct, red wrong, yellow unlabelled",
        fontsize=9,
        x=0.01,
        y=0.995,
        ha="left",
        va="top",
    )
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.4 / fig.get_figheight()), h_pad=1.0)
    return fig, table
