"""Eq. (1) in blocks of query rows for an executor that runs them elsewhere (a Dask cluster):
:func:`plan_blocks` splits a call into tasks and the parts they share, :meth:`BlockPlan.run`
scores one task; the rows equal the in-process call exactly (docs/DISTRIBUTED.md)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..checks import check_int
from ._sides import LandmarkSets, landmark_lists
from .similarity import check_pairs, similarity_matrix, similarity_pairs
from .spec import Compute, Matching
from .weighting import WEIGHTINGS, weighting_sample

__all__ = ["QUERY_BATCH", "BlockPlan", "Part", "Task", "plan_blocks"]

#: Query batch of :func:`~.similarity.similarity_matrix` (its ``batch_size`` default): a task's
#: queries are a multiple of it, so its blocks are the in-process ones.
QUERY_BATCH = 8
#: The tasks' block settings (no progress bar on a worker).
_MATRIX_TASK = Compute(batch_size=QUERY_BATCH, show_progress=False)
_PAIRS_TASK = Compute(show_progress=False)


@dataclass(frozen=True)
class Part:
    """The landmark sets of some images (an executor ships it as ONE object)."""

    desc: list
    boxes: list


@dataclass(frozen=True)
class Task:
    """One block of query rows. ``queries``: the block's queries and, last, the widest query of
    the call (its row is dropped: each task pads as the whole call pads). ``shared``: indices of
    :attr:`BlockPlan.shared` it reads. Listed pairs only: ``ref_starts`` (first reference of each
    shared reference block), ``ref_ids`` (the references it scores) and ``pairs`` (local
    ``(query, reference)`` indices)."""

    rows: np.ndarray
    queries: Part
    shared: tuple[int, ...]
    ref_starts: tuple[int, ...] = ()
    ref_ids: np.ndarray | None = None
    pairs: np.ndarray | None = None


@dataclass(frozen=True)
class BlockPlan:
    """A call split into :class:`Task` s: ``shared`` parts (``broadcast``: every worker holds
    it), the tasks, and the output's ``size`` (``(Nq, Nr)`` matrix or ``(P,)`` pairs)."""

    matching: Matching
    size: tuple[int, ...]
    shared: list[Part]
    broadcast: list[bool]
    tasks: list[Task]
    exhaustive: bool

    @staticmethod
    def run(task: Task, shared: Sequence[Part], matching: Matching) -> np.ndarray:
        """Score one task (on a worker): its rows of the matrix, or its pairs' values, equal to
        the in-process call's. ``shared``: the plan's parts ``task.shared`` names, in order."""
        q = task.queries
        if task.pairs is None:  # all references: one matrix block, the widest query's row dropped
            refs = shared[0]
            out = similarity_matrix(
                q.desc, q.boxes, refs.desc, refs.boxes, matching=matching, compute=_MATRIX_TASK
            )
            return out[:-1]
        n = len(task.ref_starts)
        blocks, wide_ref, sample = shared[:n], shared[n], shared[n + 1 :]
        rd, rb = [], []
        assert task.ref_ids is not None
        for j in task.ref_ids:
            b = int(np.searchsorted(task.ref_starts, j, side="right")) - 1
            rd.append(blocks[b].desc[j - task.ref_starts[b]])
            rb.append(blocks[b].boxes[j - task.ref_starts[b]])
        local_sample = None
        if sample:  # the references of the weighting's statistics, after the listed ones
            local_sample = np.arange(len(rd), len(rd) + len(sample[0].desc))
            rd, rb = rd + sample[0].desc, rb + sample[0].boxes
        return similarity_pairs(
            q.desc,
            q.boxes,
            rd + wide_ref.desc,
            rb + wide_ref.boxes,
            task.pairs,
            matching,
            _PAIRS_TASK,
            local_sample,
        )

    def assemble(self, outputs: Sequence[np.ndarray]) -> np.ndarray:
        """The call's output from each task's (in the order of :attr:`tasks`)."""
        out = np.empty(self.size, dtype=np.float64)
        for task, values in zip(self.tasks, outputs, strict=True):
            out[task.rows] = values
        return out


