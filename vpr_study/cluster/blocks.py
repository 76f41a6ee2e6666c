"""Matching on a Dask cluster: query blocks scored by the in-process core, equal to it exactly
(why each task carries the widest image of each side: docs/DISTRIBUTED.md)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from vpr_core import checks
from vpr_core.matching import (
    Compute,
    Matching,
    check_pairs,
    landmark_lists,
    similarity_matrix,
    similarity_pairs,
    weighting_sample,
)

from .client import gather_in_order

__all__ = ["QUERY_BATCH", "similarity_blocks_distributed", "similarity_pairs_distributed"]

#: Query batch of :func:`vpr_core.matching.similarity_matrix` (its ``batch_size`` default).
QUERY_BATCH = 8
#: The tasks' block settings (no progress bar on a worker).
_MATRIX_TASK = Compute(batch_size=QUERY_BATCH, show_progress=False)
_PAIRS_TASK = Compute(show_progress=False)


@dataclass(frozen=True)
class _Part:
    """Landmark sets of some images, scattered as ONE object (a bare tuple or list would be
    scattered element by element)."""

    desc: list
    boxes: list


def _block_size(n: Any, name: str) -> int:
    """``n`` as a positive int, rounded up to a multiple of :data:`QUERY_BATCH`."""
    return -(-checks.check_int(n, name, 1) // QUERY_BATCH) * QUERY_BATCH


def _widest(desc: list) -> int:
    """Index of the first image with the most landmarks."""
    return int(np.argmax([np.shape(d)[0] if np.ndim(d) == 2 else 0 for d in desc]))


def _query_part(qd: list, qb: list, q0: int, q1: int, wide: int) -> _Part:
    """Queries ``q0:q1`` plus the widest query (last; its results are dropped)."""
    return _Part(qd[q0:q1] + [qd[wide]], qb[q0:q1] + [qb[wide]])


def _matrix_task(qpart: _Part, refs: _Part, matching: Matching) -> np.ndarray:
    """Task: Eq. (1) of a query block x all references; ``(bq, Nr)`` (extra row dropped)."""
    out = similarity_matrix(
        qpart.desc, qpart.boxes, refs.desc, refs.boxes, matching=matching, compute=_MATRIX_TASK
    )
    return out[:-1]


def similarity_blocks_distributed(
    client,
    query_desc,
    query_boxes,
    reference_desc,
    reference_boxes,
    matching: Matching = Matching(),
    block_queries: int = 128,
) -> np.ndarray:
    """Exhaustive Eq. (1) matrix as Dask tasks over query blocks.

    The reference side is scattered once to every worker (each worker holds
    ``Nr * K * D * 4`` bytes of it); each task scores one block of queries against it.

    Args:
        client: a ``dask.distributed.Client``, or None: one in-process ``similarity_matrix``.
        query_desc, query_boxes, reference_desc, reference_boxes: sequences of ``(K_i, D)`` /
            ``(K_i, 4)`` arrays (or stacked ``(N, K, D)`` / ``(N, K, 4)``), as
            :func:`~vpr_core.matching.similarity_matrix`.
        matching: the :class:`~vpr_core.matching.Matching`; with a weighting each task holds
            every reference, so its statistics are the in-process ones.
        block_queries: queries per task (rounded up to a multiple of 8).

    Returns:
        ``(Nq, Nr)`` float64, equal to the in-process ``similarity_matrix`` exactly.
    """
    bq = _block_size(block_queries, "block_queries")
    if client is None:
        return similarity_matrix(
            query_desc, query_boxes, reference_desc, reference_boxes, matching=matching
        )
    qd, qb = landmark_lists(query_desc, query_boxes, "query")
    rd, rb = landmark_lists(reference_desc, reference_boxes, "reference")
    wide = _widest(qd)
    refs = client.scatter(_Part(rd, rb), broadcast=True, hash=False)
    starts = list(range(0, len(qd), bq))
    futures = []
    for q0 in starts:
        part = client.scatter(_query_part(qd, qb, q0, q0 + bq, wide), hash=False)
        futures.append(client.submit(_matrix_task, part, refs, matching, pure=False))
    out = np.empty((len(qd), len(rd)), dtype=np.float64)
    for q0, block in zip(
        starts, gather_in_order(client, futures, "similarity (dask)"), strict=False
    ):
        out[q0 : q0 + bq] = block
    return out


def _pairs_task(
    qpart: _Part,
    rblocks: list[_Part],
    rstarts: list[int],
    ref_ids: np.ndarray,
    wide_ref: _Part,
    local_pairs: np.ndarray,
    matching: Matching,
    sample: _Part | None = None,
) -> np.ndarray:
    """Task: Eq. (1) of listed pairs; ``local_pairs`` index ``qpart`` and ``ref_ids``.

    With a weighting, ``sample`` holds the references of its statistics (appended after the
    listed ones, in their global order)."""
    rd, rb = [], []
    for j in ref_ids:
        b = int(np.searchsorted(rstarts, j, side="right")) - 1
        rd.append(rblocks[b].desc[j - rstarts[b]])
        rb.append(rblocks[b].boxes[j - rstarts[b]])
    local_sample = None
    if sample is not None:
        local_sample = np.arange(len(rd), len(rd) + len(sample.desc))
        rd, rb = rd + sample.desc, rb + sample.boxes
    return similarity_pairs(
        qpart.desc,
        qpart.boxes,
        rd + wide_ref.desc,
        rb + wide_ref.boxes,
        local_pairs,
        matching,
        _PAIRS_TASK,
        local_sample,
    )


def similarity_pairs_distributed(
    client,
    query_desc,
    query_boxes,
    reference_desc,
    reference_boxes,
    pairs: np.ndarray,
    matching: Matching = Matching(),
    blocks: tuple[int, int] = (128, 512),
) -> np.ndarray:
    """Eq. (1) of listed pairs (a shortlist) as Dask tasks over query blocks.

    Reference blocks are scattered once; a query block's task receives only the reference
    blocks its pairs touch (along a route, a few neighbouring blocks), picks the references it
    needs and runs :func:`vpr_core.matching.similarity_pairs` on them.

    Args:
        client: a ``dask.distributed.Client``, or None: one in-process ``similarity_pairs``.
        query_desc, query_boxes, reference_desc, reference_boxes: as
            :func:`similarity_blocks_distributed`.
        pairs: ``(P, 2)`` int ``(query, reference)`` indices, any order, repeats allowed.
        matching: the :class:`~vpr_core.matching.Matching`; with a weighting the references of
            its statistics (:func:`~vpr_core.matching.weighting.weighting_sample`) are scattered
            once to every worker.
        blocks: queries per task and references per scattered block (each rounded up to a
            multiple of 8).

    Returns:
        ``(P,)`` float64 in the order of ``pairs``, equal to the in-process result exactly.
    """
    bq = _block_size(blocks[0], "blocks[0] (queries per task)")
    br = _block_size(blocks[1], "blocks[1] (references per block)")
    if client is None:
        return similarity_pairs(
            query_desc, query_boxes, reference_desc, reference_boxes, pairs, matching
        )
    if matching.weighting == "two_sided":  # a task holds a few references, not the database
        raise ValueError(
            "weighting='two_sided' with a shortlist runs in-process only (its reference "
            "statistics need the whole database): run without a Dask scheduler"
        )
    qd, qb = landmark_lists(query_desc, query_boxes, "query")
    rd, rb = landmark_lists(reference_desc, reference_boxes, "reference")
    pr = check_pairs(pairs, len(qd), len(rd))
    if pr.shape[0] == 0:
        return np.zeros(0, dtype=np.float64)
    wide_q, wide_r = _widest(qd), _widest(rd)
    wide_ref = client.scatter(_Part([rd[wide_r]], [rb[wide_r]]), broadcast=True, hash=False)
    rstarts = list(range(0, len(rd), br))
    rfut = [client.scatter(_Part(rd[s : s + br], rb[s : s + br]), hash=False) for s in rstarts]
    sample = None
    if matching.weighting is not None:
        ids = weighting_sample(len(rd), matching.weighting).tolist()
        part = _Part([rd[j] for j in ids], [rb[j] for j in ids])
        sample = client.scatter(part, broadcast=True, hash=False)
    futures, rows_of = [], []
    for q0 in range(0, len(qd), bq):
        rows = np.flatnonzero((pr[:, 0] >= q0) & (pr[:, 0] < q0 + bq))
        if rows.size == 0:
            continue
        ref_ids, local_r = np.unique(pr[rows, 1], return_inverse=True)
        touched = sorted({int(j) // br for j in ref_ids})
        local = np.stack([pr[rows, 0] - q0, local_r.reshape(-1)], axis=1)
        part = client.scatter(_query_part(qd, qb, q0, q0 + bq, wide_q), hash=False)
        futures.append(
            client.submit(
                _pairs_task,
                part,
                [rfut[b] for b in touched],
                [rstarts[b] for b in touched],
                ref_ids,
                wide_ref,
                local,
                matching,
                sample,
                pure=False,
            )
        )
        rows_of.append(rows)
    out = np.empty(pr.shape[0], dtype=np.float64)
    for rows, vals in zip(
        rows_of, gather_in_order(client, futures, "shortlist (dask)"), strict=False
    ):
        out[rows] = vals
    return out
