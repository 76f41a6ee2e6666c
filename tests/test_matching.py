"""Tests of vpr_core.matching: Eq. (1)-(2), reciprocal NN, soft-NMS, batched similarity matrix."""

from __future__ import annotations

import inspect
import math

import numpy as np
import pytest
import torch

from vpr_core.matching import (
    MatchResult,
    cosine_distance,
    image_similarity,
    match_landmarks,
    match_overlaps,
    pair_scores,
    reciprocal_matches,
    shape_penalty,
    similarity_matrix,
    similarity_pairs,
    soft_nms_scores,
)
from vpr_core.paper import SOFT_NMS_SIGMA

BOX = [0.0, 0.0, 10.0, 10.0]


def _pairwise(qd, qb, rd, rb, **kw):
    return np.array(
        [
            [image_similarity(qd[i], qb[i], rd[j], rb[j], **kw) for j in range(len(rd))]
            for i in range(len(qd))
        ]
    )


def _random_sets(rng, n, kmin, kmax, dim, ties=True):
    descs, boxes = [], []
    for _ in range(n):
        k = int(rng.integers(kmin, kmax + 1))
        d = rng.standard_normal((k, dim)).astype(np.float32)
        if ties and k > 4:
            d[1] = d[0]  # exact duplicate
            d[3] = 3.0 * d[2]  # same direction, other norm: cosine tie
        xy = rng.uniform(0, 40, (k, 2))
        wh = rng.uniform(5, 40, (k, 2))
        if k > 2:
            wh[2] = wh[1]  # equal sizes: shape penalty ties
        descs.append(d)
        boxes.append(np.concatenate([xy, wh], axis=1))
    return descs, boxes


# ------------------------------------------------------------------------------------------
# cosine distance and reciprocal matches
# ------------------------------------------------------------------------------------------


def test_cosine_distance_values_and_zero_vectors():
    a = np.array([[1.0, 0.0], [0.0, 0.0]])
    b = np.array([[1.0, 0.0], [0.0, 2.0], [-3.0, 0.0]])
    d = cosine_distance(a, b)
    assert d.shape == (2, 3)
    np.testing.assert_allclose(d[0], [0.0, 1.0, 2.0], atol=1e-12)
    np.testing.assert_allclose(d[1], [1.0, 1.0, 1.0])  # zero vector: cos defined as 0


def test_reciprocal_matches_hand_made():
    a = np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    b = np.array([[1.0, 0.1], [0.0, 1.0]])
    # cos: a0-b0 .995, a0-b1 0; a1-b0 .0995, a1-b1 1; a2-b0 .774, a2-b1 .707
    # a0->b0, b0->a0 (mutual); a1->b1, b1->a1 (mutual); a2->b0 but b0->a0 (not mutual)
    m = reciprocal_matches(a, b)
    assert m.dtype == np.int64
    np.testing.assert_array_equal(m, [[0, 0], [1, 1]])


