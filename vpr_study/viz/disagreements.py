"""Where one run wins and the other loses: per query, each run's top-1 with its matched landmarks
and the correct reference (the figure of :func:`~vpr_core.evaluation.per_query`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any, cast

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from vpr_core import checks, ground_truth_references, match_landmarks, pair_matches, per_query

from ._shared import FIG_WIDTH, FONT, check_runs_on, wrapped
from .base import TableFigure
from .curves import dataset_line
from .matches import GAP, plot_labelled_matches

__all__ = ["plot_disagreements"]


#: Matches drawn per pair: the largest Eq. (1) terms, the ones that decided the score.
TOP_TERMS = 5

#: Width ratios of a row's panels: each run's pair, the correct reference (one image of a
#: pair: the three images of a row have the same height).
_RATIOS = (2.0, 2.0, 1.0)


def _pick(full: pd.DataFrame, a: str, b: str, n: int) -> tuple[list[int], dict[int, str], int, int]:
    """``(queries, what each shows, wins, losses)``: up to ``n`` queries to show, each
    ``"<a> wins"``, ``"<a> loses"`` or ``"the runs agree"``, and ``a``'s wins and losses over
    every query. Wins and losses both when both exist (half each, the rest from the other
    kind), then agreeing queries; each kind in query order."""
    ok = full.pivot(index="query", columns="run", values="top-1 correct").astype(bool)
    order = list(dict.fromkeys(full["query"]))
    wins = [q for q in order if ok.loc[q, a] and not ok.loc[q, b]]
    losses = [q for q in order if ok.loc[q, b] and not ok.loc[q, a]]
    agree = [q for q in order if ok.loc[q, a] == ok.loc[q, b]]
    n_loss = min(len(losses), max(n // 2, n - len(wins)))
    n_win = min(len(wins), n - n_loss)
    shown = wins[:n_win] + losses[:n_loss]
    shown += agree[: n - len(shown)]
    kind = {q: f"{a} wins" for q in wins} | {q: f"{a} loses" for q in losses}
    return shown, {q: kind.get(q, "the runs agree") for q in shown}, len(wins), len(losses)


#: A wrong top-1 at most this many frames from a correct reference (frame-aligned real data)
#: may show the same scene: its matches are drawn unlabelled, not wrong ("another place").
NEAR_FRAMES = 1


def _frames_away(row: pd.Series, refs: list[int], frames: bool) -> int | None:
    """How many frames a wrong top-1 lies from the nearest correct reference (frame-aligned
    data), else None."""
    if row["top-1 correct"] or not frames or not refs:
        return None
    return min(abs(int(row["top-1"]) - c) for c in refs)


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


def _panel_title(row: pd.Series, pm: Any, top: np.ndarray, verdict: str, near: bool) -> str:
    """Four short lines (they fit the panel at :data:`FONT`): the verdict, the rank and ratio,
    the matches drawn, their labels (``near``: a wrong top-1 next to the correct place, its
    matches not labelled)."""
    rank = row["first correct rank"]
    head = (
        f"{row['run']}: {verdict}\nfirst correct rank {'-' if pd.isna(rank) else rank}, "
        f"ratio {row['ratio']:.2f}"
    )
    drawn = f"{len(pm.matches)} matches, the {len(top)} largest terms drawn"
    if near:
        return f"{head}\n{drawn}\nunlabelled: it may show the same scene"
    if pm.labels is None:
        return f"{head}\n{drawn}\nunlabelled (no verified pair geometry)"
    if not pm.ground_truth:
        return f"{head}\n{drawn}\nall wrong (another place)"
    return f"{head}\n{drawn}\n{int(pm.labels[top].sum())} correct (green)"


def _run_panel(ax, ds, run: Any, row: pd.Series, img_q: np.ndarray, frames: bool) -> None:
    """One run's top-1 pair of query ``row["query"]`` (query left, reference right) with the
    :data:`TOP_TERMS` matches of largest Eq. (1) term, labelled."""
    q = int(row["query"])
    if pd.isna(row["top-1"]):
        ax.imshow(img_q)
        ax.set_axis_off()
        ax.set_title(f"{row['run']}: nothing retrieved\n(query without landmarks)", fontsize=FONT)
        return
    r = int(row["top-1"])
    pm = pair_matches(ds, run, q, r)
    d, b = run.descriptors, run.boxes
    terms = match_landmarks(d["query"][q], b["query"][q], d["reference"][r], b["reference"][r])
    top = np.argsort(-terms.scores, kind="stable")[:TOP_TERMS]
    refs = ground_truth_references(np.asarray(ds.ground_truth, dtype=bool), q)
    away = _frames_away(row, refs, frames)
    # generated places are distinct (exact geometry): a neighbour is another place there
    near = away is not None and away <= NEAR_FRAMES and getattr(ds, "homographies", None) is None
    plot_labelled_matches(
        img_q,
        ds.load_image("reference", r),
        b["query"][q],
        b["reference"][r],
        pm.matches[top],
        None if pm.labels is None or near else pm.labels[top],
        ax=ax,
        title=_panel_title(row, pm, top, _verdict(row, refs, frames), near),
    )
    ax.title.set_fontsize(FONT)
    ax.title.set_color("darkgreen" if row["top-1 correct"] else "firebrick")


def plot_disagreements(ds: Any, run_a: Any, run_b: Any, n: int = 6) -> TableFigure:
    """Queries where two runs decide differently: per row (a query, named in the last column
    with what it shows: ``<run_a> wins``, ``<run_a> loses`` or ``the runs agree``),
    the query and each run's top-1 side by side with the :data:`TOP_TERMS` matches of largest
    Eq. (1) term, the ones that decided the score (green correct, red wrong, yellow unlabelled;
    labels from :func:`~vpr_core.labels.label_matches`, method ``auto``), and the correct
    reference; a wrong top-1 says which reference it matched and how many frames away (on
    real frame-aligned data, one at most :data:`NEAR_FRAMES` from a correct reference may show
    the same scene: its matches are drawn unlabelled, not wrong).

    Args:
        ds: the runs' :class:`~vpr_core.datasets.PlaceDataset`.
        run_a, run_b: :class:`~vpr_core.MethodResult` of ``ds`` run with
            ``keep_descriptors=True`` (the matches are recomputed from the descriptors), e.g.
            ``run_method("dense", ds, keep_descriptors=True)``.
        n: queries shown (rows): where the runs disagree, ``run_a``'s wins and losses both
            when both exist (half each, the rest from the other kind; each in query order),
            then agreeing ones when fewer disagree. The title counts the wins and losses over
            every query and says how many of each are shown; each row says which it is.

    Returns:
        The figure (``save(fig, name, label)``); its ``.table`` is
        :func:`~vpr_core.evaluation.per_query` of the two runs on the queries shown, in the
        rows' order (its ``ratio`` column named ``ratio (lower = more confident)``).

    Raises:
        ValueError: ``n < 1``, runs without descriptors, or runs of another dataset.
    """
    n = checks.check_int(n, "n (queries shown)", 1)
    for run in (run_a, run_b):
        checks.check_descriptors_kept(run, "plot_disagreements")
    check_runs_on(ds, (run_a, run_b), "plot_disagreements")
    full = per_query([run_a, run_b])
    shown, kind, wins, losses = _pick(full, run_a.label, run_b.label, n)
    table = full.set_index("query").loc[shown].reset_index()[full.columns]
    n_queries = full["query"].nunique()
    gt = np.asarray(ds.ground_truth, dtype=bool)
    frames = run_a.tolerance is not None and not getattr(run_a, "ground_truth_from_file", False)
    columns = [f"[{r.label}] query | its top-1 reference" for r in (run_a, run_b)]
    columns.append("[correct] reference")
    line = dataset_line([run_a])
    head = _heading(run_a.label, run_b.label, (wins, losses), n_queries, kind, line)
    fig, axes = _grid(ds, shown, head)
    for axrow, q in zip(axes, shown, strict=True):
        img_q = ds.load_image("query", q)
        rows = table[table["query"] == q]
        for ax, run, (_, row) in zip(axrow[:2], (run_a, run_b), rows.iterrows(), strict=True):
            _run_panel(ax, ds, run, row, img_q, frames)
        ref = ground_truth_references(gt, q)[0]
        axrow[2].imshow(ds.load_image("reference", ref))
        axrow[2].set_axis_off()
        name = Path(str(ds.query_paths[q])).name if len(ds.query_paths) > q else ""
        axrow[2].set_title(
            f"QUERY {q}: {kind[q]}\n{name}\ncorrect reference {ref}"
            if name
            else f"QUERY {q}: {kind[q]}\ncorrect reference {ref}",
            fontsize=FONT,
        )
    for ax, column in zip(axes[0], columns, strict=True):  # column headers over the first row
        ax.set_title(f"{column}\n{ax.get_title()}", fontsize=FONT, color=ax.title.get_color())
    fig.suptitle(
        head,
        fontsize=FONT,
        x=0.1 / FIG_WIDTH,
        y=1.0 - 0.08 / fig.get_figheight(),
        ha="left",
        va="top",
    )
    fig.table = table.rename(columns={"ratio": "ratio (lower = more confident)"})
    return fig


def _lines(n: int) -> float:
    """Height (inches) of ``n`` lines of :data:`FONT`-point text with their padding."""
    return n * FONT * 1.25 / 72 + 0.08


def _grid(ds: Any, shown: list[int], head: str) -> tuple[TableFigure, np.ndarray]:
    """A :data:`FIG_WIDTH` figure with a ``(rows, 3)`` array of axes placed by hand: each row's
    images (a pair of query and reference, the reference) at the height the narrowest of them
    allows, its 4-line titles above (5 in the first row, under the column headers) and
    ``head`` on top; no empty band (the images keep their aspect)."""
    h, w = ds.load_image("query", shown[0]).shape[:2]
    margin, gap = 0.1, 0.15
    usable = FIG_WIDTH - 2 * margin - 2 * gap
    widths = [usable * r / sum(_RATIOS) for r in _RATIOS]
    image_h = min(widths[0] * h / (2 * w + GAP), widths[2] * h / w)
    titles = [_lines(5 if k == 0 else 4) for k in range(len(shown))]
    top = _lines(head.count("\n") + 1) + 0.1
    height = top + sum(titles) + image_h * len(shown) + 0.1
    fig = cast(TableFigure, plt.figure(figsize=(FIG_WIDTH, height), FigureClass=TableFigure))
    axes = np.empty((len(shown), 3), dtype=object)
    y = height - top
    for k in range(len(shown)):
        y -= titles[k] + image_h
        x = margin
        for c, cw in enumerate(widths):
            axes[k, c] = fig.add_axes((x / FIG_WIDTH, y / height, cw / FIG_WIDTH, image_h / height))
            x += cw + gap
    return fig, axes


def _heading(
    a: str, b: str, counts: tuple[int, int], n_queries: int, kind: dict[int, str], line: str
) -> str:
    """What the figure shows, in the words of its rows; each line wrapped at the figure width."""
    wins, losses = counts
    shown = [sum(1 for k in kind.values() if k == what) for what in (f"{a} wins", f"{a} loses")]
    agree = len(kind) - sum(shown)
    parts = [f"{shown[0]} where {a} wins", f"{shown[1]} where it loses"]
    if agree:
        parts.append(f"{agree} where the runs agree (no more disagreements)")
    text = (
        f"{a} vs {b}: {wins + losses} of {n_queries} queries disagree (top-1 correct in one "
        f"run only): {a} wins {wins}, loses {losses}\n"
        f"{len(kind)} shown: {', '.join(parts)}; ratio S2/S1: lower = more confident\n{line}\n"
        f"boxes: the {TOP_TERMS} matches with the largest Eq. (1) terms (green correct, red "
        "wrong, yellow unlabelled)"
    )
    return wrapped(text, FIG_WIDTH - 0.2)
