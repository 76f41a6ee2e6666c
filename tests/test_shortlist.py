"""Shortlist + re-rank (vpr_core.matching.shortlist): top-k by global cosine, Eq. (1) on them."""

from __future__ import annotations

import numpy as np
import pytest

from vpr_core.matching import Compute, similarity_matrix, similarity_pairs
from vpr_core.matching.shortlist import global_cosine, rerank, shortlist_pairs, topk_lowest_index


def _landmark_sets(rng, n, dim=32, kmin=5, kmax=12):
    desc, boxes = [], []
    for k in rng.integers(kmin, kmax + 1, n):
        desc.append(rng.standard_normal((k, dim)).astype(np.float32))
        boxes.append(np.c_[rng.uniform(0, 40, (k, 2)), rng.uniform(4, 40, (k, 2))])
    return desc, boxes


def test_shortlist_picks_constructed_neighbours_best_first():
    # reference j points along angle j * 10 deg; the query at 21 deg is closest to 20, then 30,
    # then 10, then 40 ...
    ang = np.deg2rad(np.arange(8) * 10.0)
    ref = np.c_[np.cos(ang), np.sin(ang)] * np.arange(1, 9)[:, None]  # norms must not matter
    q = np.array(
        [
            [np.cos(np.deg2rad(21.0)), np.sin(np.deg2rad(21.0))],
            [np.cos(np.deg2rad(69.0)), np.sin(np.deg2rad(69.0))],
        ]
    )
    pairs, sim = shortlist_pairs(q, ref, 3)
    assert pairs.dtype == np.int64 and pairs.shape == (6, 2)
    np.testing.assert_array_equal(pairs[:, 0], [0, 0, 0, 1, 1, 1])
    np.testing.assert_array_equal(pairs[:, 1], [2, 3, 1, 7, 6, 5])
    assert sim.shape == (2, 8)
    np.testing.assert_allclose(sim[0, 2], np.cos(np.deg2rad(1.0)), rtol=1e-12)


def test_shortlist_ties_go_to_lowest_index():
    ref = np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 0.0], [2.0, 0.0], [1.0, 0.0]])
    q = np.array([[1.0, 0.0]])
    pairs, _ = shortlist_pairs(q, ref, 2)  # four references tie at cosine 1
    np.testing.assert_array_equal(pairs[:, 1], [0, 2])
    pairs, _ = shortlist_pairs(q, ref, 4)
    np.testing.assert_array_equal(pairs[:, 1], [0, 2, 3, 4])


def test_topk_lowest_index_matches_stable_sort_on_many_ties():
    rng = np.random.default_rng(3)
    scores = rng.integers(0, 4, (200, 30)).astype(np.float64)  # heavy ties everywhere
    for k in (1, 5, 29, 30):
        want = np.argsort(-scores, axis=1, kind="stable")[:, :k]
        np.testing.assert_array_equal(topk_lowest_index(scores, k), want)


def test_shortlist_k_clipped_and_validated():
    rng = np.random.default_rng(0)
    q, r = rng.standard_normal((3, 4)), rng.standard_normal((5, 4))
    pairs, _ = shortlist_pairs(q, r, 50)
    assert pairs.shape == (15, 2)
    for bad in (0, -1, 2.5, True, None):
        with pytest.raises(
            ValueError, match=r"shortlist k \(references kept per query\) must be a positive"
        ):
            shortlist_pairs(q, r, bad)
    with pytest.raises(ValueError, match="dimensions differ"):
        shortlist_pairs(q, rng.standard_normal((5, 3)), 2)
    with pytest.raises(ValueError, match=r"global_query contains NaN or inf \(first at row 1\)"):
        shortlist_pairs(np.r_[q[:1], [[np.nan] * 4], q[2:]], r, 2)
    with pytest.raises(ValueError, match=r"\(N, D\)"):
        shortlist_pairs(q[0], r, 2)


def test_global_cosine_zero_descriptor_is_zero():
    sim = global_cosine(np.array([[0.0, 0.0], [1.0, 1.0]]), np.array([[1.0, 0.0], [0.0, 3.0]]))
    np.testing.assert_allclose(sim, [[0.0, 0.0], [np.sqrt(0.5), np.sqrt(0.5)]], rtol=1e-12)


