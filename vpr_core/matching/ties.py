"""Exact nearest neighbours for the batched path: float64 re-decision of float32 near-ties.

The batched matmul runs in float32; a row (or column) whose best cosines lie within the float32
error bound of each other is re-decided here in float64 with the pairwise rule
(:data:`~vpr_core.matching.pairwise.TIE_TOL`, lowest index), so the batched matches equal
:func:`~vpr_core.matching.pairwise.reciprocal_matches` exactly.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from .padding import Side
from .pairwise import TIE_TOL

__all__ = ["cos64", "resolve_ties"]


def cos64(q: Side, qrows: torch.Tensor, r: Side, rrows: torch.Tensor) -> torch.Tensor:
    """``(t,)`` float64 cosines of flat query rows ``qrows`` and reference rows ``rrows``.

    ``dot(a, b) / (|a| |b|)`` with float64 norms computed once per side: equal to the pairwise
    path's ``(a / |a|) . (b / |b|)`` to a few ulp (far inside :data:`TIE_TOL`); 0 for zero rows.
    """
    norms = q.norm64().index_select(0, qrows) * r.norm64().index_select(0, rrows)
    if q.raw.device.type == "cpu":
        # NumPy gathers the rows and casts chunk by chunk inside einsum (no big float64
        # temporaries); float32 products are exact in float64
        x = q.raw.numpy()[qrows.numpy()]
        y = r.raw.numpy()[rrows.numpy()]
        return torch.from_numpy(np.einsum("ij,ij->i", x, y, dtype=np.float64)) / norms
    x = q.raw.index_select(0, qrows).to(torch.float64)
    y = r.raw.index_select(0, rrows).to(torch.float64)
    return torch.linalg.vecdot(x, y) / norms


def resolve_ties(vals: torch.Tensor, best: torch.Tensor, margin: float, sim64_fn):
    """Exact (float64, TIE_TOL) nearest neighbour of near-tied rows.

    Args:
        vals: ``(n, K)`` float32 similarities of the ambiguous rows.
        best: ``(n,)`` their float32 maxima.
        margin: float32 error bound; every entry within it of the max is a candidate.
        sim64_fn: ``(row_ids (t,), cols (t,)) -> (t,)`` float64 similarities.

    Returns:
        ``(nn (n,) int64, sim (n,) float64)``.
    """
    n, k = vals.shape
    cand = vals >= (best - margin).unsqueeze(1)
    rows, cols = cand.nonzero(as_tuple=True)
    sims = torch.empty(rows.shape[0], dtype=torch.float64, device=vals.device)
    step = 1024  # keeps the gathered float64 rows in cache
    for s in range(0, rows.shape[0], step):
        sims[s:s + step] = sim64_fn(rows[s:s + step], cols[s:s + step])
    sims = sims.clamp(-1.0, 1.0)
    mx = torch.full((n,), -math.inf, dtype=torch.float64, device=vals.device)
    mx = mx.scatter_reduce(0, rows, sims, reduce="amax")
    tied = sims >= mx[rows] - TIE_TOL
    big = torch.full_like(cols, k)
    nn = torch.full((n,), k, dtype=torch.int64, device=vals.device)
    nn = nn.scatter_reduce(0, rows, torch.where(tied, cols, big), reduce="amin")
    chosen = cols == nn[rows]
    sim = torch.zeros(n, dtype=torch.float64, device=vals.device)
    sim[rows[chosen]] = sims[chosen]
    return nn, sim
