"""(Not in the paper.) Which landmarks carried a top-1 that the contrast weighting changed
(notebook 07): query-crop / reference-crop pairs with cosine, weight and the other place each
also matches, beside the ones the weighting silenced."""

from __future__ import annotations

from typing import Any

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from vpr_core import checks, step_between
from vpr_core.evaluation import best_two as _best_two
from vpr_core.evaluation import ranked as _ranked
from vpr_core.matching import cosine_similarity

from ._shared import FIG_WIDTH, FONT, check_runs_on, run_matches, weighting_of, wrapped
from .curves import dataset_line

__all__ = ["CARRIED_COLUMNS", "CROP_PIXELS", "SILENT_WEIGHT", "plot_carried_landmarks"]

# ---- (not in the paper) notebook 07: the landmarks that carried a changed top-1 -------------
#: A database weight at or below this counts as silenced: the weighting took the term out.
SILENT_WEIGHT = 1e-6

#: The columns of :func:`plot_carried_landmarks`' table, in order.
CARRIED_COLUMNS = (
    "query",
    "case",
    "role",
    "reference",
    "reference correct",
    "rank",
    "query landmark",
    "reference landmark",
    "cosine",
    "weight",
    "plain term",
    "weighted term",
    "also matches",
    "its cosine",
    "also matches correct",
)

#: Height (pixels) each landmark crop is resized to before it is drawn.
CROP_PIXELS = 64


def _top1(run: Any) -> np.ndarray:
    """``(Nq,)`` each query's top-1 reference (ties: lowest index; -1: nothing ranked), as the
    metrics pick it."""
    s = np.asarray(run.similarity, dtype=np.float64)
    out = np.full(s.shape[0], -1, dtype=np.int64)
    ranked = _ranked(s)
    if ranked.any():
        out[ranked] = _best_two(s[ranked])[0]
    return out


def _changed_queries(plain: Any, weighted: Any, gt: np.ndarray, n: int) -> list[tuple[int, str]]:
    """Up to ``n`` ``(query, case)`` whose top-1 the weighting changed: the first query it
    fixed, then the first it broke (if any), then the other fixed, broken and changed ones, in
    query order."""
    tp, tw = _top1(plain), _top1(weighted)
    rows = np.arange(len(tp))
    has = gt.any(axis=1) & (tp >= 0) & (tw >= 0) & (tp != tw)
    ok_p = gt[rows, np.maximum(tp, 0)]
    ok_w = gt[rows, np.maximum(tw, 0)]
    fixed = [int(q) for q in np.flatnonzero(has & ~ok_p & ok_w)]
    broken = [int(q) for q in np.flatnonzero(has & ok_p & ~ok_w)]
    other = [int(q) for q in np.flatnonzero(has & ~ok_p & ~ok_w)]
    order = [*fixed[:1], *broken[:1], *fixed[1:], *broken[1:], *other]
    case = {q: "fixed" for q in fixed} | {q: "broken" for q in broken}
    case |= {q: "changed, both wrong" for q in other}
    return [(q, case[q]) for q in order[:n]]


def _also_matches(run: Any, q: int, landmarks: np.ndarray, shown: int) -> tuple:
    """For query ``q``'s ``landmarks``: the reference other than ``shown`` where each has its
    best cosine ``b_i(r)`` (``(k,)`` indices) and that cosine (``(k,)``)."""
    refs = run.descriptors["reference"]
    counts = np.array([len(d) for d in refs])
    k = len(landmarks)
    if not k or counts.sum() == 0:
        return np.full(k, -1), np.full(k, np.nan)
    cos = cosine_similarity(
        np.asarray(run.descriptors["query"][q])[landmarks],
        np.concatenate([np.asarray(d).reshape(len(d), -1) for d in refs if len(d)]),
    )
    best = np.full((k, len(refs)), -np.inf)
    starts = np.concatenate([[0], np.cumsum(counts[counts > 0])[:-1]])
    best[:, counts > 0] = np.maximum.reduceat(cos, starts, axis=1)
    best[:, shown] = -np.inf
    other = np.argmax(best, axis=1)
    value = best[np.arange(k), other]
    return np.where(np.isfinite(value), other, -1), np.where(np.isfinite(value), value, np.nan)


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


def _check_carried_runs(ds: Any, plain: Any, weighted: Any) -> str:
    """The weighting of ``weighted``; refuses runs the figure cannot explain."""
    weighting = weighting_of(weighted)
    m_p = getattr(getattr(plain, "config", None), "matching", None)
    if m_p is None or m_p.weighting:
        raise ValueError(
            f"`plain` must be the paper's Eq. (1) (no weighting), got "
            f"{getattr(plain, 'label', plain)!r}: run the same method without weighting"
        )
    checks.check_descriptors_kept(weighted, "plot_carried_landmarks")
    check_runs_on(ds, (plain, weighted), "plot_carried_landmarks")
    step = step_between(plain, weighted, "plot_carried_landmarks", "the weighting")
    if set(step) != {"weighting"}:  # a normalisation too: not what the figure explains
        raise ValueError(
            f"plot_carried_landmarks: {plain.label!r} and {weighted.label!r} differ in more "
            "than the weighting (normalise): pass one method run without and with weighting= "
            "alone"
        )
    return weighting


