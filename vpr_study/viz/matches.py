"""Landmark matches of two images (Fig. 1-3, 8), descriptor matrices and Eq. (1) pair terms."""

from __future__ import annotations

from typing import Any

import cv2
import matplotlib.pyplot as plt
import matplotlib.ticker
import numpy as np
from matplotlib.figure import Figure

from vpr_core import checks, pair_matches

from .base import draw_boxes

__all__ = [
    "GAP",
    "LINE_WIDTH",
    "plot_descriptor_matrices",
    "plot_labelled_matches",
    "plot_pair",
    "plot_pair_terms",
]

#: White pixels between the query and the reference of a match figure; width of its box lines.
GAP, LINE_WIDTH = 12, 1.2


def plot_labelled_matches(
    img_q: np.ndarray,
    img_r: np.ndarray,
    boxes_q: np.ndarray,
    boxes_r: np.ndarray,
    matches: np.ndarray,
    labels: np.ndarray | None,
    ax: Any = None,
    title: str | None = None,
) -> Figure:
    """Fig. 1-2: query (left) and reference side by side, :data:`GAP` white pixels apart, each match
    ``(P, 2)`` drawn as its two boxes joined by a line, coloured by its ``(P,)`` label (green
    correct, red incorrect; None: yellow); ``title`` defaults to the counts."""
    iq = np.asarray(img_q)
    ir = np.asarray(img_r)
    if iq.ndim == 2:
        iq = np.repeat(iq[..., None], 3, axis=2)
    if ir.ndim == 2:
        ir = np.repeat(ir[..., None], 3, axis=2)
    scale_r = 1.0
    if ir.shape[0] != iq.shape[0]:  # draw both at the query's height (boxes scaled along)
        scale_r = iq.shape[0] / ir.shape[0]
        ir = cv2.resize(
            np.ascontiguousarray(ir[..., :3]),
            (max(1, round(ir.shape[1] * scale_r)), iq.shape[0]),
            interpolation=cv2.INTER_AREA,
        )
    hh = iq.shape[0]
    canvas = np.full((hh, iq.shape[1] + GAP + ir.shape[1], 3), 255, dtype=np.uint8)
    canvas[:, : iq.shape[1]] = iq[..., :3]
    off = iq.shape[1] + GAP
    canvas[:, off:] = ir[..., :3]
    if ax is None:  # sized to the canvas: no empty margins beside the pictures
        width = 14.0
        height = width * hh / canvas.shape[1]
        fig, ax = plt.subplots(figsize=(width, height + 0.75))
        fig.subplots_adjust(left=0.005, right=0.995, bottom=0.005, top=height / (height + 0.75))
    else:
        fig = ax.figure
    ax.imshow(canvas)
    ax.set_axis_off()
    m = np.asarray(matches, dtype=np.int64).reshape(-1, 2)
    bq = checks.check_boxes(boxes_q, "boxes_q")
    br = checks.check_boxes(boxes_r, "boxes_r") * scale_r
    lab = None
    if labels is not None:
        lab = checks.check_per_match(np.asarray(labels, dtype=bool).reshape(-1), len(m), "labels")
    # incorrect first, correct on top
    order = np.arange(len(m)) if lab is None else np.argsort(lab, kind="stable")
    for k in order:
        i, j = m[k]
        color = "yellow" if lab is None else ("lime" if lab[k] else "red")
        a = bq[i]
        b = br[j] + np.array([off, 0.0, 0.0, 0.0])
        draw_boxes(ax, a[None], color=color, lw=LINE_WIDTH)
        draw_boxes(ax, b[None], color=color, lw=LINE_WIDTH)
        ax.plot(
            [a[0] + a[2] / 2, b[0] + b[2] / 2],
            [a[1] + a[3] / 2, b[1] + b[3] / 2],
            color=color,
            lw=LINE_WIDTH * 0.8,
            alpha=0.8,
        )
    if title is None:
        if lab is None:
            title = f"{len(m)} matches (unlabelled)"
        else:
            title = (
                f"{len(m)} matches: {int(lab.sum())} correct (green), "
                f"{int((~lab).sum())} incorrect (red)"
            )
    ax.set_title(title, fontsize=10)
    return fig


