"""Where one run wins and the other loses: per query, each run's top-1 with its matched landmarks
and the correct reference (the figure of :func:`~vpr_core.evaluation.per_query`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from ..datasets.ground_truth import ground_truth_references
from ..evaluation import per_query
from ..labels import pair_matches
from ..matching import match_landmarks
from ..pipeline.cache import dataset_fingerprint
from .curves import dataset_line
from .matches import plot_labelled_matches

__all__ = ["plot_disagreements"]


#: Matches drawn per pair: the largest Eq. (1) terms, the ones that decided the score.
TOP_TERMS = 5


def _verdict(row: pd.Series, refs: list[int], frames: bool) -> str:
    """``"correct: reference 4"`` or ``"wrong: reference 17, 3 frames away"`` (frame-aligned
    data; else the correct references)."""
    r = int(row["top-1"])
    if row["top-1 correct"]:
        return f"correct: reference {r}"
    if frames and refs:
        away = min(abs(r - c) for c in refs)
        return f"wrong: reference {r}, {away} frame{'s' if away != 1 else ''} away"
    return f"wrong: reference {r} (correct: {', '.join(map(str, refs[:3]))})"


def _panel_title(row: pd.Series, pm: Any, top: np.ndarray, verdict: str) -> str:
    """Three lines: the verdict, the rank and ratio, the matches drawn."""
    rank = row["first correct rank"]
    head = (
        f"{row['run']}: {verdict}\nfirst correct rank {'-' if pd.isna(rank) else rank}, "
        f"ratio {row['ratio']:.2f} (lower = more confident)"
    )
    drawn = f"{len(pm.matches)} matches, the {len(top)} largest terms drawn"
    if pm.labels is None:
        return f"{head}\n{drawn} (unlabelled: no verified pair geometry)"
    if not pm.ground_truth:
        return f"{head}\n{drawn}: all wrong (another place)"
    return f"{head}\n{drawn}: {int(pm.labels[top].sum())} correct (green)"


def _run_panel(ax, ds, run: Any, row: pd.Series, img_q: np.ndarray, frames: bool) -> None:
    """One run's top-1 pair of query ``row["query"]`` (query left, reference right) with the
    :data:`TOP_TERMS` matches of largest Eq. (1) term, labelled."""
    q = int(row["query"])
    if pd.isna(row["top-1"]):
        ax.imshow(img_q)
        ax.set_axis_off()
        ax.set_title(f"{row['run']}: nothing retrieved (query without landmarks)", fontsize=8)
        return
    r = int(row["top-1"])
    pm = pair_matches(ds, run, q, r)
    d, b = run.descriptors, run.boxes
    terms = match_landmarks(d["query"][q], b["query"][q], d["reference"][r], b["reference"][r])
    top = np.argsort(-terms.scores, kind="stable")[:TOP_TERMS]
    refs = ground_truth_references(np.asarray(ds.ground_truth, dtype=bool), q)
    plot_labelled_matches(
        img_q,
        ds.load_image("reference", r),
        b["query"][q],
        b["reference"][r],
        pm.matches[top],
        None if pm.labels is None else pm.labels[top],
        ax=ax,
        title=_panel_title(row, pm, top, _verdict(row, refs, frames)),
    )
    ax.title.set_fontsize(8)
    ax.title.set_color("darkgreen" if row["top-1 correct"] else "firebrick")


def plot_disagreements(
    ds: Any, run_a: Any, run_b: Any, n: int = 6
) -> tuple[matplotlib.figure.Figure, pd.DataFrame]:
    """Queries where two runs decide differently: per row (a query, named in the last column),
    the query and each run's top-1 side by side with the :data:`TOP_TERMS` matches of largest
    Eq. (1) term, the ones that decided the score (green correct, red wrong, yellow unlabelled;
    labels from :func:`~vpr_core.labels.label_matches`, method ``auto``), and the correct
    reference; a wrong top-1 says which reference it matched and how many frames away.

    Args:
        ds: the runs' :class:`~vpr_core.datasets.PlaceDataset`.
        run_a, run_b: :class:`~vpr_core.pipeline.MethodResult` of ``ds`` run with
            ``keep_descriptors=True`` (the matches are recomputed from the descriptors).
        n: queries shown (rows): those where the runs disagree first (:func:`per_query`'s
            order), then agreeing ones when fewer disagree.

    Returns:
        ``(figure, table)``: ``table`` is :func:`~vpr_core.evaluation.per_query` of the two runs
        on the queries shown (its ``ratio`` column named ``ratio (lower = more confident)``).

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
    frames = run_a.tolerance is not None and not getattr(run_a, "ground_truth_from_file", False)
    columns = [f"[{r.label}] query | its top-1 reference" for r in (run_a, run_b)]
    columns.append("[correct] reference")
    h, w = ds.load_image("query", shown[0]).shape[:2]
    row_h = 5.2 * h / (2 * w) + 1.0  # a pair panel is 2/5 of 14 in wide, plus its 3-line title
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
            _run_panel(ax, ds, run, row, img_q, frames)
        ref = ground_truth_references(gt, q)[0]
        axrow[2].imshow(ds.load_image("reference", ref))
        axrow[2].set_axis_off()
        agree = "the runs agree" if not rows["disagree"].iloc[0] else "the runs disagree"
        name = Path(str(ds.query_paths[q])).name if len(ds.query_paths) > q else ""
        axrow[2].set_title(
            f"QUERY {q}{f' ({name})' if name else ''}\n{agree}\ncorrect reference {ref}",
            fontsize=8,
        )
    for ax, head in zip(axes[0], columns, strict=True):  # column headers over the first row
        ax.set_title(f"{head}\n{ax.get_title()}", fontsize=8, color=ax.title.get_color())
    fig.suptitle(
        f"Where {run_a.label} wins and where it loses against {run_b.label}: {n_disagree} of "
        f"{full['query'].nunique()} queries disagree (top-1 correct in one run only; "
        f"{len(shown)} shown, disagreements first)\n{dataset_line([run_a])}; the {TOP_TERMS} "
        "matches with the largest Eq. (1) terms: green correct, red wrong, yellow unlabelled",
        fontsize=9,
        x=0.01,
        y=0.995,
        ha="left",
        va="top",
    )
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.4 / fig.get_figheight()), h_pad=1.0)
    return fig, table.rename(columns={"ratio": "ratio (lower = more confident)"})
