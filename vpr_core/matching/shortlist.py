"""Shortlist + re-rank: a whole-image descriptor picks top-k references per query, Eq. (1)
re-ranks them (NaN = not ranked, S2 inside the shortlist, ties: docs/DEFINITIONS.md)."""

from __future__ import annotations

import numpy as np

from ..checks import check_finite, check_int
from ..datasets.base import SIDES
from ._sides import check_same_dim, rescale_rows
from .similarity import check_pairs

__all__ = [
    "CHUNK_QUERIES",
    "global_cosine",
    "rerank",
    "shortlist_pairs",
    "split_whole_image",
    "topk_lowest_index",
    "with_whole_image_boxes",
]


#: Queries per chunk of the global cosine matrix (bounds the temporary memory to
#: ``CHUNK_QUERIES * Nr`` float64 values per step).
CHUNK_QUERIES = 1024


def _check_global(x: np.ndarray, name: str) -> np.ndarray:
    """``x`` as a finite float64 ``(N, D)`` array with N >= 1 (clear errors otherwise)."""
    arr = np.asarray(x)
    if arr.ndim != 2:
        raise ValueError(
            f"{name} must be a (N, D) array of global descriptors (one row per "
            f"image), got shape {arr.shape}"
        )
    if arr.shape[0] < 1 or arr.shape[1] < 1:
        raise ValueError(
            f"{name} is empty (shape {arr.shape}): every image needs a global descriptor"
        )
    if not np.issubdtype(arr.dtype, np.number):
        raise ValueError(f"{name} must be numeric, got dtype {arr.dtype}")
    return check_finite(arr.astype(np.float64, copy=False), name)


def _unit(x: np.ndarray) -> np.ndarray:
    """Rows scaled to unit L2 norm, safe for any magnitude; all-zero rows stay zero."""
    x = rescale_rows(x)
    n = np.linalg.norm(x, axis=1, keepdims=True)
    return x / np.where(n > 0, n, 1.0)


def _check_k(k: int) -> int:
    return check_int(k, "shortlist k (references kept per query)", 1)


def global_cosine(global_query: np.ndarray, global_reference: np.ndarray) -> np.ndarray:
    """Cosine similarity of every query x reference pair of whole-image descriptors.

    Args:
        global_query: ``(Nq, D)`` descriptors.
        global_reference: ``(Nr, D)`` descriptors.

    Returns:
        ``(Nq, Nr)`` float64 cosines (0 for an all-zero descriptor).
    """
    q = _unit(_check_global(global_query, "global_query"))
    r = _unit(_check_global(global_reference, "global_reference"))
    check_same_dim([("global_query", q.shape[1]), ("global_reference", r.shape[1])])
    out = np.empty((q.shape[0], r.shape[0]), dtype=np.float64)
    for q0 in range(0, q.shape[0], CHUNK_QUERIES):
        np.matmul(q[q0 : q0 + CHUNK_QUERIES], r.T, out=out[q0 : q0 + CHUNK_QUERIES])
    return out


def topk_lowest_index(scores: np.ndarray, k: int) -> np.ndarray:
    """Column indices of each row's ``k`` largest scores, best first, ties by lowest index.

    Vectorised: ``argpartition`` finds each row's k-th largest value, the k winners are sorted by
    (score descending, index ascending); rows where the k-th value is tied with a value outside
    the winners (rare) are re-done with a stable full sort, so ties always go to the lowest index.

    Args:
        scores: ``(N, M)`` finite scores.
        k: winners per row, ``1 <= k <= M``.

    Returns:
        ``(N, k)`` int64 column indices.
    """
    m = scores.shape[1]
    if k >= m:
        return np.argsort(-scores, axis=1, kind="stable").astype(np.int64)
    part = np.argpartition(-scores, k - 1, axis=1)[:, :k]
    vals = np.take_along_axis(scores, part, axis=1)
    # sort the winners: primary key score (descending), secondary key index (ascending)
    order = np.lexsort((part, -vals), axis=1)
    top = np.take_along_axis(part, order, axis=1)
    kth = np.take_along_axis(scores, top[:, -1:], axis=1)
    ambiguous = np.flatnonzero((scores >= kth).sum(1) > k)
    if ambiguous.size:
        top[ambiguous] = np.argsort(-scores[ambiguous], axis=1, kind="stable")[:, :k]
    return top.astype(np.int64)


