"""(Not in the paper.) What whitening the landmark descriptors on the reference database does
(notebook 07): which share of a match's cosine the database's shared components carry before and
after, and the references whose rank it changed for chosen queries."""

from __future__ import annotations

import dataclasses
from typing import Any

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.ticker import MaxNLocator

from vpr_core import checks
from vpr_core.matching import fit_whitening, match_landmarks

from ..changes import changed_queries
from ._shared import FIG_WIDTH, FONT, check_runs_on, wrapped
from .curves import dataset_line

__all__ = ["WHITENING_COLUMNS", "plot_whitening"]

#: The columns of :func:`plot_whitening`'s table, in order.
WHITENING_COLUMNS = (
    "query",
    "case",
    "reference",
    "correct",
    "rank before",
    "rank after",
    "score before",
    "score after",
    "matches before",
    "matches after",
    "shared share",
    "why",
)


def _unit(x: np.ndarray) -> np.ndarray:
    x = np.asarray(x, dtype=np.float64)
    n = np.linalg.norm(x, axis=1, keepdims=True)
    return np.divide(x, n, out=np.zeros_like(x), where=n > 0)


def _ranks(row: np.ndarray) -> np.ndarray:
    """1-based rank of each reference (best first, ties by lowest index, NaN last)."""
    order = np.argsort(-np.where(np.isnan(row), -np.inf, row), kind="stable")
    out = np.empty(row.shape[0], dtype=np.int64)
    out[order] = np.arange(1, row.shape[0] + 1)
    return out


def _check_whitening_runs(ds: Any, plain: Any, whitened: Any) -> int:
    """``whitened``'s components asked for; refuses runs the figure cannot explain."""
    m_p = getattr(getattr(plain, "config", None), "matching", None)
    m_w = getattr(getattr(whitened, "config", None), "matching", None)
    if m_w is None or m_w.whiten is None:
        raise ValueError(
            f"{getattr(whitened, 'label', whitened)!r} is not whitened: pass the run of "
            "run_method(..., whiten=256, keep_descriptors=True) as `whitened`"
        )
    if m_p is None or m_p.whiten is not None:
        raise ValueError(
            f"`plain` must be the same method without whitening, got "
            f"{getattr(plain, 'label', plain)!r}"
        )
    for run in (plain, whitened):
        checks.check_descriptors_kept(run, "plot_whitening")
    check_runs_on(ds, (plain, whitened), "plot_whitening")
    differ = [
        k for k in ("method", "encoder", "shortlist") if getattr(plain, k) != getattr(whitened, k)
    ]
    if dataclasses.replace(m_w, whiten=None) != m_p or differ:
        raise ValueError(
            f"{plain.label!r} and {whitened.label!r} differ in more than the whitening: pass one "
            "method run without and with whiten= (same encoder, shortlist and matching otherwise)"
        )
    return int(m_w.whiten)


def _groups(kept: int, shared: int) -> list[tuple[str, int, int]]:
    """``(name, first, end)`` component groups: the ``shared`` largest, the next to 50, the rest
    kept (empty groups left out)."""
    edges = sorted({0, min(shared, kept), min(max(50, shared), kept), kept})
    return [
        (f"{a + 1}-{b}" if b > a + 1 else f"{b}", a, b)
        for a, b in zip(edges[:-1], edges[1:], strict=True)
    ]


def _contributions(u: np.ndarray, v: np.ndarray, fit: Any, groups: list) -> tuple:
    """Summed over matched pairs ``(u_p, v_p)`` (unit plain descriptors): each part of the plain
    cosine (the database mean, each component group, beyond the kept ones) and of the whitened
    cosine (each group), as ``(before (G + 2,), after (G + 2,), plain cosines (P,))``."""
    lam = fit.eigenvalues
    basis = fit.projection * np.sqrt(lam)[None, :]  # (D, k') unit eigenvectors
    uc, vc = u - fit.mean, v - fit.mean
    a, b = uc @ basis, vc @ basis  # (P, k')
    cos = np.einsum("pd,pd->p", u, v)
    centred = np.einsum("pd,pd->p", uc, vc)
    norm = np.linalg.norm(a / np.sqrt(lam), axis=1) * np.linalg.norm(b / np.sqrt(lam), axis=1)
    norm = np.where(norm > 0, norm, np.inf)
    before = [float((cos - centred).sum())]
    after = [0.0]
    for _, lo, hi in groups:
        prod = a[:, lo:hi] * b[:, lo:hi]
        before.append(float(prod.sum()))
        after.append(float(((prod / lam[lo:hi]).sum(1) / norm).sum()))
    before.append(float((centred - (a * b).sum(1)).sum()))
    after.append(0.0)
    return np.array(before), np.array(after), cos


