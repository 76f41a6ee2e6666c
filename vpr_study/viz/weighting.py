"""(Not in the paper) Which landmarks carry a weighted score: queries the plain Eq. (1) gets wrong
and a database weighting gets right, each match drawn in the colour of its weight
(:func:`plot_weighted_matches`); the landmarks that carried a changed top-1: :mod:`.carried`."""

from __future__ import annotations

from typing import Any

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from vpr_core import checks
from vpr_core.datasets import ground_truth_references
from vpr_study.insight import per_query

from ._shared import FIG_WIDTH, FONT, check_runs_on, run_matches, weighting_of, wrapped
from .curves import dataset_line

__all__ = ["plot_weighted_matches"]


def _pair_panel(ax, images: tuple, boxes: tuple, match, colour, title: str) -> None:
    """Query and reference ``images`` side by side, each reciprocal match's ``boxes`` in its
    weight's ``colour(w)`` (zero weights thin and grey)."""
    (img_q, img_r), (bq, br) = images, boxes
    h = max(img_q.shape[0], img_r.shape[0])
    pad = [np.pad(im, ((0, h - im.shape[0]), (0, 0), (0, 0))) for im in (img_q, img_r)]
    ax.imshow(np.concatenate(pad, axis=1))
    off = img_q.shape[1]
    order = np.argsort(match.weights)  # the heaviest drawn last, on top
    for k in order:
        i, j = match.matches[k]
        w = match.weights[k]
        color = colour(w) if w > 0 else (0.6, 0.6, 0.6, 0.7)
        lw = 1.6 if w > 0 else 0.5
        for (x, y, bw, bh), dx in ((bq[i], 0), (br[j], off)):
            ax.add_patch(
                matplotlib.patches.Rectangle((x + dx, y), bw, bh, fill=False, ec=color, lw=lw)
            )
    ax.set_axis_off()
    ax.set_title(title, fontsize=FONT)


def _grid(ds: Any, shown: list[int], head: str):
    """``(figure, (rows, 2) axes, colour-bar axes)`` of :data:`FIG_WIDTH`, placed by hand:
    each row's two pairs of images at the height their width allows, a 3-line title above
    each, ``head`` on top, the colour bar at the right."""
    h, w = ds.load_image("query", shown[0]).shape[:2] if shown else (1, 2)
    margin, gap, bar_w = 0.1, 0.25, 0.9  # the colour bar, its ticks and label
    pair_w = (FIG_WIDTH - 2 * margin - gap - bar_w) / 2
    image_h = pair_w * h / (2 * w)
    title = 3 * FONT * 1.25 / 72 + 0.1
    top = (head.count("\n") + 1) * FONT * 1.25 / 72 + 0.2
    rows = max(1, len(shown))
    height = top + rows * (title + image_h) + 0.1
    fig = plt.figure(figsize=(FIG_WIDTH, height))
    axes = np.empty((rows, 2), dtype=object)
    y = height - top
    for k in range(rows):
        y -= title + image_h
        for c in range(2):
            x = margin + c * (pair_w + gap)
            axes[k, c] = fig.add_axes(
                (x / FIG_WIDTH, y / height, pair_w / FIG_WIDTH, image_h / height)
            )
    x = margin + 2 * pair_w + gap + 0.15
    body = height - top - 0.1 - title
    bar = fig.add_axes((x / FIG_WIDTH, 0.1 / height, 0.15 / FIG_WIDTH, body / height))
    return fig, axes, bar


def plot_weighted_matches(
    ds: Any, plain: Any, weighted: Any, n: int = 3
) -> tuple[matplotlib.figure.Figure, pd.DataFrame]:
    """Queries where ``plain`` (the paper's Eq. (1)) fails and ``weighted`` (the same method with
    ``weighting=...``) succeeds: per query, its matches with the correct reference and with the
    plain run's wrong top-1, each box coloured by its weight (grey: weight 0).

    Args:
        ds: the runs' dataset; plain, weighted: results of ``ds`` with ``keep_descriptors=True``,
            the second with a ``weighting`` (its statistics are recomputed as it matched).
        n: queries shown (rows), in query order.

    Returns:
        ``(figure, table)``: :func:`~vpr_core.evaluation.per_query` rows of the queries shown.

    Raises:
        ValueError: ``n < 1``, no weighting on ``weighted``, runs without descriptors or runs
            of another dataset.
    """
    n = checks.check_int(n, "n (queries shown)", 1)
    weighting = weighting_of(weighted)
    checks.check_descriptors_kept(weighted, "plot_weighted_matches")
    check_runs_on(ds, (plain, weighted), "plot_weighted_matches")
    table = per_query([plain, weighted])
    ok = table.pivot(index="query", columns="run", values="top-1 correct")
    fixed = ok.index[~ok[plain.label].astype(bool) & ok[weighted.label].astype(bool)]
    shown = [int(q) for q in fixed[:n]]
    table = table[table["query"].isin(shown)].reset_index(drop=True)
    gt = np.asarray(ds.ground_truth, dtype=bool)
    head = (
        f"(not in the paper) {plain.label} wrong, {weighted.label} right: {len(fixed)} of "
        f"{len(ok)} queries{f' ({len(shown)} shown)' if len(fixed) > len(shown) else ''}\n"
        f"{dataset_line([plain])}\nboxes: each reciprocal match coloured by its {weighting} "
        "weight, grey = 0"
    )
    head = wrapped(head, FIG_WIDTH - 0.2)
    fig, axes, bar = _grid(ds, shown, head)
    if not shown:
        for ax in axes[0]:
            ax.set_axis_off()
        bar.set_axis_off()
        fig.suptitle(head, fontsize=FONT, x=0.01, y=0.98, ha="left", va="top")
        return fig, table
    sim_p = np.asarray(plain.similarity)
    sim_w = np.asarray(weighted.similarity)
    pairs = []
    for q in shown:
        wrong = int(np.nanargmax(np.where(np.isnan(sim_p[q]), -np.inf, sim_p[q])))
        pairs += [(q, ground_truth_references(gt, q)[0]), (q, wrong)]
    ms = run_matches(weighted, pairs, weighting)
    top = max([float(m.weights.max()) for m in ms if len(m.weights)] + [1e-9])
    norm = matplotlib.colors.Normalize(0.0, top)
    cmap = plt.get_cmap("viridis")
    b = weighted.boxes
    for k, q in enumerate(shown):
        img_q = ds.load_image("query", q)
        for c, ((_, r), m) in enumerate(
            zip(pairs[2 * k : 2 * k + 2], ms[2 * k : 2 * k + 2], strict=True)
        ):
            what = "correct reference" if c == 0 else f"{plain.label}'s wrong top-1"
            carried = np.count_nonzero(m.weights > 0)
            _pair_panel(
                axes[k, c],
                (img_q, ds.load_image("reference", r)),
                (b["query"][q], b["reference"][r]),
                m,
                lambda w: cmap(norm(w)),
                f"query {q} vs {what} r{r}\nS {sim_p[q, r]:.3f} plain, {sim_w[q, r]:.3f} "
                f"weighted\n{len(m.matches)} matches, {carried} with weight > 0",
            )
    fig.suptitle(
        head,
        fontsize=FONT,
        x=0.1 / FIG_WIDTH,
        y=1 - 0.08 / fig.get_figheight(),
        ha="left",
        va="top",
    )
    fig.colorbar(
        matplotlib.cm.ScalarMappable(norm=norm, cmap=cmap), cax=bar, label=f"{weighting} weight"
    )
    bar.yaxis.label.set_fontsize(FONT)
    bar.tick_params(labelsize=FONT)
    return fig, table