def _carried_rows(
    run: Any, gt: np.ndarray, q: int, case: str, pairs: list, ms: list, k: int
) -> list[dict]:
    """The table rows of one query: the ``k`` largest weighted terms of the weighted top-1
    pair (``carried``), the ``k`` largest plain terms with weight about 0 of the plain top-1
    pair (``silenced``)."""
    rows = []
    for role, (_, r), m in zip(("carried", "silenced"), pairs, ms, strict=True):
        plain_term = m.raw_scores * m.spatial_weights
        if role == "carried":
            keep = np.flatnonzero(m.scores > 0)
            keep = keep[np.argsort(-m.scores[keep], kind="stable")][:k]
        else:
            keep = np.flatnonzero(m.weights <= SILENT_WEIGHT)
            keep = keep[np.argsort(-plain_term[keep], kind="stable")][:k]
        also, also_cos = _also_matches(run, q, m.matches[keep, 0], r)
        for rank, (idx, o, oc) in enumerate(zip(keep, also, also_cos, strict=True), start=1):
            i, j = (int(v) for v in m.matches[idx])
            rows.append(
                {
                    "query": q,
                    "case": case,
                    "role": role,
                    "reference": r,
                    "reference correct": bool(gt[q, r]),
                    "rank": rank,
                    "query landmark": i,
                    "reference landmark": j,
                    "cosine": 1.0 - float(m.distances[idx]),
                    "weight": float(m.weights[idx]),
                    "plain term": float(plain_term[idx]),
                    "weighted term": float(m.scores[idx]),
                    "also matches": int(o),
                    "its cosine": float(oc),
                    "also matches correct": bool(o >= 0 and gt[q, o]),
                }
            )
    return rows


def plot_carried_landmarks(
    ds: Any, plain: Any, weighted: Any, n_queries: int = 2, k: int = 5
) -> tuple[matplotlib.figure.Figure, pd.DataFrame]:
    """(Not in the paper) Why a database weighting changed a query's top-1, landmark by landmark.

    For up to ``n_queries`` queries whose top-1 the weighting changed (the first it fixed, then
    the first it broke, if any, then others, in query order), two rows: the ``k`` reciprocal
    matches with the largest weighted Eq. (1) terms in the weighted run's top-1 pair (what
    carried its score), then the ``k`` with the largest plain terms in the plain run's top-1
    pair whose weight is about 0 (at most :data:`SILENT_WEIGHT`: what the weighting silenced,
    drawn grey). Each match is its query crop beside its reference crop, captioned with its
    cosine, its weight and the other reference where that query landmark matches best
    (``also rN``, with that cosine). The weights are those the weighted run used
    (:func:`~vpr_core.matching.weighted_matches`).

    Args:
        ds: the runs' dataset (its images); plain: a method's run without weighting;
            weighted: the same method with ``weighting=`` and ``keep_descriptors=True``.
        n_queries: queries shown; k: landmarks per row (1 to 10: what the figure's width fits).

    Returns:
        ``(figure, table)``: one row per landmark shown (:data:`CARRIED_COLUMNS`).

    Raises:
        ValueError: ``n_queries`` or ``k`` below 1 (``k`` above 10), ``plain`` with or
            ``weighted`` without a weighting, ``weighted`` without descriptors, runs of another
            dataset or that differ in more than the weighting (encoder, shortlist, protocol,
            method or matching).
    """
    n_queries = checks.check_int(n_queries, "n_queries", 1)
    k = int(
        checks.check_range(checks.check_int(k, "k", 1), "k (landmarks a figure row fits)", 1, 10)
    )
    weighting = _check_carried_runs(ds, plain, weighted)
    gt = np.asarray(ds.ground_truth, dtype=bool)
    chosen = _changed_queries(plain, weighted, gt, n_queries)
    tp, tw = _top1(plain), _top1(weighted)
    blocks = []
    for q, case in chosen:
        pairs = [(q, int(tw[q])), (q, int(tp[q]))]
        ms = run_matches(weighted, pairs, weighting)
        blocks.append((q, case, pairs, ms, _carried_rows(weighted, gt, q, case, pairs, ms, k)))
    table = pd.DataFrame([r for b in blocks for r in b[4]], columns=list(CARRIED_COLUMNS))

    n_changed = int(np.count_nonzero(gt.any(axis=1) & (tp != tw) & (tp >= 0) & (tw >= 0)))
    head = wrapped(
        f"(not in the paper) Which landmarks carried the score where the {weighting} weighting "
        f"changed the top-1 ({n_changed} of {int(gt.any(axis=1).sum())} queries; "
        f"{len(chosen)} shown): {plain.label} without and with it\n{dataset_line([plain])}\n"
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
    for q, case, pairs, _ms, rows in blocks:
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