def plot_whitening(
    ds: Any, plain: Any, whitened: Any, n_queries: int = 2, shared: int = 10
) -> tuple[matplotlib.figure.Figure, pd.DataFrame]:
    """(Not in the paper) What whitening on the reference database did (docs/DEFINITIONS.md).

    Left, (a): the share of the plain cosine of the shown pairs' reciprocal matches (the plain
    run's) carried by the database mean, by its ``shared`` largest principal components, by the
    next ones to 50, by the rest kept and by the components beyond (dropped), and the same
    matches' whitened cosine by the same groups: what many places share loses its weight. Then
    one panel per chosen query (:func:`~vpr_study.changes.changed_queries`: the first whose
    top-1 whitening fixed, then one it broke, if any): the rank of each shown reference (its
    top-1 before and after, and its best-ranked correct reference) before and after whitening,
    green for a correct reference, red for a wrong one, each labelled with the share of its
    plain match cosine that the mean and the ``shared`` largest components carried.

    Args:
        ds: the runs' dataset; plain: a method's run without whitening and ``whitened`` the same
            with ``whiten=k``, both with ``keep_descriptors=True``.
        n_queries: queries shown (1 to 3); shared: the components called shared (1 to 50).

    Returns:
        ``(figure, table)``: one row per query and reference shown (:data:`WHITENING_COLUMNS`);
        ``shared share`` is the share of the pair's plain match cosine carried by the mean and
        the ``shared`` largest components, ``why`` says it in words.

    Raises:
        ValueError: bad ``n_queries`` / ``shared``; runs without descriptors, of another
            dataset, ``plain`` whitened or ``whitened`` not, or runs differing in more.
    """
    n_queries = int(
        checks.check_range(checks.check_int(n_queries, "n_queries", 1), "n_queries", 1, 3)
    )
    shared = int(checks.check_range(checks.check_int(shared, "shared", 1), "shared", 1, 50))
    k = _check_whitening_runs(ds, plain, whitened)
    dp, dw, boxes = plain.descriptors, whitened.descriptors, plain.boxes
    fit = fit_whitening(dp["reference"], k)  # the run's own fit, from memory
    groups = _groups(fit.kept, shared)
    gt = np.asarray(ds.ground_truth, dtype=bool)
    sp, sw = np.asarray(plain.similarity, float), np.asarray(whitened.similarity, float)
    chosen = changed_queries(plain, whitened, n_queries)
    total_b, total_a, total_cos = np.zeros(len(groups) + 2), np.zeros(len(groups) + 2), 0.0
    rows, panels = [], []
    for q, case in chosen:
        rp, rw = _ranks(sp[q]), _ranks(sw[q])
        refs = [int(np.argmin(rp)), int(np.argmin(rw))]
        if gt[q].any():
            refs.append(int(np.flatnonzero(gt[q])[np.argmin(rw[gt[q]])]))
        refs = list(dict.fromkeys(refs))
        points = []
        for r in refs:
            m_b = match_landmarks(
                dp["query"][q], boxes["query"][q], dp["reference"][r], boxes["reference"][r]
            )
            m_a = match_landmarks(
                dw["query"][q], boxes["query"][q], dw["reference"][r], boxes["reference"][r]
            )
            i, j = m_b.matches[:, 0], m_b.matches[:, 1]
            u = _unit(np.asarray(dp["query"][q])[i])
            v = _unit(np.asarray(dp["reference"][r])[j])
            before, after, cos = _contributions(u, v, fit, groups)
            total_b, total_a, total_cos = total_b + before, total_a + after, total_cos + cos.sum()
            share = (before[0] + before[1]) / cos.sum() if cos.sum() > 0 else np.nan
            rows.append(
                {
                    "query": q,
                    "case": case,
                    "reference": r,
                    "correct": bool(gt[q, r]),
                    "rank before": int(rp[r]),
                    "rank after": int(rw[r]),
                    "score before": float(sp[q, r]),
                    "score after": float(sw[q, r]),
                    "matches before": len(m_b.matches),
                    "matches after": len(m_a.matches),
                    "shared share": float(share),
                    "why": (
                        f"rank {rp[r]} -> {rw[r]}; {share:.0%} of its plain match cosine is the "
                        f"database mean and its {shared} largest components, which whitening "
                        f"removes or scales down; reciprocal matches {len(m_b.matches)} -> "
                        f"{len(m_a.matches)}"
                    ),
                }
            )
            points.append((r, bool(gt[q, r]), int(rp[r]), int(rw[r]), float(share)))
        panels.append((q, case, points))
    table = pd.DataFrame(rows, columns=list(WHITENING_COLUMNS))

    top1 = [np.argmax(np.where(np.isnan(s), -np.inf, s), 1) for s in (sp, sw)]
    n_changed = int(np.count_nonzero(gt.any(1) & (top1[0] != top1[1])))
    head = wrapped(
        f"(not in the paper) What whitening the landmark descriptors on the reference database "
        f"({fit.kept} components, fitted on {fit.landmarks} reference landmarks) does: "
        f"{plain.label} without and with it; top-1 changed for {n_changed} of "
        f"{int(gt.any(1).sum())} queries\n{dataset_line([plain])}\n(a) the plain cosine of the "
        "shown pairs' reciprocal matches (grey) and the same matches' whitened cosine (blue), "
        "by what carries them: the mean of every reference landmark and the database's "
        "principal components, largest first; then each shown reference's rank before and after "
        f"(green: correct, red: wrong); shared = the share of the pair's plain match cosine "
        f"carried by the mean and the {shared} largest components",
        FIG_WIDTH - 0.2,
    )
    line = FONT * 1.25 / 72
    top = (head.count("\n") + 2) * line + 0.35
    panel_h = 2.6
    height = top + panel_h + 1.0
    fig = plt.figure(figsize=(FIG_WIDTH, height))
    fig.suptitle(head, fontsize=FONT, x=0.1 / FIG_WIDTH, y=1 - 0.08 / height, ha="left", va="top")
    n_p = 1 + len(panels)
    grid = fig.add_gridspec(
        1,
        n_p,
        left=0.07,
        right=0.99,
        bottom=0.9 / height,
        top=1 - top / height,
        wspace=0.35,
        width_ratios=[1.3] + [1.0] * len(panels),
    )
    ax = fig.add_subplot(grid[0, 0])
    names = ["database mean", *(f"comp. {g[0]}" for g in groups), f"beyond {fit.kept}"]
    denom = total_cos if total_cos > 0 else np.nan
    after_sum = total_a.sum() if total_a.sum() > 0 else np.nan
    pos = np.arange(len(names))
    ax.bar(pos - 0.2, total_b / denom, 0.4, color="0.55", label="plain cosine")
    ax.bar(pos + 0.2, total_a / after_sum, 0.4, color="tab:blue", label="whitened cosine")
    ax.axhline(0, color="k", lw=0.6)
    ax.set_xticks(pos, names, rotation=35, ha="right", fontsize=FONT - 1)
    ax.set_ylabel("share of the matches' cosine", fontsize=FONT)
    ax.set_title(wrapped("(a) what carries a match's cosine", 3.0), fontsize=FONT)
    ax.legend(fontsize=FONT - 1, frameon=False)
    ax.tick_params(labelsize=FONT - 1)
    for c, (q, case, points) in enumerate(panels, start=1):
        ax = fig.add_subplot(grid[0, c])
        for r, ok, r_b, r_a, share in points:
            colour = "tab:green" if ok else "tab:red"
            ax.plot([0, 1], [r_b, r_a], color=colour, marker="o", lw=2 if ok else 1.2)
            ax.annotate(
                f"r{r}{' correct' if ok else ''}\nshared {share:.0%}",
                (1, r_a),
                xytext=(6, 0),
                textcoords="offset points",
                va="center",
                fontsize=FONT,
                color=colour,
            )
        worst = max(max(p[2], p[3]) for p in points)
        if worst > 10:
            ax.set_yscale("log")
        else:
            ax.yaxis.set_major_locator(MaxNLocator(integer=True))
        ax.set_ylim(worst * (1.6 if worst > 10 else 1) + 0.5, 0.6)
        ax.set_xlim(-0.15, 2.1)
        ax.set_xticks([0, 1], ["plain", "whitened"], fontsize=FONT - 1)
        ax.set_ylabel("rank of the reference" if c == 1 else "", fontsize=FONT)
        ax.set_title(f"({chr(97 + c)}) query {q}: {case}", fontsize=FONT)
        ax.tick_params(labelsize=FONT - 1)
        ax.spines[["top", "right"]].set_visible(False)
    return fig, table
