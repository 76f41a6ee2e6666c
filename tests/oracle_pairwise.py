"""Test oracle: Eq. (1)-(2), reciprocal NN and Algorithm 4 on one image pair in plain NumPy float64.

Written straight from docs/DEFINITIONS.md (Matching); ``tests/test_matching.py`` checks the torch
core of :mod:`vpr_core.matching` against it. Not used by the package.
"""

from __future__ import annotations

import math

import numpy as np

from vpr_core.boxes import box_iou
from vpr_core.matching.core import NMS_TIE_TOL, SPATIAL_TAU
from vpr_core.matching.reciprocal import TIE_TOL
from vpr_core.matching.weighting import CONTRAST_SIGMA_MIN
from vpr_core.paper import SOFT_NMS_SIGMA


def cosine_similarity(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(Ka, Kb)`` cosines clipped to ``[-1, 1]``; 0 where either vector is zero."""

    def unit(d: np.ndarray) -> np.ndarray:
        n = np.linalg.norm(d, axis=1, keepdims=True)
        return d / np.where(n > 0, n, 1.0)

    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    return np.clip(unit(a) @ unit(b).T, -1.0, 1.0)


def _nn_with_ties(sim: np.ndarray, axis: int) -> np.ndarray:
    """Index of the best entry along ``axis``; entries within TIE_TOL of the best tie -> lowest."""
    best = sim.max(axis=axis, keepdims=True)
    return np.argmax(sim >= best - TIE_TOL, axis=axis)


def reciprocal_from_sim(sim: np.ndarray) -> np.ndarray:
    """``(P, 2)`` int64 mutual nearest neighbours ``(i, j)`` of a cosine matrix, sorted by i."""
    ka, kb = sim.shape
    if ka == 0 or kb == 0:
        return np.zeros((0, 2), dtype=np.int64)
    nn_a = _nn_with_ties(sim, axis=1)
    nn_b = _nn_with_ties(sim, axis=0)
    i = np.arange(ka)
    keep = nn_b[nn_a] == i
    return np.stack([i[keep], nn_a[keep]], axis=1).astype(np.int64)


def reciprocal_matches(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Reciprocal matches of two descriptor sets."""
    return reciprocal_from_sim(cosine_similarity(a, b))


def shape_terms(wa, wb, ha, hb):
    """Eq. (2) from broadcastable widths and heights (a 0/0 term counts as 0)."""

    def term(u, v):
        m = np.maximum(u, v)
        return np.where(m > 0, np.abs(u - v) / np.where(m > 0, m, 1.0), 0.0)

    return np.exp(0.5 * (term(wa, wb) + term(ha, hb)))


def shape_penalty(boxes_a: np.ndarray, boxes_b: np.ndarray) -> np.ndarray:
    """``(Ka, Kb)`` Eq. (2) of every landmark pair."""
    a, b = np.asarray(boxes_a, np.float64), np.asarray(boxes_b, np.float64)
    return shape_terms(a[:, None, 2], b[None, :, 2], a[:, None, 3], b[None, :, 3])


def match_overlaps(boxes_a: np.ndarray, boxes_b: np.ndarray, matches) -> np.ndarray:
    """``(P, P)`` overlap of two matches: min of the IoU of their a-boxes and of their b-boxes."""
    a = np.asarray(boxes_a, np.float64).reshape(-1, 4)
    b = np.asarray(boxes_b, np.float64).reshape(-1, 4)
    m = np.asarray(matches, dtype=np.int64).reshape(-1, 2)
    i, j = m[:, 0], m[:, 1]
    return np.minimum(box_iou(a, a)[np.ix_(i, i)], box_iou(b, b)[np.ix_(j, j)])


def soft_nms_scores(scores, overlaps, t: float, sigma: float = SOFT_NMS_SIGMA) -> np.ndarray:
    """Algorithm 4: each pair's score when it was removed (ties: lowest pair index first)."""
    cur = np.array(scores, dtype=np.float64).reshape(-1)
    o = np.asarray(overlaps, dtype=np.float64)
    decay = np.where(o > t, np.exp(-(o**2) / sigma), 1.0)
    out = np.empty_like(cur)
    alive = np.ones(cur.shape[0], dtype=bool)
    for _ in range(cur.shape[0]):
        masked = np.where(alive, cur, -np.inf)
        m = int(np.argmax(masked >= masked.max() - NMS_TIE_TOL))
        out[m] = cur[m]
        alive[m] = False
        cur *= decay[m]
    return out


def extent_centres(boxes: np.ndarray) -> np.ndarray:
    """``(K, 2)`` box centres relative to the boxes' union bounding box, in units of its size."""
    if len(boxes) == 0:
        return np.zeros((0, 2))
    x0, y0 = boxes[:, 0].min(), boxes[:, 1].min()
    w = (boxes[:, 0] + boxes[:, 2]).max() - x0
    h = (boxes[:, 1] + boxes[:, 3]).max() - y0
    w, h = (w if w > 0 else 1.0), (h if h > 0 else 1.0)
    cx = (boxes[:, 0] + boxes[:, 2] / 2 - x0) / w
    cy = (boxes[:, 1] + boxes[:, 3] / 2 - y0) / h
    return np.stack([cx, cy], axis=1)


def consistency_weights(ba, bb, matches, tau: float = SPATIAL_TAU) -> np.ndarray:
    """(Not in the paper) ``exp(-|delta - median delta|^2 / (2 tau^2))`` of each match."""
    i, j = matches[:, 0], matches[:, 1]
    delta = extent_centres(ba)[i] - extent_centres(bb)[j]
    if len(delta) == 0:
        return np.ones(0)
    med = np.median(delta, axis=0)
    return np.exp(-((delta - med) ** 2).sum(axis=1) / (2 * tau**2))


def term_weights(weighting, desc_q, reference_descs):
    """(Not in the paper) ``f(i, c)``: the weight of query landmark ``i``'s term with cosine ``c``,
    statistics over ``reference_descs`` (those with landmarks)."""
    cos = [cosine_similarity(desc_q, d) for d in reference_descs if len(d)]
    if weighting == "contrast":
        b = np.stack([c.max(axis=1) for c in cos], axis=1)  # (K, N): b_i(r)
        mu, sd = b.mean(axis=1), b.std(axis=1)

        def contrast(i, c):
            ok = sd[i] > CONTRAST_SIGMA_MIN
            return np.where(ok, np.maximum(0.0, (c - mu[i]) / np.where(ok, sd[i], 1.0)), 0.0)

        return contrast
    assert weighting == "idf"
    n = np.zeros(len(desc_q))
    for c in cos:
        n[reciprocal_from_sim(c)[:, 0]] += 1
    idf = np.log((len(cos) + 1) / (n + 1))
    return lambda i, c: idf[i]


def reference_contrast(rd, r, refs):
    """(Not in the paper) ``(mu_j, sigma_j)`` of reference ``r``'s landmarks: their best cosines
    over the references ``refs`` other than ``r`` with landmarks (0, 0 when there are none)."""
    others = [rd[t] for t in refs if t != r and len(rd[t])]
    k = len(rd[r])
    if not others or k == 0:
        return np.zeros(k), np.zeros(k)
    b = np.stack([cosine_similarity(rd[r], d).max(axis=1) for d in others], axis=1)
    return b.mean(axis=1), b.std(axis=1)


def pair_weights(weighting, desc_q, rd, r, refs=None):
    """(Not in the paper) ``f(i, c, j)``: the weight of match ``(i, j)`` with cosine ``c`` of a
    query and reference ``r``; statistics over the references ``refs`` (default: all)."""
    refs = range(len(rd)) if refs is None else refs
    if weighting != "two_sided":
        f = term_weights(weighting, desc_q, [rd[t] for t in refs])
        return lambda i, c, j: f(i, c)
    fq = term_weights("contrast", desc_q, [rd[t] for t in refs])
    mu, sd = reference_contrast(rd, r, refs)

    def two_sided(i, c, j):
        ok = sd[j] > CONTRAST_SIGMA_MIN
        wr = np.where(ok, np.maximum(0.0, (c - mu[j]) / np.where(ok, sd[j], 1.0)), 0.0)
        return (1.0 + fq(i, c)) * (1.0 + wr)

    return two_sided


def match_landmarks(
    desc_a,
    boxes_a,
    desc_b,
    boxes_b,
    soft_nms_iou=None,
    sigma=SOFT_NMS_SIGMA,
    spatial=None,
    weights=None,
):
    """``dict`` of matches, distances, shape, raw_scores, weights, db_weights, scores, similarity,
    n_a, n_b; ``weights``: None or a :func:`pair_weights` function."""
    a, b = np.asarray(desc_a, np.float64), np.asarray(desc_b, np.float64)
    ba = np.asarray(boxes_a, np.float64).reshape(-1, 4)
    bb = np.asarray(boxes_b, np.float64).reshape(-1, 4)
    cos = cosine_similarity(a, b) if a.size and b.size else np.zeros((len(a), len(b)))
    m = reciprocal_from_sim(cos)
    i, j = m[:, 0], m[:, 1]
    dist = 1.0 - cos[i, j]
    shp = shape_terms(ba[i, 2], bb[j, 2], ba[i, 3], bb[j, 3])
    raw = 1.0 - dist * shp
    assert spatial in (None, "consistency")
    w = np.ones(len(m)) if spatial is None else consistency_weights(ba, bb, m)
    wd = np.ones(len(m)) if weights is None else weights(i, 1.0 - dist, j)
    scores = raw * w * wd
    if soft_nms_iou is not None and len(m) > 1:
        scores = soft_nms_scores(scores, match_overlaps(ba, bb, m), soft_nms_iou, sigma)
    na, nb = len(a), len(b)
    sim = float(scores.sum() / math.sqrt(na * nb)) if na * nb > 0 else 0.0
    return {
        "matches": m,
        "distances": dist,
        "shape": shp,
        "raw_scores": raw,
        "weights": w,
        "db_weights": wd,
        "scores": scores,
        "similarity": sim,
        "n_a": na,
        "n_b": nb,
    }


def image_similarity(
    desc_a, boxes_a, desc_b, boxes_b, soft_nms_iou=None, sigma=SOFT_NMS_SIGMA, spatial=None
):
    """Eq. (1) of two images."""
    res = match_landmarks(desc_a, boxes_a, desc_b, boxes_b, soft_nms_iou, sigma, spatial)
    return res["similarity"]


def similarity_matrix(qd, qb, rd, rb, weighting=None, sample=None, **kw):
    """``(Nq, Nr)`` Eq. (1); with ``weighting``, statistics over the references ``sample``
    (default: all)."""
    refs = list(range(len(rd)) if sample is None else sample)
    out = np.zeros((len(qd), len(rd)))
    for i in range(len(qd)):
        for j in range(len(rd)):
            w = None if weighting is None else pair_weights(weighting, qd[i], rd, j, refs)
            out[i, j] = match_landmarks(qd[i], qb[i], rd[j], rb[j], weights=w, **kw)["similarity"]
    return out