def _block_size(n: int, name: str) -> int:
    """``n`` as a positive int, rounded up to a multiple of :data:`QUERY_BATCH`."""
    return -(-check_int(n, name, 1) // QUERY_BATCH) * QUERY_BATCH


def _widest(desc: list) -> int:
    """Index of the first image with the most landmarks."""
    return int(np.argmax([np.shape(d)[0] if np.ndim(d) == 2 else 0 for d in desc]))


def _query_part(qd: list, qb: list, q0: int, q1: int, wide: int) -> Part:
    """Queries ``q0:q1`` plus the widest query (last; its results are dropped)."""
    return Part(qd[q0:q1] + [qd[wide]], qb[q0:q1] + [qb[wide]])


def plan_blocks(
    query_desc: LandmarkSets,
    query_boxes: LandmarkSets,
    reference_desc: LandmarkSets,
    reference_boxes: LandmarkSets,
    matching: Matching = Matching(),
    pairs: np.ndarray | Sequence | None = None,
    blocks: tuple[int, int] = (128, 512),
) -> BlockPlan:
    """Split Eq. (1) of every pair (``pairs`` None) or of listed pairs into tasks of query rows.

    Exhaustive: each task scores a block of queries against every reference (one shared part,
    on every worker). Listed pairs: the references are shared in blocks, each task reads only
    the blocks its pairs touch, plus the widest reference and, with a weighting, the references
    of its statistics (:func:`~.weighting.weighting_sample`, on every worker).

    Args:
        query_desc, query_boxes, reference_desc, reference_boxes: as
            :func:`~.similarity.similarity_matrix`.
        matching: the :class:`~.spec.Matching` (a weighting with a reference side, as
            ``two_sided``, needs the whole database: listed pairs of it are refused).
        pairs: None, or ``(P, 2)`` int ``(query, reference)`` indices (any order, repeats).
        blocks: queries per task and references per shared block (each rounded up to a
            multiple of :data:`QUERY_BATCH`).
    """
    bq = _block_size(blocks[0], "blocks[0] (queries per task)")
    br = _block_size(blocks[1], "blocks[1] (references per block)")
    qd, qb = landmark_lists(query_desc, query_boxes, "query")
    rd, rb = landmark_lists(reference_desc, reference_boxes, "reference")
    wide_q = _widest(qd)
    if pairs is None:
        tasks = [
            Task(
                np.arange(q0, min(q0 + bq, len(qd))), _query_part(qd, qb, q0, q0 + bq, wide_q), (0,)
            )
            for q0 in range(0, len(qd), bq)
        ]
        return BlockPlan(matching, (len(qd), len(rd)), [Part(rd, rb)], [True], tasks, True)
    if matching.weighting is not None and WEIGHTINGS[matching.weighting].reference_side:
        raise ValueError(
            f"weighting={matching.weighting!r} with a shortlist runs in-process only (its "
            "reference statistics need the whole database): run without a Dask scheduler"
        )
    pr = check_pairs(pairs, len(qd), len(rd))
    wide_r = _widest(rd) if rd else 0
    starts = list(range(0, len(rd), br))
    shared = [Part(rd[s : s + br], rb[s : s + br]) for s in starts]
    broadcast = [False] * len(shared)
    shared.append(Part([rd[wide_r]], [rb[wide_r]]) if rd else Part([], []))
    broadcast.append(True)
    extra: tuple[int, ...] = ()
    if matching.weighting is not None:
        ids = weighting_sample(len(rd), matching.weighting).tolist()
        shared.append(Part([rd[j] for j in ids], [rb[j] for j in ids]))
        broadcast.append(True)
        extra = (len(shared) - 1,)
    tasks = []
    for q0 in range(0, len(qd), bq):
        rows = np.flatnonzero((pr[:, 0] >= q0) & (pr[:, 0] < q0 + bq))
        if rows.size == 0:
            continue
        ref_ids, local_r = np.unique(pr[rows, 1], return_inverse=True)
        touched = sorted({int(j) // br for j in ref_ids})
        local = np.stack([pr[rows, 0] - q0, local_r.reshape(-1)], axis=1)
        tasks.append(
            Task(
                rows,
                _query_part(qd, qb, q0, q0 + bq, wide_q),
                (*touched, len(starts), *extra),
                tuple(starts[b] for b in touched),
                ref_ids,
                local,
            )
        )
    return BlockPlan(matching, (pr.shape[0],), shared, broadcast, tasks, False)
