"""(Not in the paper.) Which landmarks carried a top-1 that the contrast weighting changed
(notebook 07): query-crop / reference-crop pairs with cosine, weight and the other place each
also matches, beside the ones the weighting silenced."""

from __future__ import annotations

from typing import Any

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from vpr_core import carried_landmarks

from ._shared import FIG_WIDTH, FONT, check_runs_on, wrapped
from .curves import dataset_line

__all__ = ["CROP_PIXELS", "plot_carried_landmarks"]

#: Height (pixels) each landmark crop is resized to before it is drawn.
CROP_PIXELS = 64


def _crop(image: np.ndarray, box: np.ndarray) -> np.ndarray:
    """The pixels of an ``(x, y, w, h)`` box (at least one), resized to :data:`CROP_PIXELS`
    rows (nearest neighbour, aspect kept, width clipped to 0.25-2.5x the height)."""
    h, w = image.shape[:2]
    x0, y0 = int(np.clip(np.floor(box[0]), 0, w - 1)), int(np.clip(np.floor(box[1]), 0, h - 1))
    x1 = int(np.clip(np.ceil(box[0] + box[2]), x0 + 1, w))
    y1 = int(np.clip(np.ceil(box[1] + box[3]), y0 + 1, h))
    crop = image[y0:y1, x0:x1]
    out_w = int(np.clip(round(CROP_PIXELS * crop.shape[1] / crop.shape[0]), 16, 160))
    rows = np.minimum(
        (np.arange(CROP_PIXELS) + 0.5) * crop.shape[0] / CROP_PIXELS, crop.shape[0] - 1
    )
    cols = np.minimum((np.arange(out_w) + 0.5) * crop.shape[1] / out_w, crop.shape[1] - 1)
    return crop[rows.astype(int)][:, cols.astype(int)]


def _as_rgb(image: np.ndarray) -> np.ndarray:
    """Float RGB in [0, 1] of an image (grey, RGB or RGBA; uint8 or float)."""
    a = np.asarray(image)
    a = a.astype(np.float64) / 255.0 if a.dtype.kind in "ui" else a.astype(np.float64)
    if a.ndim == 2:
        a = np.repeat(a[:, :, None], 3, axis=2)
    return np.clip(a[:, :, :3], 0.0, 1.0)


