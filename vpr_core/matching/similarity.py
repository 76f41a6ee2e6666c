"""Public matching functions: many pairs by the block engine (:class:`.core.Problem`:
:func:`similarity_matrix`, :func:`similarity_pairs`, :func:`weighted_matches`), one pair by the
float64 reference of :mod:`.pairwise` (:func:`match_landmarks`, :func:`image_similarity`,
:func:`reciprocal_matches`); the same numbers either way."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor, as_completed
from functools import partial

import numpy as np
import torch

from ..checks import check_boxes, check_finite, check_shape
from ..paper import SOFT_NMS_SIGMA
from ..utils import progress
from ._sides import LandmarkSets, check_same_dim, rescale_rows, unit_rows
from .core import BLOCK_BYTES, BlockPairs, Problem, shape_terms
from .normalise import refuse_normalise
from .pairwise import MatchResult, match_pair
from .spec import Compute, Matching, as_matching
from .weighting import (
    WEIGHTINGS,
    prepare_reference_stats,
    sample_matches,
    weighted_block,
    weighting_sample,
)
from .whiten import refuse_whiten

__all__ = [
    "check_pairs",
    "cosine_distance",
    "image_similarity",
    "match_landmarks",
    "reciprocal_matches",
    "shape_penalty",
    "similarity_matrix",
    "similarity_pairs",
    "weighted_matches",
]

#: The block engine's settings in the one-pair functions (Eq. (1) alone, a float64 matmul: only
#: its boundary check and parse are used) and in weighted_matches; made once, not per call.
_PAIR, _PAIR_MATCHING = Compute(matmul_dtype="float64"), Matching()
_DEFAULT = Compute()


def similarity_matrix(
    query_desc: LandmarkSets,
    query_boxes: LandmarkSets,
    reference_desc: LandmarkSets,
    reference_boxes: LandmarkSets,
    soft_nms_iou: float | None = None,
    sigma: float = SOFT_NMS_SIGMA,
    matching: Matching | None = None,
    compute: Compute = Compute(),
) -> np.ndarray:
    """Eq. (1) similarity of every query x reference image pair (optionally with Algorithm 4).

    The block engine (:mod:`.core`): one matmul per block of ``compute.batch_size`` queries x
    ``compute.ref_batch_size`` references; near-ties are re-decided in float64
    (:mod:`.reciprocal`), so the matches equal those of the one-pair reference
    (:mod:`.pairwise`: Eq. (1)-(2) on one page) exactly and values agree with it to ~1e-6. On
    the CPU the blocks run on ``torch.get_num_threads()`` worker threads (same bits for any
    count).

    Args:
        query_desc: sequence of ``(K_q, D)`` arrays, or one ``(Nq, K, D)`` array.
        query_boxes: sequence of ``(K_q, 4)`` ``(x, y, w, h)`` arrays, or ``(Nq, K, 4)``.
        reference_desc: sequence of ``(K_r, D)`` arrays, or ``(Nr, K, D)``.
        reference_boxes: sequence of ``(K_r, 4)`` arrays, or ``(Nr, K, 4)``.
        soft_nms_iou, sigma: Algorithm 4 (the paper's shorthand for ``Matching(soft_nms_iou,
            sigma)``).
        matching: a :class:`~.spec.Matching` (Algorithm 4 and, not in the paper, ``spatial``
            and ``weighting``; docs/DEFINITIONS.md) instead of ``soft_nms_iou``/``sigma``. With
            a weighting each term's statistics cover every reference. ``normalise`` is refused:
            it is a step on a result's whole matrix (``run_method(..., normalise=)``), and so is
            ``whiten``, a step on the database's descriptors that ``run_method`` applies.
        compute: device, block sizes, matmul precision and progress bar (:class:`~.spec.Compute`).

    Returns:
        ``(Nq, Nr)`` float64 similarities; 0 for a pair where an image has no landmark.
    """
    matching = as_matching(soft_nms_iou, sigma, matching)
    refuse_normalise(matching, "similarity_matrix")
    refuse_whiten(matching, "similarity_matrix")
    prob = Problem.build(
        query_desc,
        query_boxes,
        reference_desc,
        reference_boxes,
        matching,
        compute,
    )
    q, r = prob.q, prob.r
    out = torch.zeros((q.n, r.n), dtype=torch.float64, device=prob.dev)
    if prob.empty:  # no landmark anywhere on one side
        return out.cpu().numpy()
    prepare_reference_stats(prob, np.arange(r.n))  # two_sided: every other reference
    bq = compute.batch_size or 8
    br = compute.ref_batch_size or max(1, BLOCK_BYTES // (4 * bq * q.k * r.k))
    br = max(1, min(br, r.n))

    def task(q0: int, r0: int) -> None:
        q1, r1 = min(q0 + bq, q.n), min(r0 + br, r.n)
        out[q0:q1, r0:r1] = prob.block(slice(q0, q1), slice(r0, r1))[0]

    def weighted_task(q0: int) -> None:
        # (not in the paper) the weights need every reference: one query batch at a time
        qs, rs = slice(q0, min(q0 + bq, q.n)), slice(0, r.n)
        m = prob.chunked(qs, rs, br)
        out[qs] = weighted_block(prob, qs, rs, m, (m, rs))[0]

    if prob.matching.weighting is None:
        tasks = [partial(task, q0, r0) for q0 in range(0, q.n, bq) for r0 in range(0, r.n, br)]
    else:
        tasks = [partial(weighted_task, q0) for q0 in range(0, q.n, bq)]
    _run(prob, tasks)
    return out.cpu().numpy()


def similarity_pairs(
    query_desc: LandmarkSets,
    query_boxes: LandmarkSets,
    reference_desc: LandmarkSets,
    reference_boxes: LandmarkSets,
    pairs: np.ndarray | Sequence,
    matching: Matching = Matching(),
    compute: Compute = Compute(),
    sample: np.ndarray | None = None,
) -> np.ndarray:
    """Eq. (1) similarity of the listed (query, reference) image pairs only (e.g. a shortlist).

    Pairs are grouped by query; each query is scored against its listed references in chunks of
    ``compute.ref_batch_size`` by the same core as :func:`similarity_matrix`.

    Args:
        query_desc, query_boxes, reference_desc, reference_boxes: as :func:`similarity_matrix`.
        pairs: ``(P, 2)`` int ``(query index, reference index)``; any order, repeats allowed.
        matching: the :class:`~.spec.Matching`; a weighting takes its statistics over the
            references ``sample``.
        compute: as :func:`similarity_matrix` (``batch_size`` unused: one query at a time).
        sample: indices of the references whose cosines give the weighting statistics
            (default: :func:`~.weighting.weighting_sample`: ``contrast`` 12, ``idf`` 256).

    Returns:
        ``(P,)`` float64 similarities, in the order of ``pairs``.
    """
    refuse_normalise(matching, "similarity_pairs")
    refuse_whiten(matching, "similarity_pairs")
    prob = Problem.build(
        query_desc, query_boxes, reference_desc, reference_boxes, matching, compute
    )
    q, r = prob.q, prob.r
    pr = check_pairs(pairs, q.n, r.n)
    ids = (
        weighting_sample(r.n, matching.weighting) if sample is None else _check_sample(sample, r.n)
    )
    out = np.zeros(pr.shape[0], dtype=np.float64)
    if prob.empty or pr.shape[0] == 0:
        return out
    prepare_reference_stats(prob, ids)  # two_sided: the sample, computed once per database
    br = compute.ref_batch_size or max(1, BLOCK_BYTES // (4 * q.k * r.k))
    order = np.argsort(pr[:, 0], kind="stable")
    starts = np.flatnonzero(np.r_[True, pr[order[1:], 0] != pr[order[:-1], 0]])
    groups = np.split(order, starts[1:])

    samp = torch.from_numpy(ids).to(prob.dev)

    def task(rows: np.ndarray) -> None:
        qi = int(pr[rows[0], 0])
        if matching.weighting is not None:  # (not in the paper) statistics over the sample
            qs = slice(qi, qi + 1)
            ridx = torch.from_numpy(pr[rows, 1]).to(prob.dev)
            m = prob.chunked(qs, ridx, br)
            stats = (sample_matches(prob, qs, samp, br), samp)
            out[rows] = weighted_block(prob, qs, ridx, m, stats)[0][0].cpu().numpy()
            return
        for c0 in range(0, rows.shape[0], br):
            chunk = rows[c0 : c0 + br]
            ridx = torch.from_numpy(pr[chunk, 1]).to(prob.dev)
            out[chunk] = prob.block(slice(qi, qi + 1), ridx)[0][0].cpu().numpy()

    _run(prob, [partial(task, g) for g in groups])
    return out


def check_pairs(pairs: np.ndarray | Sequence, nq: int, nr: int) -> np.ndarray:
    """``pairs`` as an int64 ``(P, 2)`` array of valid (query, reference) indices."""
    arr = np.asarray(pairs)
    if arr.size == 0:
        return np.zeros((0, 2), dtype=np.int64)
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ValueError(
            f"pairs must be a (P, 2) array of (query index, reference index), got shape {arr.shape}"
        )
    if not np.issubdtype(arr.dtype, np.integer):
        raise ValueError(f"pairs must hold integer indices, got dtype {arr.dtype}")
    arr = arr.astype(np.int64)
    for col, n, what in ((0, nq, "query"), (1, nr, "reference")):
        bad = np.flatnonzero((arr[:, col] < 0) | (arr[:, col] >= n))
        if bad.size:
            raise ValueError(
                f"pairs[{bad[0]}] has {what} index {arr[bad[0], col]}, outside "
                f"0..{n - 1} ({n} {what} images)"
            )
    return arr


def _check_sample(sample: np.ndarray | Sequence, nr: int) -> np.ndarray:
    """``sample`` as int64 reference indices (at least one, each in ``0..nr-1``)."""
    arr = np.asarray(sample)
    if arr.ndim != 1 or arr.size == 0 or not np.issubdtype(arr.dtype, np.integer):
        raise ValueError(f"sample must be a non-empty 1-D array of reference indices, got {arr!r}")
    if arr.min() < 0 or arr.max() >= nr:
        raise ValueError(f"sample holds reference indices outside 0..{nr - 1} ({nr} references)")
    return arr.astype(np.int64)


def _run(prob: Problem, tasks: Sequence[Callable[[], None]]) -> None:
    """Run independent tasks; on a multi-core CPU, on one worker thread per torch thread.

    Each worker sets torch's intra-op threads to 1 for itself, so the small reductions after
    each matmul never wait at an OpenMP barrier; the cores are used by running different blocks
    at once. Blocks write disjoint outputs, so the result is the same for any number of workers.
    """
    show = prob.compute.show_progress
    bar = progress(range(len(tasks)), desc="similarity", unit="block") if show else None
    threads = torch.get_num_threads()
    workers = min(threads, len(tasks)) if prob.dev.type == "cpu" else 1
    try:
        if workers <= 1:
            for t in tasks:
                t()
                if bar is not None:
                    bar.update()
            return
        ex = ThreadPoolExecutor(workers, initializer=torch.set_num_threads, initargs=(1,))
        try:
            for f in as_completed([ex.submit(t) for t in tasks]):
                f.result()  # re-raises a worker's exception here
                if bar is not None:
                    bar.update()
        finally:
            ex.shutdown(wait=True, cancel_futures=True)
    finally:
        torch.set_num_threads(threads)  # MKL's thread count is process-wide
        if bar is not None:
            bar.close()


# ---- the matches of listed pairs with their database weights (the block engine) ----------
def _result(p: BlockPairs, sim: float, na: int, nb: int, weights: bool = False) -> MatchResult:
    """A :class:`MatchResult` from the core's pairs of one image pair."""
    return MatchResult(
        matches=torch.stack([p.i, p.j], dim=1).cpu().numpy().astype(np.int64),
        distances=(1.0 - p.cos).cpu().numpy(),
        shape=p.shape.cpu().numpy(),
        scores=p.score.cpu().numpy(),
        similarity=sim,
        raw_scores=p.raw.cpu().numpy(),
        n_a=na,
        n_b=nb,
        spatial_weights=p.weight.cpu().numpy(),
        weights=p.db_weight.cpu().numpy() if weights else None,
    )