@pytest.mark.parametrize("scale", [2.0**664, 2.0**-664])
def test_global_cosine_any_magnitude(scale):
    # cosine does not depend on scale: huge (~1e200) or tiny descriptors must not overflow or
    # underflow the norms into all-zero cosines (scales are powers of two: exact)
    rng = np.random.default_rng(5)
    q, r = rng.standard_normal((3, 6)), rng.standard_normal((4, 6))
    want = global_cosine(q, r)
    np.testing.assert_allclose(global_cosine(q * scale, r), want, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(global_cosine(q, r * scale), want, rtol=1e-12, atol=1e-15)
    np.testing.assert_array_equal(shortlist_pairs(q * scale, r, 2)[0], shortlist_pairs(q, r, 2)[0])


def test_rerank_with_all_references_equals_exhaustive():
    rng = np.random.default_rng(1)
    qd, qb = _landmark_sets(rng, 6)
    rd, rb = _landmark_sets(rng, 9)
    full = similarity_matrix(qd, qb, rd, rb, compute=Compute(show_progress=False))
    gq = np.stack([d.mean(0) for d in qd])
    gr = np.stack([d.mean(0) for d in rd])
    pairs, _ = shortlist_pairs(gq, gr, 9)
    vals = similarity_pairs(qd, qb, rd, rb, pairs, compute=Compute(show_progress=False))
    np.testing.assert_array_equal(rerank(vals, pairs, 6, 9), full)


def test_rerank_small_k_nan_off_shortlist_and_top1_inside_unchanged():
    rng = np.random.default_rng(2)
    qd, qb = _landmark_sets(rng, 10)
    rd, rb = _landmark_sets(rng, 14)
    full = similarity_matrix(qd, qb, rd, rb, compute=Compute(show_progress=False))
    gq = rng.standard_normal((10, 8))
    gr = rng.standard_normal((14, 8))
    pairs, _ = shortlist_pairs(gq, gr, 4)
    vals = similarity_pairs(qd, qb, rd, rb, pairs, compute=Compute(show_progress=False))
    sim = rerank(vals, pairs, 10, 14)
    listed = np.zeros((10, 14), dtype=bool)
    listed[pairs[:, 0], pairs[:, 1]] = True
    assert (listed.sum(1) == 4).all()
    assert np.isnan(sim[~listed]).all()
    np.testing.assert_array_equal(sim[listed], full[listed])
    # top-1 inside the shortlist is the exhaustive matrix's best among the same references
    masked = np.where(listed, full, -np.inf)
    np.testing.assert_array_equal(np.nanargmax(sim, axis=1), masked.argmax(1))


def test_rerank_validates_inputs():
    pairs = np.array([[0, 1], [1, 0]])
    with pytest.raises(ValueError, match="one value per pair"):
        rerank(np.zeros(3), pairs, 2, 2)
    with pytest.raises(ValueError, match="reference index 5"):
        rerank(np.zeros(2), np.array([[0, 5], [1, 0]]), 2, 2)
    with pytest.raises(ValueError, match="NaN or inf"):
        rerank(np.array([0.1, np.nan]), pairs, 2, 2)
    with pytest.raises(ValueError, match="listed twice"):
        rerank(np.array([0.1, 0.2]), np.array([[0, 1], [0, 1]]), 2, 2)
    with pytest.raises(ValueError, match="integer indices"):
        rerank(np.zeros(2), pairs.astype(float), 2, 2)


def test_match_stage_exhaustive_and_full_shortlist_agree():
    from vpr_core.run import _match as match

    rng = np.random.default_rng(4)
    qd, qb = _landmark_sets(rng, 5)
    rd, rb = _landmark_sets(rng, 7)
    boxes, feats = {"query": qb, "reference": rb}, {"query": qd, "reference": rd}
    full, info = match(boxes, feats)
    np.testing.assert_array_equal(
        full, similarity_matrix(qd, qb, rd, rb, compute=Compute(show_progress=False))
    )
    assert info["pairs"] == 35
    glob = {"query": rng.standard_normal((5, 6)), "reference": rng.standard_normal((7, 6))}
    sim, info = match(boxes, feats, shortlist=7, global_desc=glob)
    np.testing.assert_array_equal(sim, full)
    sim, info = match(boxes, feats, shortlist=2, global_desc=glob)
    assert info["pairs"] == 10 and np.isnan(sim).sum() == 25
    with pytest.raises(ValueError, match="global_desc"):
        match(boxes, feats, shortlist=2)


def test_whole_image_boxes_round_trip(tiny_synthetic):
    from vpr_core.matching.shortlist import split_whole_image, with_whole_image_boxes

    n = len(tiny_synthetic.query_paths)
    boxes = {
        "query": [np.zeros((0, 4))] + [np.ones((2, 4))] * (n - 1),
        "reference": [np.ones((3, 4))] * n,
        "seconds": {},
    }
    out = with_whole_image_boxes(boxes, tiny_synthetic)
    h, w = tiny_synthetic.image_size("query", 0)
    np.testing.assert_array_equal(out["query"][0], [[0, 0, w, h]])
    assert out["reference"][0].shape == (4, 4) and "seconds" in out
    feats = {
        s: [np.arange(len(b) * 2, dtype=np.float32).reshape(-1, 2) for b in out[s]]
        for s in ("query", "reference")
    }
    lm, glob = split_whole_image(feats)
    assert lm["query"][0].shape == (0, 2) and lm["reference"][0].shape == (3, 2)
    np.testing.assert_array_equal(glob["reference"][0], [6, 7])
    assert glob["query"].shape == (n, 2)
