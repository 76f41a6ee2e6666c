"""(Not in the paper.) Database weighting of the Eq. (1) terms, ``weighting=``: each query
landmark's statistics over the references (``two_sided``: also each reference landmark's over
the other references, :func:`reference_stats`) and the weight of its term (docs/DEFINITIONS.md);
:func:`weighted_block` applies them in :func:`.core.score_block`."""

from __future__ import annotations

import hashlib
import threading
from collections import OrderedDict

import numpy as np
import torch

from ._sides import PAD, Selection, Side
from .core import BLOCK_BYTES, BlockPairs, Matches, Problem, score_block

__all__ = [
    "CONTRAST_SAMPLE",
    "CONTRAST_SIGMA_MIN",
    "REFERENCE_CACHE_SIZE",
    "WEIGHTING_SAMPLE",
    "clear_reference_cache",
    "prepare_reference_stats",
    "reference_cache_keys",
    "reference_stats",
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
#: (Not in the paper.) Databases whose ``two_sided`` reference statistics are kept in memory
#: (keyed by content, least recently used dropped first).
REFERENCE_CACHE_SIZE = 4
#: The weightings whose query-side statistics are ``contrast``'s (best cosines, no reciprocal test).
_CONTRAST_LIKE = ("contrast", "two_sided")
_CACHE: OrderedDict[str, tuple[torch.Tensor, torch.Tensor]] = OrderedDict()
_CACHE_LOCK = threading.Lock()


def weighting_sample(n_references: int, weighting: str | None = None) -> np.ndarray:
    """Sorted indices of the references whose cosines give a shortlist's weighting statistics.

    ``size`` = :data:`CONTRAST_SAMPLE` for ``"contrast"`` and ``"two_sided"``, else
    :data:`WEIGHTING_SAMPLE`: every reference when there are at most ``size``, else ``size``
    drawn without replacement by ``np.random.default_rng(0)`` (docs/DEFINITIONS.md).
    """
    size = CONTRAST_SAMPLE if weighting in _CONTRAST_LIKE else WEIGHTING_SAMPLE
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
    if prob.matching.weighting in _CONTRAST_LIKE:
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
        ``contrast``, ``two_sided``: ``(mu, sigma)`` of the best cosines ``b_i(r)`` (ddof 0);
        ``idf``: ``(log((N + 1) / (n_i + 1)), N)``, ``n_i`` the references that landmark ``i``
        reciprocally matches, ``N`` the references (as a ``(1,)`` tensor).
    """
    if weighting in _CONTRAST_LIKE:
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
    if weighting in _CONTRAST_LIKE:
        return _contrast(best, a.unsqueeze(1), b.unsqueeze(1))
    return a.unsqueeze(1).expand_as(best)


def _contrast(c: torch.Tensor, mu: torch.Tensor, sd: torch.Tensor) -> torch.Tensor:
    """``max(0, (c - mu) / sd)``, 0 where ``sd <= CONTRAST_SIGMA_MIN`` (broadcast shapes)."""
    ok = sd > CONTRAST_SIGMA_MIN
    z = (c.clamp(-1.0, 1.0) - mu) / torch.where(ok, sd, 1.0)
    return torch.where(ok, z.clamp(min=0.0), 0.0)


def _reference_weights(prob: Problem, rsel: Selection, m: Matches) -> torch.Tensor:
    """``(nq, nr, Kq)`` ``w_r`` of each query landmark's matched reference landmark ``m.nn``."""
    mu, sd = prob.ref_stats  # type: ignore[misc]  # (Nr, Kr) each
    nq = m.best.shape[0]
    j = m.nn.clamp(min=0)
    mu_j = mu[rsel].unsqueeze(0).expand(nq, -1, -1).gather(2, j)
    sd_j = sd[rsel].unsqueeze(0).expand(nq, -1, -1).gather(2, j)
    return _contrast(m.best, mu_j, sd_j)


def _database_key(r: Side, ids: np.ndarray) -> str:
    """Content key of a database's reference statistics: descriptors, counts, sample, dtype."""
    h = hashlib.sha256()
    h.update(str((r.n, r.k, r.dim, str(r.d32.dtype))).encode())
    h.update(np.ascontiguousarray(r.d32.cpu().numpy()).reshape(-1).view(np.uint8).data)
    h.update(r.count.cpu().numpy().tobytes())
    h.update(np.asarray(ids, dtype=np.int64).tobytes())
    return h.hexdigest()


def _compute_reference_stats(r: Side, ids: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """``(mu, sigma)`` ``(Nr, Kr)`` float64 of each reference landmark's best cosines over the
    references ``ids`` other than its own with landmarks (docs/DEFINITIONS.md, two-sided)."""
    k, n_ids = r.k, int(ids.numel())
    rows = max(1, min(8, r.n))
    size = max(1, BLOCK_BYTES // (4 * rows * k * k))
    every = n_ids == r.n and bool((ids == torch.arange(r.n, device=ids.device)).all())
    sels: list[Selection] = [
        slice(c0, min(c0 + size, n_ids)) if every else ids[c0 : c0 + size]
        for c0 in range(0, n_ids, size)
    ]  # slices (views) for every reference, gathered indices for a sample
    chunks = [(r.images(sel), ~r.mask[sel][None, None]) for sel in sels]
    valid_ref = (r.count > 0)[ids]  # (ns,)
    mu = torch.zeros((r.n, k), dtype=torch.float64, device=r.d32.device)
    sd = torch.zeros_like(mu)
    for r0 in range(0, r.n, rows):
        r1 = min(r0 + rows, r.n)
        a = r.images(slice(r0, r1))
        parts = []
        for b, pad in chunks:
            s = (a @ b.T).view(r1 - r0, k, b.shape[0] // k, k)
            if r.padded:
                s.masked_fill_(pad, PAD)
            parts.append(s.amax(3))
        best = torch.cat(parts, 2).permute(0, 2, 1).to(torch.float64).clamp(-1.0, 1.0)
        own = torch.arange(r0, r1, device=ids.device)[:, None] != ids[None, :]  # (nr, ns)
        w = (own & valid_ref[None, :]).to(torch.float64).unsqueeze(2)  # (nr, ns, 1)
        cnt = w.sum(1)  # (nr, 1)
        m_ = (best * w).sum(1) / cnt.clamp(min=1.0)
        v = (((best - m_.unsqueeze(1)) ** 2) * w).sum(1) / cnt.clamp(min=1.0)
        mu[r0:r1] = m_
        sd[r0:r1] = torch.where(cnt > 0, v.sqrt(), torch.zeros_like(v))
    return mu, sd


def reference_stats(r: Side, ids: np.ndarray) -> tuple[torch.Tensor, torch.Tensor]:
    """``two_sided``'s reference statistics ``(mu, sigma)``, ``(Nr, Kr)`` float64 each, over the
    references ``ids`` (every one: exhaustive; :func:`weighting_sample`: a shortlist), computed
    once per database content (:data:`REFERENCE_CACHE_SIZE` kept; docs/DEFINITIONS.md)."""
    key = _database_key(r, ids)
    with _CACHE_LOCK:
        hit = _CACHE.get(key)
        if hit is not None:
            _CACHE.move_to_end(key)
            return hit
    out = _compute_reference_stats(r, torch.from_numpy(np.asarray(ids, np.int64)).to(r.d32.device))
    with _CACHE_LOCK:
        _CACHE[key] = out
        while len(_CACHE) > REFERENCE_CACHE_SIZE:
            _CACHE.popitem(last=False)
    return out


def clear_reference_cache() -> int:
    """Empty the in-memory ``two_sided`` reference statistics; returns the entries dropped."""
    with _CACHE_LOCK:
        n = len(_CACHE)
        _CACHE.clear()
    return n


def reference_cache_keys() -> list[str]:
    """The content keys of the databases whose reference statistics are in memory (oldest
    first)."""
    with _CACHE_LOCK:
        return list(_CACHE)


def prepare_reference_stats(prob: Problem, ids: np.ndarray) -> None:
    """Set ``prob.ref_stats`` for ``two_sided`` (before worker threads share ``prob``)."""
    if prob.matching.weighting == "two_sided" and not prob.empty:
        prob.ref_stats = reference_stats(prob.r, ids)


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
    if weighting == "two_sided":  # (1 + w_q)(1 + w_r)
        w = (1.0 + w) * (1.0 + _reference_weights(prob, rsel, m))
    return score_block(prob, m, qsel, rsel, keep_pairs, w)