def shortlist_pairs(
    global_query: np.ndarray, global_reference: np.ndarray, k: int
) -> tuple[np.ndarray, np.ndarray]:
    """Each query's top-k references by cosine of whole-image descriptors.

    Args:
        global_query: ``(Nq, D)`` whole-image descriptors of the queries.
        global_reference: ``(Nr, D)`` whole-image descriptors of the references.
        k: references kept per query, ``k >= 1``; clipped to ``Nr`` (``k' = min(k, Nr)``).

    Returns:
        ``(pairs, global_similarity)``: ``pairs`` ``(Nq * k', 2)`` int64 ``(query, reference)``
        rows grouped by query (query 0's k' references first), each query's references in
        descending global cosine (ties: lowest index); ``global_similarity`` ``(Nq, Nr)`` float64
        cosines that chose them.

    Raises:
        ValueError: bad ``k``, shapes, dimensions, or non-finite descriptors.
    """
    k = _check_k(k)
    sim = global_cosine(global_query, global_reference)
    nq, nr = sim.shape
    kk = min(k, nr)
    top = np.empty((nq, kk), dtype=np.int64)
    for q0 in range(0, nq, CHUNK_QUERIES):
        top[q0 : q0 + CHUNK_QUERIES] = topk_lowest_index(sim[q0 : q0 + CHUNK_QUERIES], kk)
    pairs = np.stack([np.repeat(np.arange(nq, dtype=np.int64), kk), top.reshape(-1)], axis=1)
    return pairs, sim


def rerank(similarity_pairs_values: np.ndarray, pairs: np.ndarray, nq: int, nr: int) -> np.ndarray:
    """The final similarity matrix of a shortlist run: Eq. (1) on listed pairs, NaN elsewhere.

    Args:
        similarity_pairs_values: ``(P,)`` Eq. (1) similarities of ``pairs`` (as returned by
            :func:`vpr_core.matching.similarity_pairs`).
        pairs: ``(P, 2)`` int ``(query, reference)`` indices (e.g. from :func:`shortlist_pairs`).
        nq: number of queries; nr: number of references.

    Returns:
        ``(nq, nr)`` float64: the values at the listed pairs, NaN ("not ranked") elsewhere.

    Raises:
        ValueError: shapes disagree, indices out of range, non-finite values, or one pair listed
            twice with different values.
    """
    vals = np.asarray(similarity_pairs_values, dtype=np.float64)
    nq, nr = int(nq), int(nr)
    pr = check_pairs(pairs, nq, nr)
    if vals.shape != (pr.shape[0],):
        raise ValueError(
            f"similarity_pairs_values must have shape ({pr.shape[0]},) (one value "
            f"per pair), got {vals.shape}"
        )
    check_finite(vals, "similarity_pairs_values")
    out = np.full((nq, nr), np.nan, dtype=np.float64)
    out[pr[:, 0], pr[:, 1]] = vals
    if not np.array_equal(out[pr[:, 0], pr[:, 1]], vals):
        raise ValueError("a (query, reference) pair is listed twice with different values")
    return out


def _whole_image_box(image_size: tuple[int, int]) -> np.ndarray:
    """``(1, 4)`` float64 box ``(0, 0, W, H)`` of an image of size ``(H, W)``."""
    h, w = image_size
    return np.array([[0.0, 0.0, float(w), float(h)]])


def with_whole_image_boxes(boxes: dict, dataset) -> dict:
    """Landmarks with the whole-image box appended as each image's last row.

    The whole-image descriptor of a shortlist is then computed in the same encoder call as the
    landmarks (one backbone pass per image with ``pooling="roi"``) and cached in the same
    per-image store; :func:`split_whole_image` separates them again.

    Args:
        boxes: ``{"query": [(K_i, 4)], "reference": [...], ...}`` (other keys are kept).
        dataset: the :class:`~vpr_core.datasets.PlaceDataset` the boxes belong to.

    Returns:
        The same dict layout with ``(K_i + 1, 4)`` arrays.
    """
    out = dict(boxes)
    for side in SIDES:
        out[side] = [
            np.concatenate(
                [
                    np.asarray(b, dtype=np.float64).reshape(-1, 4),
                    _whole_image_box(dataset.image_size(side, i)),
                ]
            )
            for i, b in enumerate(boxes[side])
        ]
    return out


def split_whole_image(feats: dict) -> tuple[dict, dict[str, np.ndarray]]:
    """Undo :func:`with_whole_image_boxes` on descriptors.

    Args:
        feats: ``{"query": [(K_i + 1, D)], "reference": [...], "seconds": ...}``.

    Returns:
        ``(landmark feats in the same layout with (K_i, D) arrays, {side: (N, D) whole-image
        descriptors})``.
    """
    out = dict(feats)
    glob = {}
    for side in SIDES:
        out[side] = [d[:-1] for d in feats[side]]
        glob[side] = np.stack([d[-1] for d in feats[side]]).astype(np.float32)
    return out, glob