def test_reciprocal_matches_ties_lowest_index():
    a = np.array([[1.0, 0.0], [2.0, 0.0]])  # same direction: tied cosines
    b = np.array([[1.0, 0.0], [5.0, 0.0]])
    # every row and column ties -> argmax semantics pick index 0 everywhere: only (0, 0) mutual
    np.testing.assert_array_equal(reciprocal_matches(a, b), [[0, 0]])
    # a1 -> b0 (tie with b1 -> lowest); b0 -> a0 (tie) -> a1 unmatched
    a = np.array([[0.0, 1.0], [1.0, 0.0], [1.0, 0.0]])
    b = np.array([[1.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    np.testing.assert_array_equal(reciprocal_matches(a, b), [[0, 2], [1, 0]])


def test_reciprocal_matches_empty_and_sorted():
    assert reciprocal_matches(np.zeros((0, 3)), np.ones((2, 3))).shape == (0, 2)
    rng = np.random.default_rng(1)
    m = reciprocal_matches(rng.standard_normal((30, 8)), rng.standard_normal((25, 8)))
    assert np.all(np.diff(m[:, 0]) > 0)
    assert len(np.unique(m[:, 1])) == len(m)


# ------------------------------------------------------------------------------------------
# Eq. (2) shape penalty and Eq. (1) image similarity
# ------------------------------------------------------------------------------------------


def test_shape_penalty_values():
    a = np.array([[0, 0, 10, 20], [5, 5, 10, 20]], dtype=float)
    b = np.array([[3, 3, 10, 20], [0, 0, 20, 20], [0, 0, 20, 40], [0, 0, 0, 0]], dtype=float)
    s = shape_penalty(a, b)
    assert s.shape == (2, 4)
    assert s[0, 0] == pytest.approx(1.0)  # identical size (position ignored)
    assert s[0, 1] == pytest.approx(math.exp(0.25))  # w doubled: exp(0.5 * 0.5)
    assert s[0, 2] == pytest.approx(math.exp(0.5))  # w and h doubled
    assert s[0, 3] == pytest.approx(math.e)  # against an empty box: both terms 1
    assert shape_penalty(b[3:], b[3:])[0, 0] == pytest.approx(1.0)  # 0/0 counts as 0


def test_image_similarity_by_hand_2x2():
    a = np.array([[1.0, 0.0], [0.0, 1.0]])
    b = np.array([[1.0, 0.0], [0.6, 0.8]])
    ba = np.array([BOX, BOX])
    bb = np.array([BOX, [0, 0, 20, 10]])
    # cos: a0b0 1, a0b1 .6, a1b0 0, a1b1 .8 -> matches (0,0), (1,1)
    # (0,0): d=0, s=1 -> 1;  (1,1): d=.2, s=exp(.25) -> 1 - .2 e^.25;  / sqrt(2*2)
    expected = (2.0 - 0.2 * math.exp(0.25)) / 2.0
    assert image_similarity(a, ba, b, bb) == pytest.approx(expected, abs=1e-12)
    r = match_landmarks(a, ba, b, bb)
    assert isinstance(r, MatchResult)
    np.testing.assert_array_equal(r.matches, [[0, 0], [1, 1]])
    np.testing.assert_allclose(r.distances, [0.0, 0.2], atol=1e-12)
    np.testing.assert_allclose(r.shape, [1.0, math.exp(0.25)])
    np.testing.assert_allclose(r.scores, [1.0, 1 - 0.2 * math.exp(0.25)])
    assert (r.n_a, r.n_b) == (2, 2)


def test_image_similarity_counts_unmatched_landmarks():
    a = np.array([[1.0, 0.0]])
    b = np.array([[1.0, 0.0], [-1.0, 0.0], [-1.0, 0.1]])
    bb = np.array([BOX] * 3)
    # one perfect match, na=1, nb=3 -> 1 / sqrt(3)
    assert image_similarity(a, [BOX], b, bb) == pytest.approx(1 / math.sqrt(3))
    assert image_similarity(np.zeros((0, 2)), np.zeros((0, 4)), b, bb) == 0.0


# ------------------------------------------------------------------------------------------
# Algorithm 4 (soft-NMS)
# ------------------------------------------------------------------------------------------


def test_soft_nms_scores_hand_example():
    scores = np.array([0.9, 0.8, 0.7])
    o = np.eye(3)
    o[0, 1] = o[1, 0] = 0.6
    # take 0 (0.9): pair 1 overlaps by .6 > .5 -> .8 * exp(-.36 / .5); pair 2 untouched
    # then 2 (0.7 > 0.389), then 1
    out = soft_nms_scores(scores, o, 0.5, 0.5)
    np.testing.assert_allclose(out, [0.9, 0.8 * math.exp(-0.72), 0.7])
    # overlap equal to the threshold is not "> t"
    np.testing.assert_allclose(soft_nms_scores(scores, o, 0.6), scores)
    # ties: the lowest index goes first and decays the other
    out = soft_nms_scores([0.5, 0.5], [[1.0, 0.8], [0.8, 1.0]], 0.5)
    np.testing.assert_allclose(out, [0.5, 0.5 * math.exp(-0.64 / 0.5)])


def _three_pair_example():
    # a_i = e_i; b_i = c_i e_i + sqrt(1 - c_i^2) e_3: cos(a_i, b_j) = c_i [i == j]
    c = np.array([0.9, 0.8, 0.7])
    a = np.eye(4)[:3]
    b = np.zeros((3, 4))
    b[np.arange(3), np.arange(3)] = c
    b[:, 3] = np.sqrt(1 - c**2)
    ba = np.array([[0, 0, 10, 10], [0, 2, 10, 10], [50, 50, 10, 10]], dtype=float)
    bb = np.array([[0, 0, 10, 10], [0, 0, 10, 10], [80, 80, 10, 10]], dtype=float)
    return c, a, ba, b, bb


def test_soft_nms_image_similarity_hand_example():
    c, a, ba, b, bb = _three_pair_example()
    # scores 1 - (1 - c) * 1 = c. Pairs 0 and 1: query IoU 80/120 = 2/3, reference IoU 1
    # -> overlap min = 2/3. Pair 2 overlaps nothing.
    o = match_overlaps(ba, bb, [[0, 0], [1, 1], [2, 2]])
    np.testing.assert_allclose(o[0, 1], 2 / 3)
    assert o[0, 2] == 0
    m, raw, sc = pair_scores(a, ba, b, bb, soft_nms_iou=0.5)
    np.testing.assert_array_equal(m, [[0, 0], [1, 1], [2, 2]])
    np.testing.assert_allclose(raw, c)
    np.testing.assert_allclose(sc, [0.9, 0.8 * math.exp(-(4 / 9) / 0.5), 0.7])
    assert image_similarity(a, ba, b, bb, soft_nms_iou=0.5) == pytest.approx(sc.sum() / 3)
    assert image_similarity(a, ba, b, bb, soft_nms_iou=0.7) == pytest.approx(c.sum() / 3)
    assert image_similarity(a, ba, b, bb) == pytest.approx(c.sum() / 3)
    # the reference side limits the overlap: disjoint reference boxes -> no decay
    bb2 = np.array([[0, 0, 10, 10], [40, 40, 10, 10], [80, 80, 10, 10]], dtype=float)
    assert image_similarity(a, ba, b, bb2, soft_nms_iou=0.3) == pytest.approx(c.sum() / 3)
    # sigma changes the decay
    s1 = image_similarity(a, ba, b, bb, soft_nms_iou=0.5, sigma=0.1)
    assert s1 == pytest.approx((0.9 + 0.8 * math.exp(-(4 / 9) / 0.1) + 0.7) / 3)


# ------------------------------------------------------------------------------------------
# batched similarity matrix == pairwise path
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("t", [None, 0.0, 0.2, 0.5])
def test_similarity_matrix_equals_pairwise_unequal_counts_and_ties(t):
    rng = np.random.default_rng(7)
    qd, qb = _random_sets(rng, 6, 1, 14, 48)
    rd, rb = _random_sets(rng, 7, 1, 14, 48)
    # a reference equal to a query (all landmarks match, many overlaps) and an empty query
    rd[2], rb[2] = qd[3].copy(), qb[3].copy()
    qd[5], qb[5] = np.zeros((0, 48), np.float32), np.zeros((0, 4))
    got = similarity_matrix(qd, qb, rd, rb, soft_nms_iou=t, batch_size=4, ref_batch_size=3)
    want = _pairwise(qd, qb, rd, rb, soft_nms_iou=t)
    assert got.shape == (6, 7) and got.dtype == np.float64
    np.testing.assert_allclose(got, want, atol=1e-5, rtol=0)
    assert np.all(got[5] == 0)


def test_similarity_matrix_stacked_input_and_float64_matmul():
    rng = np.random.default_rng(3)
    qd = rng.standard_normal((5, 20, 64)).astype(np.float32)
    rd = rng.standard_normal((4, 20, 64)).astype(np.float32)
    rd[1] = qd[0]
    rd[2, :10] = qd[1, :10]
    qb = np.concatenate([rng.uniform(0, 50, (5, 20, 2)), rng.uniform(10, 60, (5, 20, 2))], 2)
    rb = np.concatenate([rng.uniform(0, 50, (4, 20, 2)), rng.uniform(10, 60, (4, 20, 2))], 2)
    want = _pairwise(qd, qb, rd, rb)
    np.testing.assert_allclose(similarity_matrix(qd, qb, rd, rb), want, atol=1e-5, rtol=0)
    got64 = similarity_matrix(qd, qb, rd, rb, matmul_dtype="float64")
    np.testing.assert_allclose(got64, want, atol=1e-12, rtol=0)
    want_nms = _pairwise(qd, qb, rd, rb, soft_nms_iou=0.3)
    got_nms = similarity_matrix(list(qd), list(qb), list(rd), list(rb), soft_nms_iou=0.3)
    np.testing.assert_allclose(got_nms, want_nms, atol=1e-5, rtol=0)


def test_similarity_matrix_many_ties_discrete_descriptors():
    # descriptors from a tiny discrete set: exact ties everywhere, zero vectors included
    rng = np.random.default_rng(11)
    qd = [rng.integers(0, 2, (int(rng.integers(3, 12)), 4)).astype(np.float32) for _ in range(5)]
    rd = [rng.integers(0, 2, (int(rng.integers(3, 12)), 4)).astype(np.float32) for _ in range(6)]
    qb = [np.c_[rng.uniform(0, 9, (len(d), 2)), np.full((len(d), 2), 10.0)] for d in qd]
    rb = [np.c_[rng.uniform(0, 9, (len(d), 2)), np.full((len(d), 2), 10.0)] for d in rd]
    for t in (None, 0.3):
        np.testing.assert_allclose(
            similarity_matrix(qd, qb, rd, rb, soft_nms_iou=t),
            _pairwise(qd, qb, rd, rb, soft_nms_iou=t),
            atol=1e-5,
            rtol=0,
        )


def test_similarity_matrix_float32_near_ties_decided_in_float64():
    # b0 and b1 differ from a0's direction by amounts float32 cannot tell apart
    rng = np.random.default_rng(5)
    x = rng.standard_normal(256)
    v = rng.standard_normal(256)
    b = np.stack([x + 3e-4 * v, x + 1e-5 * v, -x])  # 1 - cos: ~4.5e-8 vs ~5e-11
    a = np.stack([x, -x + 0.01 * v])
    boxes_a, boxes_b = np.array([BOX] * 2), np.array([BOX] * 3)
    m = reciprocal_matches(a, b)
    assert [0, 1] in m.tolist()
    want = image_similarity(a, boxes_a, b, boxes_b)
    got = similarity_matrix([a], [boxes_a], [b], [boxes_b])
    assert got[0, 0] == pytest.approx(want, abs=1e-6)


def test_similarity_matrix_bad_inputs():
    d = [np.ones((3, 8))]
    bx = [np.ones((3, 4))]
    with pytest.raises(ValueError, match="images"):
        similarity_matrix(d, bx + bx, d, bx)
    with pytest.raises(ValueError, match="dimensions differ"):
        similarity_matrix(d, bx, [np.ones((3, 9))], bx)
    with pytest.raises(ValueError, match="boxes"):
        similarity_matrix(d, [np.ones((2, 4))], d, bx)
    with pytest.raises(ValueError, match=r"\(K, 4\)"):
        similarity_matrix(d, [np.ones((3, 3))], d, bx)
    with pytest.raises(ValueError, match="NaN"):
        similarity_matrix([np.full((3, 8), np.nan)], bx, d, bx)
    with pytest.raises(ValueError, match="mixes"):
        similarity_matrix([np.ones((3, 8)), np.ones((3, 7))], bx + bx, d, bx)
    with pytest.raises(ValueError, match="soft_nms_iou"):
        similarity_matrix(d, bx, d, bx, soft_nms_iou=1.5)
    with pytest.raises(ValueError, match="sigma"):
        similarity_matrix(d, bx, d, bx, soft_nms_iou=0.5, sigma=0)
    with pytest.raises(ValueError, match="empty"):
        similarity_matrix([], [], d, bx)


def test_pairwise_bad_inputs():
    with pytest.raises(ValueError, match="dimensions differ"):
        image_similarity(np.ones((2, 3)), np.ones((2, 4)), np.ones((2, 4)), np.ones((2, 4)))
    with pytest.raises(ValueError, match="boxes"):
        image_similarity(np.ones((2, 3)), np.ones((3, 4)), np.ones((2, 3)), np.ones((2, 4)))
    with pytest.raises(ValueError, match="negative"):
        shape_penalty(np.array([[0, 0, -1, 2.0]]), np.ones((1, 4)))
    with pytest.raises(ValueError, match=r"\(K, D\)"):
        reciprocal_matches(np.ones(3), np.ones((2, 3)))
    with pytest.raises(ValueError, match="overlaps"):
        soft_nms_scores([1.0, 2.0], np.eye(3), 0.5)


# ------------------------------------------------------------------------------------------
# threads, devices, defaults
# ------------------------------------------------------------------------------------------


def test_similarity_matrix_same_bits_for_any_thread_count():
    rng = np.random.default_rng(13)
    qd, qb = _random_sets(rng, 20, 1, 30, 32)
    rd, rb = _random_sets(rng, 9, 1, 30, 32)
    threads = torch.get_num_threads()
    try:
        torch.set_num_threads(1)
        one = similarity_matrix(qd, qb, rd, rb, batch_size=3, show_progress=False)
        assert torch.get_num_threads() == 1
        torch.set_num_threads(2)
        two = similarity_matrix(qd, qb, rd, rb, batch_size=3, show_progress=False)
        assert torch.get_num_threads() == 2  # the workers' thread setting does not leak
    finally:
        torch.set_num_threads(threads)
    np.testing.assert_array_equal(one, two)
    np.testing.assert_allclose(two, _pairwise(qd, qb, rd, rb), atol=1e-5, rtol=0)


def test_soft_nms_sigma_default_is_the_papers():
    for fn in (
        image_similarity,
        match_landmarks,
        soft_nms_scores,
        similarity_matrix,
        similarity_pairs,
    ):
        assert inspect.signature(fn).parameters["sigma"].default == SOFT_NMS_SIGMA


@pytest.mark.skipif(torch.cuda.is_available(), reason="checks the no-GPU message")
def test_cuda_without_gpu_is_a_clear_error():
    d, bx = [np.ones((3, 8))], [np.ones((3, 4))]
    with pytest.raises(ValueError, match="no CUDA GPU"):
        similarity_matrix(d, bx, d, bx, device="cuda")


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA GPU")
@pytest.mark.parametrize("t", [None, 0.3])
def test_cuda_equals_pairwise(t):
    rng = np.random.default_rng(17)
    qd, qb = _random_sets(rng, 6, 1, 20, 48)
    rd, rb = _random_sets(rng, 7, 1, 20, 48)
    want = _pairwise(qd, qb, rd, rb, soft_nms_iou=t)
    got = similarity_matrix(qd, qb, rd, rb, soft_nms_iou=t, device="cuda")
    np.testing.assert_allclose(got, want, atol=1e-5, rtol=0)
    pairs = np.array([[0, 1], [5, 6], [2, 2]])
    got_p = similarity_pairs(qd, qb, rd, rb, pairs, soft_nms_iou=t, device="cuda")
    np.testing.assert_allclose(got_p, want[pairs[:, 0], pairs[:, 1]], atol=1e-5, rtol=0)


# ------------------------------------------------------------------------------------------
# similarity_pairs (shortlist re-ranking)
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("t", [None, 0.3])
def test_similarity_pairs_equals_pairwise(t):
    rng = np.random.default_rng(19)
    qd, qb = _random_sets(rng, 7, 1, 16, 40)
    rd, rb = _random_sets(rng, 9, 1, 16, 40)
    rd[4], rb[4] = qd[2].copy(), qb[2].copy()
    qd[6], qb[6] = np.zeros((0, 40), np.float32), np.zeros((0, 4))
    want = _pairwise(qd, qb, rd, rb, soft_nms_iou=t)
    # unsorted, repeated, several references per query (chunks of 2), an empty query
    pairs = np.array(
        [[3, 1], [0, 4], [2, 4], [0, 0], [3, 8], [2, 4], [6, 1], [0, 7], [0, 2], [5, 5]]
    )
    got = similarity_pairs(
        qd, qb, rd, rb, pairs, soft_nms_iou=t, ref_batch_size=2, show_progress=False
    )
    assert got.shape == (10,) and got.dtype == np.float64
    np.testing.assert_allclose(got, want[pairs[:, 0], pairs[:, 1]], atol=1e-5, rtol=0)
    full = similarity_matrix(qd, qb, rd, rb, soft_nms_iou=t, show_progress=False)
    np.testing.assert_allclose(got, full[pairs[:, 0], pairs[:, 1]], atol=1e-6, rtol=0)
    assert got[6] == 0.0


def test_similarity_pairs_shortlist_of_every_query():
    rng = np.random.default_rng(23)
    qd = rng.standard_normal((12, 30, 64)).astype(np.float32)
    rd = rng.standard_normal((15, 30, 64)).astype(np.float32)
    qb = np.concatenate([rng.uniform(0, 50, (12, 30, 2)), rng.uniform(10, 60, (12, 30, 2))], 2)
    rb = np.concatenate([rng.uniform(0, 50, (15, 30, 2)), rng.uniform(10, 60, (15, 30, 2))], 2)
    top = np.argsort(-rng.random((12, 15)), axis=1)[:, :4]
    pairs = np.stack([np.repeat(np.arange(12), 4), top.ravel()], axis=1)
    full = similarity_matrix(qd, qb, rd, rb, show_progress=False)
    got = similarity_pairs(qd, qb, rd, rb, pairs, show_progress=False)
    np.testing.assert_allclose(got, full[pairs[:, 0], pairs[:, 1]], atol=1e-6, rtol=0)


def test_similarity_pairs_bad_pairs():
    d, bx = [np.ones((3, 8))] * 2, [np.ones((3, 4))] * 2
    assert similarity_pairs(d, bx, d, bx, np.zeros((0, 2), int)).shape == (0,)
    with pytest.raises(ValueError, match=r"\(P, 2\)"):
        similarity_pairs(d, bx, d, bx, np.array([0, 1]))
    with pytest.raises(ValueError, match="integer"):
        similarity_pairs(d, bx, d, bx, np.array([[0.0, 1.0]]))
    with pytest.raises(ValueError, match="reference index 2, outside 0..1"):
        similarity_pairs(d, bx, d, bx, np.array([[0, 1], [1, 2]]))
    with pytest.raises(ValueError, match="query index -1"):
        similarity_pairs(d, bx, d, bx, np.array([[-1, 0]]))
