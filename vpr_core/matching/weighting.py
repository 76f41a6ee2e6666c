"""(Not in the paper.) The room of the database weightings of the Eq. (1) terms, ``weighting=``:
:data:`WEIGHTINGS` (one :class:`Weighting` per name: a weight function and what its statistics
read; docs/DEFINITIONS.md), the statistics, and :func:`weighted_block`, which applies them."""

from __future__ import annotations

import hashlib
import threading
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch

from ..utils import code_digest
from ._sides import PAD, Selection, Side
from .core import BLOCK_BYTES, BlockPairs, Matches, Problem, score_block

__all__ = [
    "CONTRAST_SAMPLE",
    "CONTRAST_SIGMA_MIN",
    "REFERENCE_CACHE_SIZE",
    "WEIGHTINGS",
    "WEIGHTING_SAMPLE",
    "Weighting",
    "best_cosine_statistics",
    "clear_reference_cache",
    "contrast_weight",
    "idf_statistics",
    "idf_weight",
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
_CACHE: OrderedDict[str, tuple[torch.Tensor, torch.Tensor]] = OrderedDict()
_CACHE_LOCK = threading.Lock()

#: The statistics of a weighting: per query landmark, over the references of the matches given.
Statistics = Callable[[Matches, torch.Tensor], tuple[torch.Tensor, torch.Tensor]]


def best_cosine_statistics(m: Matches, has: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """``(mu, sigma)`` ``(nq, Kq)`` of each query landmark's best cosines ``b_i(r)`` (ddof 0)
    over the references of ``m`` with landmarks (``has``: ``(nr,)`` bool)."""
    b = m.best[:, has].clamp(-1.0, 1.0)  # (nq, N, Kq)
    mu = b.mean(1)
    sd = ((b - mu.unsqueeze(1)) ** 2).mean(1).sqrt()
    return mu, sd


def idf_statistics(m: Matches, has: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """``(log((N + 1) / (n_i + 1)), N)``: ``n_i`` the references with landmarks that query
    landmark ``i`` reciprocally matches, ``N`` those references (a ``(1,)`` tensor)."""
    n = m.recip[:, has].sum(1).to(torch.float64)
    total = has.sum().to(torch.float64)
    return torch.log((total + 1.0) / (n + 1.0)), total.reshape(1)


def contrast_weight(c: torch.Tensor, mu: torch.Tensor, sd: torch.Tensor) -> torch.Tensor:
    """``max(0, (c - mu) / sd)``, 0 where ``sd <= CONTRAST_SIGMA_MIN`` (broadcast shapes)."""
    ok = sd > CONTRAST_SIGMA_MIN
    z = (c.clamp(-1.0, 1.0) - mu) / torch.where(ok, sd, 1.0)
    return torch.where(ok, z.clamp(min=0.0), 0.0)


def idf_weight(c: torch.Tensor, idf: torch.Tensor, n: torch.Tensor) -> torch.Tensor:
    """The landmark's ``log((N + 1) / (n_i + 1))``, whatever its cosine."""
    return idf.expand_as(c)


@dataclass(frozen=True)
class Weighting:
    """(Not in the paper.) One database weighting of the Eq. (1) terms: an entry of
    :data:`WEIGHTINGS`, whose key is its ``weighting=`` name.

    Attributes:
        weight: ``weight(c, a, b)``: each term's weight from ``c``, the query landmark's cosine
            to its match (``(nq, nr, Kq)``), and its statistics ``(a, b)`` (broadcastable).
        statistics: ``(a, b)`` per query landmark over the references (default: the mean and
            standard deviation of its best cosines, as ``contrast``).
        reads: ``"best"``: the statistics read best cosines only (one matmul a block);
            ``"reciprocal"``: they need the reciprocal matches.
        sample: references whose matches give a shortlist run's statistics.
        reference_side: also weight by the matched reference landmark's own best-cosine
            statistics over the other references: ``(1 + w_q)(1 + w_r)`` (``two_sided``).
    """

    weight: Callable[[torch.Tensor, torch.Tensor, torch.Tensor], torch.Tensor]
    statistics: Statistics = best_cosine_statistics
    reads: str = "best"
    sample: int = CONTRAST_SAMPLE
    reference_side: bool = False

    def __post_init__(self) -> None:
        assert self.reads in ("best", "reciprocal"), self.reads

    def identity(self) -> str:
        """What a matrix cache key holds of it: "" for the package's functions (its code
        version covers them), else the bytecode digest of its functions (a weighting defined
        in a notebook cell and edited there gets a new key)."""
        funcs = [f for f in (self.weight, self.statistics) if not _packaged(f)]
        return code_digest(funcs) if funcs else ""


#: (Not in the paper.) The database weightings by ``weighting=`` name (docs/DEFINITIONS.md). A
#: new weighting is one weight function and one entry here.
WEIGHTINGS: dict[str, Weighting] = {
    "contrast": Weighting(contrast_weight),
    "idf": Weighting(idf_weight, idf_statistics, "reciprocal", WEIGHTING_SAMPLE),
    "two_sided": Weighting(contrast_weight, reference_side=True),
}


def _packaged(func: Callable) -> bool:
    return str(getattr(func, "__module__", "")).split(".")[0] == "vpr_core"


def weighting_sample(n_references: int, weighting: str | None = None) -> np.ndarray:
    """Sorted indices of the references whose cosines give a shortlist's weighting statistics.

    ``size`` = the weighting's :attr:`Weighting.sample` (:data:`CONTRAST_SAMPLE` for
    ``"contrast"`` and ``"two_sided"``, :data:`WEIGHTING_SAMPLE` for ``"idf"``): every reference
    when there are at most ``size``, else ``size`` drawn without replacement by
    ``np.random.default_rng(0)`` (docs/DEFINITIONS.md).
    """
    size = WEIGHTINGS[weighting].sample if weighting is not None else WEIGHTING_SAMPLE
    if n_references <= size:
        return np.arange(n_references, dtype=np.int64)
    pick = np.random.default_rng(0).choice(n_references, size, replace=False)
    return np.sort(pick).astype(np.int64)


def sample_matches(prob: Problem, qsel: Selection, refs: torch.Tensor, size: int) -> Matches:
    """The matches of the images ``qsel`` x the references ``refs`` that the statistics read.

    ``reads="best"``: only the best cosines ``b_i(r)``, each the maximum of one row of a
    matmul of ``qsel``'s landmarks x ``size`` references' landmarks (matmul dtype, padded
    landmarks never win), with no reciprocal test (``nn`` -1, ``recip`` False);
    ``"reciprocal"``: the reciprocal matches (:meth:`.core.Problem.chunked`).
    """
    if WEIGHTINGS[str(prob.matching.weighting)].reads == "best":
        return prob.best_cosines(qsel, refs, size)
    return prob.chunked(qsel, refs, size)


def _reference_weights(
    entry: Weighting, prob: Problem, rsel: Selection, m: Matches
) -> torch.Tensor:
    """``(nq, nr, Kq)`` ``w_r`` of each query landmark's matched reference landmark ``m.nn``."""
    mu, sd = prob.ref_stats  # type: ignore[misc]  # (Nr, Kr) each
    nq = m.best.shape[0]
    j = m.nn.clamp(min=0)
    mu_j = mu[rsel].unsqueeze(0).expand(nq, -1, -1).gather(2, j)
    sd_j = sd[rsel].unsqueeze(0).expand(nq, -1, -1).gather(2, j)
    return entry.weight(m.best, mu_j, sd_j)


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
    """Set ``prob.ref_stats`` for a weighting with a reference side (``two_sided``; before worker
    threads share ``prob``)."""
    weighting = prob.matching.weighting
    if weighting is not None and WEIGHTINGS[weighting].reference_side and not prob.empty:
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
    entry = WEIGHTINGS[str(prob.matching.weighting)]
    ms, ssel = stats_from
    a, b = entry.statistics(ms, prob.r.count[ssel] > 0)
    w = entry.weight(m.best, a.unsqueeze(1), b.unsqueeze(1))
    if entry.reference_side:  # (1 + w_q)(1 + w_r)
        w = (1.0 + w) * (1.0 + _reference_weights(entry, prob, rsel, m))
    return score_block(prob, m, qsel, rsel, keep_pairs, w)
