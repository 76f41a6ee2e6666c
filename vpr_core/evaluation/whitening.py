"""(Not in the paper.) What whitening the landmark descriptors on the reference database changed
(docs/DEFINITIONS.md, whitening): which share of a match's cosine the database's shared
components carry before and after, and the references whose rank it moved for chosen queries
(:func:`whitening_changes`); ``vpr_study.viz.plot_whitening`` draws its frame."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pandas as pd

from .. import checks
from ..matching.similarity import match_landmarks
from ..matching.whiten import Whitening, _unit, fit_whitening
from ..methods import step_between
from .steps import _ranks, _top1, changed_queries

__all__ = ["WHITENING_COLUMNS", "whitening_changes"]

#: The columns of :func:`whitening_changes`, in order.
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


def _check_whitening_runs(plain: Any, whitened: Any) -> int:
    """``whitened``'s components asked for; refuses runs the frame cannot explain."""
    m_w = getattr(getattr(whitened, "config", None), "matching", None)
    if m_w is None or m_w.whiten is None:
        raise ValueError(
            f"{getattr(whitened, 'label', whitened)!r} is not whitened: pass the run of "
            "run_method(..., whiten=256, keep_descriptors=True) as `whitened`"
        )
    m_p = getattr(getattr(plain, "config", None), "matching", None)
    if m_p is None or m_p.whiten is not None:
        raise ValueError(
            f"`plain` must be the same method without whitening, got "
            f"{getattr(plain, 'label', plain)!r}"
        )
    if dataclasses.replace(m_w, whiten=None) != m_p:
        raise ValueError(
            f"whitening_changes: {plain.label!r} and {whitened.label!r} differ in more than the "
            "whitening (their matching options): pass one method run without and with whiten= "
            "alone"
        )
    for run in (plain, whitened):
        checks.check_descriptors_kept(run, "whitening_changes")
    step_between(plain, whitened, "whitening_changes", "the whitening")  # dataset, encoder, ...
    return int(m_w.whiten)


def _groups(kept: int, shared: int) -> list[tuple[str, int, int]]:
    """``(name, first, end)`` component groups: the ``shared`` largest, the next to 50, the rest
    kept (empty groups left out)."""
    edges = sorted({0, min(shared, kept), min(max(50, shared), kept), kept})
    return [
        (f"{a + 1}-{b}" if b > a + 1 else f"{b}", a, b)
        for a, b in zip(edges[:-1], edges[1:], strict=True)
    ]


def _contributions(u: np.ndarray, v: np.ndarray, fit: Whitening, groups: list) -> tuple:
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


def whitening_changes(
    plain: Any, whitened: Any, n_queries: int = 2, shared: int = 10
) -> pd.DataFrame:
    """(Not in the paper.) What whitening on the reference database changed, for chosen queries.

    The queries are :func:`~vpr_core.evaluation.steps.changed_queries`' (the first whose top-1
    whitening fixed, then one it broke, if any); for each, its top-1 before and after and its
    best-ranked correct reference, with their ranks and scores before and after, their
    reciprocal matches, and the share of the pair's plain match cosine that the database mean
    and its ``shared`` largest principal components carry (what whitening removes or scales
    down).

    Args:
        plain: a method's run without whitening; whitened: the same with ``whiten=k``; both with
            ``keep_descriptors=True``.
        n_queries: queries shown (1 to 3); shared: the components called shared (1 to 50).

    Returns:
        One row per query and reference (:data:`WHITENING_COLUMNS`); ``attrs``: ``parts`` (the
        names of what carries a cosine: the mean, each component group, beyond the kept ones),
        ``before`` and ``after`` (each part's share of the shown pairs' plain and whitened match
        cosines), ``kept`` and ``landmarks`` (the fit), ``shared``, ``queries`` (each chosen
        ``(query, case)``), ``changed`` (queries with a correct reference whose top-1 changed)
        and ``with_gt``.

    Raises:
        ValueError: bad ``n_queries`` / ``shared``; runs without descriptors, ``whitened`` not
            whitened, or runs differing in more than the whitening.
    """
    n_queries = int(
        checks.check_range(checks.check_int(n_queries, "n_queries", 1), "n_queries", 1, 3)
    )
    shared = int(checks.check_range(checks.check_int(shared, "shared", 1), "shared", 1, 50))
    k = _check_whitening_runs(plain, whitened)
    dp, dw, boxes = plain.descriptors, whitened.descriptors, plain.boxes
    fit = fit_whitening(dp["reference"], k)  # the run's own fit, from memory
    groups = _groups(fit.kept, shared)
    gt = np.asarray(plain.ground_truth, dtype=bool)
    sp, sw = np.asarray(plain.similarity, float), np.asarray(whitened.similarity, float)
    chosen = changed_queries(plain, whitened, n_queries)
    total_b, total_a, total_cos = np.zeros(len(groups) + 2), np.zeros(len(groups) + 2), 0.0
    rows = []
    for q, case in chosen:
        rp, rw = _ranks(sp[q]), _ranks(sw[q])
        refs = [int(np.argmin(rp)), int(np.argmin(rw))]
        if gt[q].any():
            refs.append(int(np.flatnonzero(gt[q])[np.argmin(rw[gt[q]])]))
        for r in dict.fromkeys(refs):
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
    table = pd.DataFrame(rows, columns=list(WHITENING_COLUMNS))
    top1 = [_top1(s) for s in (sp, sw)]
    after_sum = total_a.sum() if total_a.sum() > 0 else np.nan
    table.attrs.update(
        parts=["database mean", *(f"comp. {g[0]}" for g in groups), f"beyond {fit.kept}"],
        before=list(total_b / (total_cos if total_cos > 0 else np.nan)),
        after=list(total_a / after_sum),
        kept=fit.kept,
        landmarks=fit.landmarks,
        shared=shared,
        queries=list(chosen),
        changed=int(np.count_nonzero(gt.any(1) & (top1[0] != top1[1]))),
        with_gt=int(gt.any(1).sum()),
    )
    return table
