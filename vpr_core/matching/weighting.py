"""(Not in the paper.) Database weighting of the Eq. (1) terms, ``weighting=``: each query
landmark's statistics over the references and the weight of its term (docs/DEFINITIONS.md,
"(not in the paper) database weighting"); :func:`weighted_block` applies them in
:func:`.core.score_block`."""

from __future__ import annotations

import numpy as np
import torch

from ._sides import Selection
from .core import BlockPairs, Matches, Problem, score_block

__all__ = [
    "CONTRAST_SAMPLE",
    "CONTRAST_SIGMA_MIN",
    "WEIGHTING_SAMPLE",
    "sample_matches",
    "weighted_block",
    "weighting_sample",
]

#: (Not in the paper.) References (a seed-0 sample) whose matches give the ``idf`` statistics
#: of a shortlist run; every reference when there are at most this many.
WEIGHTING_SAMPLE = 256
#: (Not in the paper.) References (a seed-0 sample) whose best cosines give the ``contrast``
#: statistics of a shortlist run; every reference when there are at most this many. 12 keeps
#: their cost within 1.3x the unweighted matching of a 25-reference shortlist (issue 46; their
#: precision and the sizes measured: docs/DEFINITIONS.md).
CONTRAST_SAMPLE = 12
#: (Not in the paper.) A contrast standard deviation at or below this counts as 0 (the float32
#: cosines cannot tell the references apart): the landmark's weight is 0.
CONTRAST_SIGMA_MIN = 1e-6


def weighting_sample(n_references: int, weighting: str | None = None) -> np.ndarray:
    """Sorted indices of the references whose cosines give a shortlist's weighting statistics.

    ``size`` = :data:`CONTRAST_SAMPLE` for ``weighting="contrast"``, else
    :data:`WEIGHTING_SAMPLE`: every reference when there are at most ``size``, else ``size``
    drawn without replacement by ``np.random.default_rng(0)`` (docs/DEFINITIONS.md).
    """
    size = CONTRAST_SAMPLE if weighting == "contrast" else WEIGHTING_SAMPLE
    if n_references <= size:
        return np.arange(n_references, dtype=np.int64)
    pick = np.random.default_rng(0).choice(n_references, size, replace=False)
    return np.sort(pick).astype(np.int64)


def sample_matches(prob: Problem, qsel: Selection, refs: torch.Tensor, size: int) -> Matches:
    """The matches of the images ``qsel`` x the references ``refs`` that the statistics read.

    ``contrast`` reads only the best cosines ``b_i(r)``: each the maximum of one row of a
    matmul of ``qsel``'s landmarks x ``size`` references' landmarks (matmul dtype, padded
    landmarks never win), with no reciprocal test (``nn`` -1, ``recip`` False). ``idf`` needs
    the reciprocal matches: :meth:`.core.Problem.chunked`.
    """
    if prob.matching.weighting == "contrast":
        return prob.best_cosines(qsel, refs, size)
    return prob.chunked(qsel, refs, size)


def _weighting_stats(
    weighting: str, m: Matches, has: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """Per query landmark ``(nq, Kq)`` statistics over the references of ``m`` with landmarks.

    Args:
        weighting: a name in :data:`~.spec.WEIGHTING_OPTIONS`.
        m: matches of ``nq`` query images x the references that define the statistics.
        has: ``(nr,)`` bool: the reference has at least one landmark (only those count).

    Returns:
        ``contrast``: ``(mu, sigma)`` of the best cosines ``b_i(r)`` (population std);
        ``idf``: ``(log((N + 1) / (n_i + 1)), N)``, ``n_i`` the references that landmark ``i``
        reciprocally matches, ``N`` the references (as a ``(1,)`` tensor).
    """
    if weighting == "contrast":
        b = m.best[:, has].clamp(-1.0, 1.0)  # (nq, N, Kq)
        mu = b.mean(1)
        sd = ((b - mu.unsqueeze(1)) ** 2).mean(1).sqrt()
        return mu, sd
    n = m.recip[:, has].sum(1).to(torch.float64)
    total = has.sum().to(torch.float64)
    return torch.log((total + 1.0) / (n + 1.0)), total.reshape(1)


def _database_weights(
    weighting: str, best: torch.Tensor, stats: tuple[torch.Tensor, torch.Tensor]
) -> torch.Tensor:
    """``(nq, nr, Kq)`` weight of each query landmark's term (docs/DEFINITIONS.md).

    ``contrast``: ``max(0, (c - mu_i) / sigma_i)`` with ``c`` the landmark's cosine to its match
    (its best cosine ``b_i(r)`` in that reference), 0 where ``sigma_i <= CONTRAST_SIGMA_MIN``;
    ``idf``: the landmark's ``log((N + 1) / (n_i + 1))``.

    Args:
        weighting: a name in :data:`~.spec.WEIGHTING_OPTIONS`; best: ``(nq, nr, Kq)`` ``b_i(r)``;
            stats: from :func:`_weighting_stats`.
    """
    a, b = stats
    if weighting == "contrast":
        ok = (b > CONTRAST_SIGMA_MIN).unsqueeze(1)
        z = (best.clamp(-1.0, 1.0) - a.unsqueeze(1)) / torch.where(ok, b.unsqueeze(1), 1.0)
        return torch.where(ok, z.clamp(min=0.0), 0.0)
    return a.unsqueeze(1).expand_as(best)


def weighted_block(
    prob: Problem,
    qsel: Selection,
    rsel: Selection,
    m: Matches,
    stats_from: tuple[Matches, Selection],
    keep_pairs: bool = False,
) -> tuple[torch.Tensor, BlockPairs | None]:
    """Eq. (1) with database-weighted terms of the images ``qsel`` x ``rsel`` (matches ``m``):
    :func:`.core.score_block`'s ``((nq, nr) float64, pairs or None)``.

    Args:
        prob: the call's :class:`~.core.Problem`, its ``matching.weighting`` set.
        stats_from: the matches of ``qsel`` x the references that define the statistics
            (:func:`sample_matches`), and those references.
    """
    weighting = prob.matching.weighting
    assert weighting is not None
    ms, ssel = stats_from
    stats = _weighting_stats(weighting, ms, prob.r.count[ssel] > 0)
    w = _database_weights(weighting, m.best, stats)
    return score_block(prob, m, qsel, rsel, keep_pairs, w)