def _side_by_side(a: np.ndarray, b: np.ndarray, grey: bool) -> np.ndarray:
    """Two images of equal height side by side with a white gap; ``grey``: desaturated and
    faded (a silenced landmark)."""
    a, b = _as_rgb(a), _as_rgb(b)
    h = max(a.shape[0], b.shape[0])
    pad = [np.pad(x, ((0, h - x.shape[0]), (0, 0), (0, 0)), constant_values=1.0) for x in (a, b)]
    gap = np.ones((h, max(2, h // 16), 3))
    out = np.concatenate([pad[0], gap, pad[1]], axis=1)
    if grey:
        lum = out @ np.array([0.299, 0.587, 0.114])
        out = np.repeat((0.35 + 0.5 * lum)[:, :, None], 3, axis=2)
    return out


def plot_carried_landmarks(
    ds: Any, plain: Any, weighted: Any, n_queries: int = 2, k: int = 5
) -> tuple[matplotlib.figure.Figure, pd.DataFrame]:
    """(Not in the paper) Why a database weighting changed a query's top-1, landmark by landmark.

    Draws the frame of :func:`vpr_core.carried_landmarks`: for each chosen query, the matches
    that carried the weighted run's top-1 pair, then those the weighting silenced in the plain
    run's top-1 pair (grey); each match is its query crop beside its reference crop, captioned
    with its cosine, its weight and the other reference where that query landmark matches best
    (``also rN``, with that cosine).

    Args:
        ds: the runs' dataset (its images); plain: a method's run without weighting;
            weighted: the same method with ``weighting=`` and ``keep_descriptors=True``.
        n_queries: queries shown; k: landmarks per row (1 to 10: what the figure's width fits).

    Returns:
        ``(figure, table)``: the frame, one row per landmark shown.

    Raises:
        ValueError: ``n_queries`` or ``k`` below 1 (``k`` above 10), ``plain`` with or
            ``weighted`` without a weighting, ``weighted`` without descriptors, runs of another
            dataset or that differ in more than the weighting (encoder, shortlist, protocol,
            method or matching).
    """
    check_runs_on(ds, (plain, weighted), "plot_carried_landmarks")
    table = carried_landmarks(plain, weighted, n_queries, k)
    weighting = weighted.config.matching.weighting
    gt = np.asarray(ds.ground_truth, dtype=bool)
    blocks = [
        (q, case, [(q, rw), (q, rp)], table[table["query"] == q].to_dict("records"))
        for q, case, rw, rp in table.attrs["queries"]
    ]
    n_changed = table.attrs["changed"]
    head = wrapped(
        f"(not in the paper) Which landmarks carried the score where the {weighting} weighting "
        f"changed the top-1 ({n_changed} of {int(gt.any(axis=1).sum())} queries; "
        f"{len(blocks)} shown): {plain.label} without and with it\n{dataset_line([plain])}\n"
        f"each pair: query crop | reference crop; cos = their cosine, w = the {weighting} "
        "weight, also rN (c) = the other reference where that query landmark matches best; "
        "grey = silenced (w = 0)",
        FIG_WIDTH - 0.2,
    )
    line = FONT * 1.25 / 72
    margin, ctx_w, gap = 0.1, 1.55, 0.2
    slot_w = (FIG_WIDTH - 2 * margin - ctx_w - gap) / k
    image_h = min(1.0, max(0.45, (slot_w - 0.12) / 2))
    row_h = line + 0.06 + image_h + 2 * line + 0.1  # its header, the crops, 2 caption lines
    top = (head.count("\n") + 1) * line + 0.2
    height = top + max(1, len(blocks)) * (line + 0.1 + 2 * row_h) + 0.1
    fig = plt.figure(figsize=(FIG_WIDTH, height))
    fig.suptitle(
        head, fontsize=FONT, x=margin / FIG_WIDTH, y=1 - 0.08 / height, ha="left", va="top"
    )
    y = height - top

    def text(x: float, y_: float, s: str, **kw) -> None:
        fig.text(x / FIG_WIDTH, y_ / height, s, fontsize=FONT, **kw)

    if not blocks:
        text(margin, y - line, f"the {weighting} weighting changed no query's top-1 here", va="top")
    for q, case, pairs, rows in blocks:
        y -= line + 0.1
        (_, rw), (_, rp) = pairs
        text(
            margin,
            y,
            f"query {q}: {case} by the weighting (top-1 r{rp} "
            f"{'correct' if gt[q, rp] else 'wrong'} -> r{rw} "
            f"{'correct' if gt[q, rw] else 'wrong'})",
            va="bottom",
            fontweight="bold",
        )
        img_q = ds.load_image("query", q)
        for role, (_, r) in zip(("carried", "silenced"), pairs, strict=True):
            shown = [row for row in rows if row["role"] == role]
            s_p, s_w = float(plain.similarity[q, r]), float(weighted.similarity[q, r])
            what = (
                f"carried the weighted score of r{r} (the weighted top-1): its {k} largest "
                "weighted terms"
                if role == "carried"
                else f"silenced in r{r} (the plain top-1): its largest plain terms with w = 0"
            )
            y -= line + 0.06
            text(margin, y, f"{what}; S {s_p:.3f} plain, {s_w:.3f} weighted", va="bottom")
            y -= image_h
            img_r = ds.load_image("reference", r)
            ax = fig.add_axes((margin / FIG_WIDTH, y / height, ctx_w / FIG_WIDTH, image_h / height))
            ax.imshow(_side_by_side(img_q, img_r, grey=False))
            ax.set_axis_off()
            mark = "correct" if gt[q, r] else "wrong"
            text(margin + ctx_w / 2, y - 0.03, f"query {q} | r{r}\n({mark})", ha="center", va="top")
            if not shown:
                sw = [float(x.similarity[q, rw]) for x in (plain, weighted)]
                none = (
                    f"none: every match kept a weight > 0; the weighting lifted r{rw} more\n"
                    f"(S {sw[0]:.3f} -> {sw[1]:.3f}) than r{r} (S {s_p:.3f} -> {s_w:.3f})"
                    if role == "silenced"
                    else "none: no match with a weighted term > 0"
                )
                text(margin + ctx_w + gap, y + image_h / 2, none, va="center")
            for s, row in enumerate(shown):
                x = margin + ctx_w + gap + s * slot_w
                ax = fig.add_axes(
                    (x / FIG_WIDTH, y / height, (slot_w - 0.12) / FIG_WIDTH, image_h / height)
                )
                bq = weighted.boxes["query"][q][row["query landmark"]]
                br = weighted.boxes["reference"][r][row["reference landmark"]]
                pair = _side_by_side(_crop(img_q, bq), _crop(img_r, br), grey=role == "silenced")
                ax.imshow(pair)
                ax.set_axis_off()
                also = (
                    f"also r{row['also matches']} ({row['its cosine']:.2f})"
                    if row["also matches"] >= 0
                    else "no other reference"
                )
                text(
                    x + (slot_w - 0.12) / 2,
                    y - 0.03,
                    f"cos {row['cosine']:.2f}, w {row['weight']:.2f}\n{also}",
                    ha="center",
                    va="top",
                    color="0.35" if role == "silenced" else "black",
                )
            y -= 2 * line + 0.1
    return fig, table
