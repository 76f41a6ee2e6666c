"""Algorithm 4 (soft-NMS) for the batched path: many image pairs in lockstep.

Same rule as :func:`~vpr_core.matching.pairwise.soft_nms_scores`, run on every image pair of a
block at once; pair scores are recomputed from float64 cosines so that its argmax, which is
discontinuous at ties, breaks ties exactly as the pairwise path does.
"""

from __future__ import annotations

import math

import torch

from .pairwise import NMS_TIE_TOL

__all__ = ["nms_block", "soft_nms_batched"]


def soft_nms_batched(
    scores: torch.Tensor,
    alive: torch.Tensor,
    oq: torch.Tensor,
    orf: torch.Tensor,
    t: float,
    sigma: float,
) -> torch.Tensor:
    """Algorithm 4 on G image pairs in lockstep.

    Args:
        scores: ``(G, P)`` float64 pair scores (pairs in query-landmark order).
        alive: ``(G, P)`` bool real pairs.
        oq: ``(G, P, P)`` IoU of the query boxes of two pairs.
        orf: ``(G, P, P)`` IoU of the reference boxes of two pairs.
        t: threshold; sigma: Gaussian width.

    Returns:
        ``(G, P)`` rescaled scores (undefined where not alive).
    """
    o = torch.minimum(oq, orf)
    decay = torch.where(o > t, torch.exp(-(o * o) / sigma), torch.ones_like(o))
    del o
    g = scores.shape[0]
    cur = scores.clone()
    out = scores.clone()
    alive = alive.clone()
    ar = torch.arange(g, device=scores.device)
    neg = torch.tensor(-math.inf, dtype=scores.dtype, device=scores.device)
    for _ in range(int(alive.sum(1).max().item()) if g else 0):
        masked = torch.where(alive, cur, neg)
        mx = masked.amax(1, keepdim=True)
        m = (masked >= mx - NMS_TIE_TOL).to(torch.uint8).argmax(1)  # lowest tied pair index
        has = alive[ar, m]
        out[ar, m] = torch.where(has, cur[ar, m], out[ar, m])
        alive[ar, m] = False
        cur = cur * decay[ar, m]
    return out


def nms_block(
    score: torch.Tensor,
    shp: torch.Tensor,
    recip: torch.Tensor,
    ri_p: torch.Tensor,
    s64: torch.Tensor,
    iou_q: torch.Tensor,
    iou_r: torch.Tensor,
    t: float,
    sigma: float,
    group: int = 1024,
) -> torch.Tensor:
    """Soft-NMS for a block of image pairs.

    Pair scores are recomputed from float64 cosines so that ties break as in the pairwise path.

    Args:
        score: ``(nq, nr, Kq)`` pair scores per query landmark.
        shp: ``(nq, nr, Kq)`` shape penalties.
        recip: ``(nq, nr, Kq)`` bool, query landmark is reciprocally matched.
        ri_p: ``(nq, nr, Kq)`` matched reference landmark.
        s64: ``(nq, Kq, nr, Kr)`` float64 cosines of the block.
        iou_q: ``(nq, Kq, Kq)``; iou_r: ``(nr, Kr, Kr)`` per-image box IoUs.
        t, sigma: soft-NMS parameters.

    Returns:
        ``(nq, nr, Kq)`` rescaled scores (unchanged where not matched).
    """
    npair = recip.sum(2)
    qi, rj = (npair > 1).nonzero(as_tuple=True)  # soft-NMS is the identity below 2 matches
    if qi.numel() == 0:
        return score
    score = score.clone()
    for s0 in range(0, qi.numel(), group):
        gq, gr = qi[s0 : s0 + group], rj[s0 : s0 + group]
        alive0 = recip[gq, gr]  # (G, Kq)
        p = int(npair[gq, gr].max().item())
        # compact matched landmarks to the front, keeping query-landmark order (pair index)
        order = torch.argsort((~alive0).to(torch.int8), dim=1, stable=True)[:, :p]
        alive = alive0.gather(1, order)
        ii = order
        jj = ri_p[gq, gr].gather(1, order)
        # float64 cosines of the matched pairs: the argmax of Algorithm 4 is discontinuous at
        # ties, so the scores must equal the pairwise path's to ~1e-15, not just ~1e-7
        cos = s64[gq[:, None], ii, gr[:, None], jj][alive].clamp(-1.0, 1.0)
        sc = torch.zeros(alive.shape, dtype=torch.float64, device=score.device)
        sc[alive] = 1.0 - (1.0 - cos) * shp[gq, gr].gather(1, order)[alive]
        oq = iou_q[gq[:, None, None], ii[:, :, None], ii[:, None, :]]
        orf = iou_r[gr[:, None, None], jj[:, :, None], jj[:, None, :]]
        new = soft_nms_batched(sc, alive, oq, orf, t, sigma)
        rows = score[gq, gr]
        rows.scatter_(1, order, torch.where(alive, new, sc))
        score[gq, gr] = rows
    return score
