"""Matching on a Dask cluster: the core's block plan (:func:`vpr_core.plan_blocks`) run as
tasks, equal to the in-process call exactly (why each task carries the widest image of each
side: docs/DISTRIBUTED.md)."""

from __future__ import annotations

import numpy as np

from vpr_core import Matching, checks, plan_blocks, similarity_matrix, similarity_pairs

from .client import gather_in_order

__all__ = ["similarity_blocks_distributed", "similarity_pairs_distributed"]


def _run_plan(client, plan, what: str) -> np.ndarray:
    """Scatter the plan's shared parts once and its tasks' query blocks, run every task, and
    assemble the output."""
    shared = [
        client.scatter(part, broadcast=wide, hash=False)
        for part, wide in zip(plan.shared, plan.broadcast, strict=True)
    ]
    futures = [
        client.submit(
            plan.run,
            client.scatter(task, hash=False),
            [shared[i] for i in task.shared],
            plan.matching,
            pure=False,
        )
        for task in plan.tasks
    ]
    return plan.assemble(gather_in_order(client, futures, what))


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
            :func:`vpr_core.similarity_matrix`.
        matching: the :class:`vpr_core.Matching`; with a weighting each task holds every
            reference, so its statistics are the in-process ones.
        block_queries: queries per task (rounded up to a multiple of 8).

    Returns:
        ``(Nq, Nr)`` float64, equal to the in-process ``similarity_matrix`` exactly.
    """
    bq = checks.check_int(block_queries, "block_queries", 1)
    plan = plan_blocks(
        query_desc, query_boxes, reference_desc, reference_boxes, matching, None, (bq, 8)
    )
    if client is None:
        return similarity_matrix(
            query_desc, query_boxes, reference_desc, reference_boxes, matching=matching
        )
    return _run_plan(client, plan, "similarity (dask)")


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
    needs and runs :func:`vpr_core.similarity_pairs` on them.

    Args:
        client: a ``dask.distributed.Client``, or None: one in-process ``similarity_pairs``.
        query_desc, query_boxes, reference_desc, reference_boxes: as
            :func:`similarity_blocks_distributed`.
        pairs: ``(P, 2)`` int ``(query, reference)`` indices, any order, repeats allowed.
        matching: the :class:`vpr_core.Matching`; with a weighting the references of its
            statistics are scattered once to every worker.
        blocks: queries per task and references per scattered block (each rounded up to a
            multiple of 8).

    Returns:
        ``(P,)`` float64 in the order of ``pairs``, equal to the in-process result exactly.
    """
    if client is None:
        return similarity_pairs(
            query_desc, query_boxes, reference_desc, reference_boxes, pairs, matching
        )
    plan = plan_blocks(
        query_desc, query_boxes, reference_desc, reference_boxes, matching, pairs, blocks
    )
    return _run_plan(client, plan, "shortlist (dask)")