def weighted_matches(
    query_desc: LandmarkSets,
    query_boxes: LandmarkSets,
    reference_desc: LandmarkSets,
    reference_boxes: LandmarkSets,
    pairs: np.ndarray | Sequence,
    matching: Matching,
    sample: np.ndarray | None = None,
) -> list[MatchResult]:
    """The matches of the listed image pairs with their database weights (not in the paper).

    The same core and statistics as :func:`similarity_pairs` (``similarity`` equals its value);
    ``weights`` holds each match's weight. An exhaustive run's statistics cover every reference:
    pass ``sample=np.arange(Nr)`` to see its weights when ``Nr`` exceeds the shortlist's sample.

    Args:
        query_desc, query_boxes, reference_desc, reference_boxes, pairs, sample: as
            :func:`similarity_pairs`; matching: a :class:`~.spec.Matching` with a ``weighting``.

    Returns:
        One :class:`MatchResult` per row of ``pairs``.
    """
    if getattr(matching, "weighting", None) is None:
        raise ValueError(
            f"weighted_matches needs Matching(weighting=one of {tuple(WEIGHTINGS)}), got "
            f"{matching!r}"
        )
    refuse_normalise(matching, "weighted_matches")
    refuse_whiten(matching, "weighted_matches")
    prob = Problem.build(
        query_desc, query_boxes, reference_desc, reference_boxes, matching, _DEFAULT
    )
    q, r = prob.q, prob.r
    pr = check_pairs(pairs, q.n, r.n)
    ids = (
        weighting_sample(r.n, matching.weighting) if sample is None else _check_sample(sample, r.n)
    )
    samp = torch.from_numpy(ids)
    br = max(1, BLOCK_BYTES // (4 * q.k * r.k))
    prepare_reference_stats(prob, ids)
    stats: dict[int, tuple] = {}
    out = []
    for qi, rj in pr.tolist():
        na, nb = int(q.count[qi]), int(r.count[rj])
        if prob.empty:
            e = np.zeros(0, dtype=np.float64)
            out.append(MatchResult(np.zeros((0, 2), np.int64), e, e, e, 0.0, e, na, nb, e, e))
            continue
        qs, ridx = slice(qi, qi + 1), torch.tensor([rj])
        if qi not in stats:
            stats[qi] = (sample_matches(prob, qs, samp, br), samp)
        sim, p = weighted_block(prob, qs, ridx, prob.matches(qs, ridx), stats[qi], keep_pairs=True)
        assert p is not None
        out.append(_result(p, float(sim[0, 0]), na, nb, weights=True))
    return out


# ---- one image pair: the float64 reference of pairwise.py --------------------------------
def match_landmarks(
    desc_a: np.ndarray | Sequence,
    boxes_a: np.ndarray | Sequence | None,
    desc_b: np.ndarray | Sequence,
    boxes_b: np.ndarray | Sequence | None,
    matching: Matching = Matching(),
) -> MatchResult:
    """Match the landmarks of two images and score them (Eq. 1-2, optional Algorithm 4), in
    float64, by the reference :func:`~.pairwise.match_pair` (the same numbers as
    :func:`similarity_matrix`).

    Args:
        desc_a: ``(Ka, D)`` descriptors of image a (query).
        boxes_a: ``(Ka, 4)`` ``(x, y, w, h)`` boxes of image a (None: sizes 0).
        desc_b: ``(Kb, D)`` descriptors of image b (reference).
        boxes_b: ``(Kb, 4)`` boxes of image b.
        matching: a :class:`~.spec.Matching` without a weighting (that needs the references:
            :func:`weighted_matches`).
    """
    refuse_normalise(matching, "match_landmarks")
    refuse_whiten(matching, "match_landmarks")
    if matching.weighting is not None:
        raise ValueError(
            f"weighting={matching.weighting!r} needs statistics over every reference, which one "
            "image pair does not have: use weighted_matches (or similarity_matrix / "
            "similarity_pairs), the block engine"
        )
    # the boundary check of every matching call (shapes, NaN / inf, box counts, dimensions)
    prob = Problem.build(
        [np.asarray(desc_a)],
        None if boxes_a is None else [np.asarray(boxes_a)],
        [np.asarray(desc_b)],
        None if boxes_b is None else [np.asarray(boxes_b)],
        _PAIR_MATCHING,
        _PAIR,
        sides=("a", "b"),
    )
    a, b = prob.q, prob.r
    desc_a_, desc_b_ = a.raw[: len(a.boxes[0])].numpy(), b.raw[: len(b.boxes[0])].numpy()
    return match_pair(desc_a_, a.boxes[0], desc_b_, b.boxes[0], matching)


def image_similarity(
    desc_a: np.ndarray | Sequence,
    boxes_a: np.ndarray | Sequence,
    desc_b: np.ndarray | Sequence,
    boxes_b: np.ndarray | Sequence,
    soft_nms_iou: float | None = None,
    sigma: float = SOFT_NMS_SIGMA,
    matching: Matching | None = None,
) -> float:
    """Eq. (1) similarity of two images (0 if one has no landmark); arguments as
    :func:`match_landmarks` and :func:`similarity_matrix`."""
    m = as_matching(soft_nms_iou, sigma, matching)
    return match_landmarks(desc_a, boxes_a, desc_b, boxes_b, m).similarity


def reciprocal_matches(desc_a: np.ndarray | Sequence, desc_b: np.ndarray | Sequence) -> np.ndarray:
    """Reciprocal nearest-neighbour matches ``(P, 2)`` int64 ``(i, j)``, sorted by ``i``.

    Args:
        desc_a: ``(Ka, D)`` descriptors; desc_b: ``(Kb, D)`` descriptors.
    """
    return match_landmarks(desc_a, None, desc_b, None).matches


def shape_penalty(boxes_a: np.ndarray | Sequence, boxes_b: np.ndarray | Sequence) -> np.ndarray:
    """Eq. (2) shape penalty ``(Ka, Kb)`` float64 of every landmark pair, in ``[1, e]``.

    Args:
        boxes_a: ``(Ka, 4)`` ``(x, y, w, h)`` boxes; boxes_b: ``(Kb, 4)`` boxes.
    """
    a = torch.from_numpy(check_boxes(boxes_a, "boxes_a"))
    b = torch.from_numpy(check_boxes(boxes_b, "boxes_b"))
    return shape_terms(a[:, None, 2], b[None, :, 2], a[:, None, 3], b[None, :, 3]).numpy()


def cosine_distance(desc_a: np.ndarray | Sequence, desc_b: np.ndarray | Sequence) -> np.ndarray:
    """Cosine distance ``1 - cos`` ``(Ka, Kb)`` float64 in ``[0, 2]`` (a zero vector: ``d = 1``).

    Args:
        desc_a: ``(Ka, D)`` descriptors; desc_b: ``(Kb, D)`` descriptors.
    """
    units = []
    for x, name in ((desc_a, "desc_a"), (desc_b, "desc_b")):
        d = check_shape(x, "K D", name, dtype=np.float64)
        u, norm = unit_rows(torch.from_numpy(rescale_rows(d)))
        check_finite(norm.numpy(), name)  # NaN / inf anywhere shows in its row's norm
        units.append(u)
    check_same_dim([("desc_a", units[0].shape[1]), ("desc_b", units[1].shape[1])])
    return 1.0 - (units[0] @ units[1].T).clamp(-1.0, 1.0).numpy()