def plot_descriptor_matrices(descriptors: dict, title: str | None = None) -> Figure:
    """``{panel title: (K, D) descriptors}`` as heatmaps, one panel each (pipeline tour, step 2):
    rows landmarks, columns dimensions, colour the value (symmetric around 0, shared scale)."""
    if not descriptors:
        raise ValueError("plot_descriptor_matrices: descriptors is empty.")
    mats = {
        k: checks.check_shape(v, "K D", f"descriptors[{k!r}]", float)
        for k, v in descriptors.items()
    }
    vmax = max(float(np.abs(m).max()) if m.size else 0.0 for m in mats.values()) or 1.0
    fig, axes = plt.subplots(
        1, len(mats), figsize=(5.2 * len(mats), 3.6), squeeze=False, layout="constrained"
    )
    images = []
    for ax, (name, m) in zip(axes[0], mats.items(), strict=False):
        images.append(
            ax.imshow(
                m, aspect="auto", cmap="RdBu_r", vmin=-vmax, vmax=vmax, interpolation="nearest"
            )
        )
        ax.set_title(f"{name}: {m.shape[0]} x {m.shape[1]}", fontsize=9)
        ax.set_xlabel("descriptor dimension")
        ax.set_ylabel("landmark")
    fig.colorbar(images[-1], ax=list(axes[0]), fraction=0.03, pad=0.02, label="value")
    if title:
        fig.suptitle(title, fontsize=10)
    return fig


def plot_pair_terms(
    distances: np.ndarray,
    shape: np.ndarray,
    n_a: int,
    n_b: int,
    similarity: float,
    title: str | None = None,
) -> Figure:
    """Eq. (1) as a picture: every reciprocal pair's term ``1 - d*s`` and the image score
    (pipeline tour, step 4): (a) the terms of the ``(P,)`` distances and shape penalties in
    decreasing order, with ``S = sum(1 - d*s) / sqrt(n_a * n_b)``; (b) ``d`` against ``s``."""
    d = np.asarray(distances, dtype=float).reshape(-1)
    s = np.asarray(shape, dtype=float).reshape(-1)
    if d.shape != s.shape:
        raise ValueError(f"distances {d.shape} and shape {s.shape} must have one entry per pair")
    terms = 1.0 - d * s
    fig, (ax_a, ax_b) = plt.subplots(1, 2, figsize=(11.0, 3.6))
    order = np.argsort(-terms, kind="stable")
    ax_a.bar(np.arange(len(terms)), terms[order], width=0.85, color="tab:blue")
    ax_a.axhline(0.0, color="0.3", lw=0.8)
    ax_a.xaxis.set_major_locator(matplotlib.ticker.MaxNLocator(integer=True))
    ax_a.set_xlabel("reciprocal pair (sorted by its term)")
    ax_a.set_ylabel("1 - d * s")
    ax_a.set_title(
        f"(a) S = {terms.sum():.3f} / sqrt({n_a} x {n_b}) = {similarity:.4f}", fontsize=9
    )
    sc = ax_b.scatter(d, s, c=terms, cmap="viridis", s=14)
    fig.colorbar(sc, ax=ax_b, label="1 - d * s")
    ax_b.set_xlabel("cosine distance d")
    ax_b.set_ylabel("shape penalty s (Eq. 2)")
    ax_b.set_title(f"(b) {len(terms)} pairs", fontsize=9)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return fig


def plot_pair(dataset: Any, result: Any, query: int = 0, reference: int | None = None) -> Figure:
    """Fig. 1-3, 8: the matched landmarks of one pair of a run, coloured correct / incorrect.

    Labels from :func:`vpr_core.labels.pair_matches` (an unverifiable pair is drawn unlabelled
    and the title says why); ``reference`` None: the query's ground-truth reference.
    """
    pm = pair_matches(dataset, result, query, reference)
    fig = plot_labelled_matches(
        dataset.load_image("query", pm.query),
        dataset.load_image("reference", pm.reference),
        result.boxes["query"][pm.query],
        result.boxes["reference"][pm.reference],
        pm.matches,
        pm.labels,
    )
    note = f"\n(labels unavailable: {pm.note[:90]})" if pm.note else ""
    fig.suptitle(
        f"{result.label} on {dataset.name}: {pm.summary()}{note}", fontsize=11, y=0.995, va="top"
    )
    return fig
