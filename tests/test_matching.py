"""Tests of vpr_core.matching: the torch core against the NumPy oracle (oracle_pairwise.py)."""

from __future__ import annotations

import inspect
import math

import numpy as np
import oracle_pairwise as oracle
import pytest
import torch

from vpr_core.matching import (
    Compute,
    Matching,
    cosine_distance,
    image_similarity,
    match_landmarks,
    reciprocal_matches,
    shape_penalty,
    similarity_matrix,
    similarity_pairs,
)
from vpr_core.matching.pairwise import MatchResult
from vpr_core.paper import SOFT_NMS_SIGMA

BOX = [0.0, 0.0, 10.0, 10.0]


def _pairwise(qd, qb, rd, rb, **kw):
    """The oracle's Eq. (1) matrix."""
    return np.array(
        [
            [oracle.image_similarity(qd[i], qb[i], rd[j], rb[j], **kw) for j in range(len(rd))]
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
    assert s.shape == (2, 4) and s.dtype == np.float64
    assert s[0, 0] == pytest.approx(1.0)  # identical size (position ignored)
    assert s[0, 1] == pytest.approx(math.exp(0.25))  # w doubled: exp(0.5 * 0.5)
    assert s[0, 2] == pytest.approx(math.exp(0.5))  # w and h doubled
    assert s[0, 3] == pytest.approx(math.e)  # against an empty box: both terms 1
    assert shape_penalty(b[3:], b[3:])[0, 0] == pytest.approx(1.0)  # 0/0 counts as 0
    np.testing.assert_allclose(s, oracle.shape_penalty(a, b), rtol=1e-15)


def test_image_similarity_by_hand_2x2():
    a = np.array([[1.0, 0.0], [0.0, 1.0]])
    b = np.array([[1.0, 0.0], [0.6, 0.8]])
    ba = np.array([BOX, BOX])
    bb = np.array([BOX, [0, 0, 20, 10]])
    # cos: a0b0 1, a0b1 .6, a1b0 0, a1b1 .8 -> matches (0,0), (1,1)
    # (0,0): d=0, s=1 -> 1;  (1,1): d=.2, s=exp(.25) -> 1 - .2 e^.25;  / sqrt(2*2)
    expected = (2.0 - 0.2 * math.exp(0.25)) / 2.0
    assert image_similarity(a, ba, b, bb) == pytest.approx(expected, abs=1e-12)
    assert oracle.image_similarity(a, ba, b, bb) == pytest.approx(expected, abs=1e-12)
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
    r = match_landmarks(np.zeros((0, 2)), np.zeros((0, 4)), b, bb)
    assert r.matches.shape == (0, 2) and (r.n_a, r.n_b) == (0, 3) and r.similarity == 0.0


# ------------------------------------------------------------------------------------------
# Algorithm 4 (soft-NMS)
# ------------------------------------------------------------------------------------------


def test_oracle_soft_nms_hand_example():
    scores = np.array([0.9, 0.8, 0.7])
    o = np.eye(3)
    o[0, 1] = o[1, 0] = 0.6
    # take 0 (0.9): pair 1 overlaps by .6 > .5 -> .8 * exp(-.36 / .5); pair 2 untouched
    # then 2 (0.7 > 0.389), then 1
    out = oracle.soft_nms_scores(scores, o, 0.5, 0.5)
    np.testing.assert_allclose(out, [0.9, 0.8 * math.exp(-0.72), 0.7])
    # overlap equal to the threshold is not "> t"
    np.testing.assert_allclose(oracle.soft_nms_scores(scores, o, 0.6), scores)
    # ties: the lowest index goes first and decays the other
    out = oracle.soft_nms_scores([0.5, 0.5], [[1.0, 0.8], [0.8, 1.0]], 0.5)
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
    o = oracle.match_overlaps(ba, bb, [[0, 0], [1, 1], [2, 2]])
    np.testing.assert_allclose(o[0, 1], 2 / 3)
    assert o[0, 2] == 0
    r = match_landmarks(a, ba, b, bb, matching=Matching(soft_nms_iou=0.5))
    want = [0.9, 0.8 * math.exp(-(4 / 9) / 0.5), 0.7]
    np.testing.assert_array_equal(r.matches, [[0, 0], [1, 1], [2, 2]])
    np.testing.assert_allclose(r.raw_scores, c)
    np.testing.assert_allclose(r.scores, want)
    assert image_similarity(a, ba, b, bb, soft_nms_iou=0.5) == pytest.approx(sum(want) / 3)
    assert image_similarity(a, ba, b, bb, soft_nms_iou=0.7) == pytest.approx(c.sum() / 3)
    assert image_similarity(a, ba, b, bb) == pytest.approx(c.sum() / 3)
    # the reference side limits the overlap: disjoint reference boxes -> no decay
    bb2 = np.array([[0, 0, 10, 10], [40, 40, 10, 10], [80, 80, 10, 10]], dtype=float)
    assert image_similarity(a, ba, b, bb2, soft_nms_iou=0.3) == pytest.approx(c.sum() / 3)
    # sigma changes the decay
    s1 = image_similarity(a, ba, b, bb, soft_nms_iou=0.5, sigma=0.1)
    assert s1 == pytest.approx((0.9 + 0.8 * math.exp(-(4 / 9) / 0.1) + 0.7) / 3)
    # the core's 1 x 1 case and its many-pair case agree with the oracle
    for t in (None, 0.5, 0.7):
        want_s = oracle.image_similarity(a, ba, b, bb, soft_nms_iou=t)
        assert similarity_matrix([a], [ba], [b], [bb], soft_nms_iou=t)[0, 0] == pytest.approx(
            want_s, abs=1e-6
        )


@pytest.mark.parametrize("t", [None, 0.0, 0.3])
def test_match_landmarks_equals_oracle_pair_by_pair(t):
    rng = np.random.default_rng(29)
    qd, qb = _random_sets(rng, 8, 0, 25, 32)
    rd, rb = _random_sets(rng, 8, 1, 25, 32)
    rd[3], rb[3] = qd[2].copy(), qb[2].copy()  # all landmarks match, many overlaps
    for i in range(8):
        for j in range(8):
            got = match_landmarks(qd[i], qb[i], rd[j], rb[j], matching=Matching(soft_nms_iou=t))
            want = oracle.match_landmarks(qd[i], qb[i], rd[j], rb[j], soft_nms_iou=t)
            np.testing.assert_array_equal(got.matches, want["matches"])
            np.testing.assert_array_equal(reciprocal_matches(qd[i], rd[j]), want["matches"])
            for key in ("distances", "shape", "raw_scores", "scores"):
                np.testing.assert_allclose(getattr(got, key), want[key], atol=1e-12, rtol=0)
            assert got.similarity == pytest.approx(want["similarity"], abs=1e-12)
            assert (got.n_a, got.n_b) == (want["n_a"], want["n_b"])


# ------------------------------------------------------------------------------------------
# similarity matrix == oracle
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("t", [None, 0.0, 0.2, 0.5])
def test_similarity_matrix_equals_pairwise_unequal_counts_and_ties(t):
    rng = np.random.default_rng(7)
    qd, qb = _random_sets(rng, 6, 1, 14, 48)
    rd, rb = _random_sets(rng, 7, 1, 14, 48)
    # a reference equal to a query (all landmarks match, many overlaps) and an empty query
    rd[2], rb[2] = qd[3].copy(), qb[3].copy()
    qd[5], qb[5] = np.zeros((0, 48), np.float32), np.zeros((0, 4))
    got = similarity_matrix(
        qd, qb, rd, rb, soft_nms_iou=t, compute=Compute(batch_size=4, ref_batch_size=3)
    )
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
    got64 = similarity_matrix(qd, qb, rd, rb, compute=Compute(matmul_dtype="float64"))
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
        for i in range(5):
            for j in range(6):
                np.testing.assert_array_equal(
                    reciprocal_matches(qd[i], rd[j]), oracle.reciprocal_matches(qd[i], rd[j])
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
    np.testing.assert_array_equal(m, oracle.reciprocal_matches(a, b))
    want = oracle.image_similarity(a, boxes_a, b, boxes_b)
    got = similarity_matrix([a.astype(np.float32)], [boxes_a], [b.astype(np.float32)], [boxes_b])
    assert got[0, 0] == pytest.approx(want, abs=1e-6)


@pytest.mark.parametrize(
    ("dtype", "scale"),
    [
        (np.float64, 2.0**664),
        (np.float64, 2.0**-664),
        (np.float32, 2.0**100),
        (np.float32, 2.0**-100),
    ],
)
def test_descriptor_magnitude_does_not_change_similarity(dtype, scale):
    # cosine does not depend on scale: huge (~1e200) or tiny descriptors must neither overflow
    # the norms into all-zero similarities nor be refused (scales are powers of two: exact)
    rng = np.random.default_rng(31)
    qd, qb = _random_sets(rng, 3, 2, 12, 16)
    rd, rb = _random_sets(rng, 4, 2, 12, 16)
    want = similarity_matrix(qd, qb, rd, rb, compute=Compute(matmul_dtype="float64"))
    assert np.all(want[want != 0] != 0) and np.count_nonzero(want) > 0
    big_q = [(d.astype(np.float64) * scale).astype(dtype) for d in qd]
    big_r = [(d.astype(np.float64) * scale).astype(dtype) for d in rd]
    for t in (None, 0.3):
        ref = similarity_matrix(
            qd, qb, rd, rb, soft_nms_iou=t, compute=Compute(matmul_dtype="float64")
        )
        got = similarity_matrix(big_q, qb, big_r, rb, soft_nms_iou=t)
        np.testing.assert_allclose(got, ref, atol=1e-5, rtol=0)
        pairs = np.array([[0, 1], [2, 3]])
        got_p = similarity_pairs(big_q, qb, big_r, rb, pairs, matching=Matching(soft_nms_iou=t))
        np.testing.assert_allclose(got_p, ref[pairs[:, 0], pairs[:, 1]], atol=1e-5, rtol=0)
        s = image_similarity(big_q[0], qb[0], big_r[1], rb[1], soft_nms_iou=t)
        assert s == pytest.approx(ref[0, 1], abs=1e-9)
    np.testing.assert_allclose(
        cosine_distance(big_q[0], big_r[0]), cosine_distance(qd[0], rd[0]), atol=1e-6
    )


_D, _B = [np.ones((3, 8))], [np.ones((3, 4))]


@pytest.mark.parametrize(
    ("args", "kwargs", "message"),
    [
        ((_D, _B + _B, _D, _B), {}, "query_desc has 1 images but query_boxes has 2"),
        ((_D, _B, [np.ones((3, 9))], _B), {}, "dimensions differ: query_desc D=8"),
        ((_D, [np.ones((2, 4))], _D, _B), {}, r"query_boxes\[0\] has 2 boxes"),
        ((_D, [np.ones((3, 3))], _D, _B), {}, r"\(K, 4\)"),
        (([np.full((3, 8), np.nan)], _B, _D, _B), {}, "query_desc contains NaN"),
        (
            ([np.ones((3, 8)), np.ones((3, 7))], _B + _B, _D, _B),
            {},
            r"dimensions differ: query_desc\[0\] D=8, query_desc\[1\] D=7",
        ),
        ((_D, _B, _D, _B), {"soft_nms_iou": 1.5}, "soft_nms_iou"),
        ((_D, _B, _D, _B), {"soft_nms_iou": 0.5, "sigma": 0}, "sigma"),
        (([], [], _D, _B), {}, "query_desc is empty"),
    ],
)
def test_similarity_matrix_bad_inputs(args, kwargs, message):
    with pytest.raises(ValueError, match=message):
        similarity_matrix(*args, **kwargs)


@pytest.mark.parametrize(
    ("build", "message"),
    [
        (lambda: Compute(matmul_dtype="float16"), "unknown matmul_dtype 'float16'"),
        (lambda: Compute(batch_size=0), "batch_size must be a positive integer"),
        (lambda: Compute(device="gpu0"), "device='gpu0' is not a torch device"),
        (lambda: Matching(soft_nms_iou=True), "soft_nms_iou=True is not valid"),
        (lambda: Matching(spatial="ransac"), "spatial='ransac' is not valid"),
        (
            lambda: similarity_matrix(_D, _B, _D, _B, 0.5, matching=Matching(0.5)),
            "soft-NMS is given twice",
        ),
        (
            lambda: match_landmarks(_D[0], _B[0], _D[0], _B[0], Matching(weighting="idf")),
            "use weighted_matches",
        ),
    ],
)
def test_matching_values_refuse_bad_fields(build, message):
    """Matching and Compute check their fields once, when made; a call refuses two sources."""
    with pytest.raises(ValueError, match=message):
        build()


@pytest.mark.parametrize(
    ("fn", "args", "message"),
    [
        (
            image_similarity,
            (np.ones((2, 3)), np.ones((2, 4)), np.ones((2, 4)), np.ones((2, 4))),
            "dimensions differ: desc_a D=3, desc_b D=4",
        ),
        (
            match_landmarks,
            (np.ones((2, 3)), np.ones((3, 4)), np.ones((2, 3)), np.ones((2, 4))),
            "boxes_a has 3 boxes",
        ),
        (shape_penalty, (np.array([[0, 0, -1, 2.0]]), np.ones((1, 4))), "boxes_a has negative"),
        (reciprocal_matches, (np.ones(3), np.ones((2, 3))), r"desc_a must have shape \(K, D\)"),
        (reciprocal_matches, (np.ones((2, 3)), np.full((2, 3), np.inf)), "desc_b contains NaN"),
        (cosine_distance, (np.ones((2, 3)), np.ones((2, 4))), "dimensions differ"),
        (cosine_distance, (np.ones(3), np.ones((2, 3))), r"desc_a must have shape \(K, D\)"),
    ],
)
def test_one_pair_bad_inputs(fn, args, message):
    with pytest.raises(ValueError, match=message):
        fn(*args)


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
        one = similarity_matrix(qd, qb, rd, rb, compute=Compute(batch_size=3, show_progress=False))
        assert torch.get_num_threads() == 1
        torch.set_num_threads(2)
        two = similarity_matrix(qd, qb, rd, rb, compute=Compute(batch_size=3, show_progress=False))
        assert torch.get_num_threads() == 2  # the workers' thread setting does not leak
    finally:
        torch.set_num_threads(threads)
    np.testing.assert_array_equal(one, two)
    np.testing.assert_allclose(two, _pairwise(qd, qb, rd, rb), atol=1e-5, rtol=0)


def test_soft_nms_sigma_default_is_the_papers():
    for fn in (image_similarity, similarity_matrix):
        assert inspect.signature(fn).parameters["sigma"].default == SOFT_NMS_SIGMA
    assert Matching().sigma == SOFT_NMS_SIGMA


@pytest.mark.skipif(torch.cuda.is_available(), reason="checks the no-GPU message")
def test_cuda_without_gpu_is_a_clear_error():
    """Refused where the value is made (checks.check_device), before any matching call."""
    with pytest.raises(ValueError, match="device='cuda' but torch sees no CUDA GPU"):
        Compute(device="cuda")


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA GPU")
@pytest.mark.parametrize("t", [None, 0.3])
@pytest.mark.parametrize("spatial", [None, "consistency"])
def test_cuda_equals_pairwise(t, spatial):
    rng = np.random.default_rng(17)
    qd, qb = _random_sets(rng, 6, 1, 20, 48)
    rd, rb = _random_sets(rng, 7, 1, 20, 48)
    want = _pairwise(qd, qb, rd, rb, soft_nms_iou=t, spatial=spatial)
    m, cuda = Matching(soft_nms_iou=t, spatial=spatial), Compute(device="cuda")
    got = similarity_matrix(qd, qb, rd, rb, matching=m, compute=cuda)
    np.testing.assert_allclose(got, want, atol=1e-5, rtol=0)
    pairs = np.array([[0, 1], [5, 6], [2, 2]])
    got_p = similarity_pairs(qd, qb, rd, rb, pairs, matching=m, compute=cuda)
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
        qd,
        qb,
        rd,
        rb,
        pairs,
        matching=Matching(soft_nms_iou=t),
        compute=Compute(ref_batch_size=2, show_progress=False),
    )
    assert got.shape == (10,) and got.dtype == np.float64
    np.testing.assert_allclose(got, want[pairs[:, 0], pairs[:, 1]], atol=1e-5, rtol=0)
    full = similarity_matrix(qd, qb, rd, rb, soft_nms_iou=t, compute=Compute(show_progress=False))
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
    full = similarity_matrix(qd, qb, rd, rb, compute=Compute(show_progress=False))
    got = similarity_pairs(qd, qb, rd, rb, pairs, compute=Compute(show_progress=False))
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


# ------------------------------------------------------------------------------------------
# (not in the paper) spatial="consistency": geometry-aware re-scoring
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("t", [None, 0.0, 0.3])
def test_spatial_match_landmarks_equals_oracle(t):
    rng = np.random.default_rng(41)
    qd, qb = _random_sets(rng, 6, 0, 25, 32)
    rd, rb = _random_sets(rng, 6, 1, 25, 32)
    rd[3], rb[3] = qd[2].copy(), qb[2].copy() + [7.0, -3.0, 0.0, 0.0]  # all match, one shift
    rd[4], rb[4] = qd[1].copy(), _random_sets(rng, 1, len(qd[1]), len(qd[1]), 2)[1][0]
    n_matches = []
    for i in range(6):
        for j in range(6):
            got = match_landmarks(
                qd[i], qb[i], rd[j], rb[j], matching=Matching(soft_nms_iou=t, spatial="consistency")
            )
            want = oracle.match_landmarks(
                qd[i], qb[i], rd[j], rb[j], soft_nms_iou=t, spatial="consistency"
            )
            np.testing.assert_array_equal(got.matches, want["matches"])
            np.testing.assert_allclose(got.spatial_weights, want["weights"], atol=1e-12, rtol=0)
            for key in ("distances", "shape", "raw_scores", "scores"):
                np.testing.assert_allclose(getattr(got, key), want[key], atol=1e-12, rtol=0)
            assert got.similarity == pytest.approx(want["similarity"], abs=1e-12)
            n_matches.append(len(want["matches"]))
    assert max(n_matches) > 10  # the median is exercised on odd and even counts
    assert {n % 2 for n in n_matches if n > 1} == {0, 1}


@pytest.mark.parametrize("t", [None, 0.3])
def test_spatial_similarity_matrix_and_pairs_equal_oracle(t):
    rng = np.random.default_rng(43)
    qd, qb = _random_sets(rng, 7, 1, 18, 40)
    rd, rb = _random_sets(rng, 9, 1, 18, 40)
    rd[4], rb[4] = qd[2].copy(), qb[2][::-1].copy()  # all landmarks match, boxes permuted
    qd[6], qb[6] = np.zeros((0, 40), np.float32), np.zeros((0, 4))
    want = _pairwise(qd, qb, rd, rb, soft_nms_iou=t, spatial="consistency")
    got = similarity_matrix(
        qd,
        qb,
        rd,
        rb,
        matching=Matching(soft_nms_iou=t, spatial="consistency"),
        compute=Compute(batch_size=3, ref_batch_size=4),
    )
    np.testing.assert_allclose(got, want, atol=1e-5, rtol=0)
    assert not np.allclose(want, _pairwise(qd, qb, rd, rb, soft_nms_iou=t), atol=1e-3)
    pairs = np.array([[3, 1], [0, 4], [2, 4], [6, 1], [0, 8], [5, 5], [2, 4]])
    got_p = similarity_pairs(
        qd,
        qb,
        rd,
        rb,
        pairs,
        matching=Matching(soft_nms_iou=t, spatial="consistency"),
        compute=Compute(ref_batch_size=2),
    )
    np.testing.assert_allclose(got_p, want[pairs[:, 0], pairs[:, 1]], atol=1e-5, rtol=0)


def _shifted_pair(move: tuple[float, float] | None = None):
    """Four matches whose reference boxes are the query boxes shifted by (16, 8) pixels.

    Each image also has a 128 x 64 landmark that matches nothing and fixes its extent, so every
    match's normalised displacement is (-0.125, -0.125), exactly. ``move``: new (x, y) of the
    reference box of match 2.
    """
    c = np.array([0.9, 0.8, 0.95, 0.7])
    a = np.eye(8)[[0, 1, 2, 3, 4]]
    b = np.zeros((5, 8))
    b[np.arange(4), np.arange(4)] = c
    b[:4, 7] = np.sqrt(1 - c**2)
    b[4, 5] = 1.0
    ba = np.array([[0, 0, 16, 16], [32, 8, 16, 24], [64, 16, 16, 16], [96, 0, 8, 32]], float)
    bb = ba + [16.0, 8.0, 0.0, 0.0]
    if move is not None:
        bb[2, :2] = move
    frame = [[0.0, 0.0, 128.0, 64.0]]
    return a, np.r_[ba, frame], b, np.r_[bb, frame]


@pytest.mark.parametrize("t", [None, 0.3])
def test_spatial_one_shared_displacement_changes_nothing(t):
    a, ba, b, bb = _shifted_pair()
    plain = match_landmarks(a, ba, b, bb, matching=Matching(soft_nms_iou=t))
    geo = match_landmarks(a, ba, b, bb, matching=Matching(soft_nms_iou=t, spatial="consistency"))
    np.testing.assert_array_equal(geo.matches, [[0, 0], [1, 1], [2, 2], [3, 3]])
    np.testing.assert_array_equal(geo.spatial_weights, np.ones(4))
    np.testing.assert_array_equal(geo.scores, plain.scores)
    assert geo.similarity == plain.similarity
    # ... although the shared displacement itself is far from zero (0.18 of the image)
    np.testing.assert_allclose(
        oracle.extent_centres(ba)[:4] - oracle.extent_centres(bb)[:4], -0.125
    )
    for spatial in (None, "consistency"):
        s = similarity_matrix(
            [a], [ba], [b], [bb], matching=Matching(soft_nms_iou=t, spatial=spatial)
        )
        assert s[0, 0] == pytest.approx(plain.similarity, abs=1e-6)


@pytest.mark.parametrize("t", [None, 0.3])
def test_spatial_one_displaced_match_lowers_only_its_term(t):
    a, ba, b, bb = _shifted_pair()
    before = match_landmarks(a, ba, b, bb, matching=Matching(soft_nms_iou=t, spatial="consistency"))
    a, ba, b, bb = _shifted_pair(move=(8.0, 40.0))  # same size: Eq. (2) does not change
    after = match_landmarks(a, ba, b, bb, matching=Matching(soft_nms_iou=t, spatial="consistency"))
    plain = match_landmarks(a, ba, b, bb, matching=Matching(soft_nms_iou=t))
    np.testing.assert_array_equal(after.matches, before.matches)
    np.testing.assert_array_equal(after.raw_scores, plain.raw_scores)
    # match 2: query centre (72, 24) / (128, 64), reference centre now (16, 48) / (128, 64):
    # displacement (0.4375, -0.375), median of the four still (-0.125, -0.125)
    w = math.exp(-(0.5625**2 + 0.25**2) / (2 * 0.1**2))
    np.testing.assert_allclose(after.spatial_weights, [1, 1, w, 1], rtol=1e-12)
    assert after.scores[2] < before.scores[2]
    np.testing.assert_array_equal(np.delete(after.scores, 2), np.delete(before.scores, 2))
    assert after.similarity < before.similarity
    assert plain.similarity == pytest.approx(before.similarity, abs=1e-12)
    got = similarity_matrix(
        [a], [ba], [b], [bb], matching=Matching(soft_nms_iou=t, spatial="consistency")
    )
    assert got[0, 0] == pytest.approx(after.similarity, abs=1e-6)


def test_spatial_default_off_and_unknown_name_lists_valid_ones():
    assert Matching().spatial is None
    with pytest.raises(ValueError, match="spatial='ransac' is not valid"):
        Matching(spatial="ransac")
    with pytest.raises(ValueError, match="expected None or one of 'consistency'"):
        Matching(spatial="Consistency")
