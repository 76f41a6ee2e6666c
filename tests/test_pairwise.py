"""The one-pair reference of Eq. (1)-(2) (vpr_core/matching/pairwise.py) against the block engine
(core.py, through similarity_matrix / similarity_pairs, what the study runs) on every study
method's landmarks and matching settings, with exact and near ties; and the one-pair public
functions are the reference."""

from __future__ import annotations

import math

import numpy as np
import oracle_pairwise as oracle
import pytest

import vpr_core.matching.similarity as similarity_module
from vpr_core.datasets import load_dataset
from vpr_core.landmarks.schemes import EdgeBoxesTop, ReduceOverlap
from vpr_core.matching import (
    Compute,
    Matching,
    image_similarity,
    match_landmarks,
    reciprocal_matches,
    similarity_matrix,
    similarity_pairs,
)
from vpr_core.matching.core import Problem
from vpr_core.matching.pairwise import match_pair
from vpr_core.methods import METHODS
from vpr_core.paper import FIG7_NMS_THRESHOLDS, FIG7_SOFT_NMS_THRESHOLDS

QUIET = Compute(show_progress=False)
F64 = Compute(matmul_dtype="float64", show_progress=False)


def _study_cases() -> list[tuple[str, object, Matching]]:
    """(label, landmark scheme, Matching) of every study method and every matching setting the
    study sweeps: the presets (classical, Scheme 1/2 selection, overlap Scheme 1 (NMS) and 2
    (soft-NMS), dense, global), Fig. 7a's NMS and Fig. 7b's soft-NMS thresholds, and each with
    the geometry-aware re-scoring (notebook 06)."""
    cases = []
    for name, m in METHODS.items():
        cases.append((name, m.landmarks, m.matching))
        geo = Matching(m.matching.soft_nms_iou, m.matching.sigma, spatial="consistency")
        cases.append((f"{name}+spatial", m.landmarks, geo))
    for t in FIG7_NMS_THRESHOLDS:
        cases.append((f"nms{t}", ReduceOverlap(iou_threshold=t), Matching()))
    for t in FIG7_SOFT_NMS_THRESHOLDS:
        cases.append((f"soft-nms{t}", EdgeBoxesTop(), Matching(soft_nms_iou=t)))
        geo = Matching(soft_nms_iou=t, spatial="consistency")
        cases.append((f"soft-nms{t}+spatial", EdgeBoxesTop(), geo))
    return cases


CASES = _study_cases()


@pytest.fixture(scope="module")
def landmarks():
    """Boxes of three query and three reference synthetic images (small, fast), per scheme."""
    ds = load_dataset("synthetic", n_places=3, image_size=(120, 200))
    images = [[ds.load_image(side, i) for i in range(3)] for side in ("query", "reference")]
    cache: dict = {}

    def boxes(scheme) -> tuple[list[np.ndarray], list[np.ndarray]]:
        if scheme not in cache:
            cache[scheme] = tuple([scheme.boxes(im) for im in side] for side in images)
        return cache[scheme]

    return boxes


def _descriptors(rng, kq: list[int], kr: list[int], dim: int = 24):
    """float32 descriptors with exact and near ties within and across images.

    Query landmark 1 repeats landmark 0 (a duplicate: a column tie), landmark 3 is 3x landmark 2
    (the same cosines up to float rounding); each reference copies some query landmarks exactly,
    twice over for one of them (a row tie), scaled by 0.5 for another (a tie up to rounding), and
    the rest are noisy copies or fresh vectors; some rows are zero (cosine 0 with everything).
    """
    qd = []
    for k in kq:
        d = rng.standard_normal((k, dim)).astype(np.float32)
        if k > 4:
            d[1] = d[0]
            d[3] = 3.0 * d[2]
        if k > 8:
            d[8] = 0.0
        qd.append(d)
    rd = []
    for i, k in enumerate(kr):
        src = qd[i % len(qd)]
        d = rng.standard_normal((k, dim)).astype(np.float32)
        if k > 6 and len(src) > 6:
            d[0] = src[5]
            d[1] = src[5]  # two references tie for query landmark 5
            d[2] = 0.5 * src[6]
            d[3] = src[0]  # ties with query landmarks 0 and 1
            n = min(k, len(src)) - 4
            noisy = src[4 : 4 + n] + 0.3 * rng.standard_normal((n, dim)).astype(np.float32)
            d[4 : 4 + n] = noisy
        if k > 9:
            d[9] = 0.0
        rd.append(d)
    return qd, rd


def _engine_pairs(qd, qb, rd, rb, matching: Matching, compute: Compute):
    """The block engine's ``(Nq, Nr)`` similarities, in one block, and its matches and terms per
    image pair: {(q, r): (matches, scores)}."""
    prob = Problem.build(qd, qb, rd, rb, matching, compute)
    none = (np.zeros((0, 2), np.int64), np.zeros(0))
    out = {(q, r): none for q in range(len(qd)) for r in range(len(rd))}
    if prob.empty:
        return np.zeros((len(qd), len(rd))), out
    sim, p = prob.block(slice(0, len(qd)), slice(0, len(rd)), keep_pairs=True)
    g, rr = p.g.numpy(), p.rr.numpy()
    ij = np.stack([p.i.numpy(), p.j.numpy()], axis=1)
    for q in range(len(qd)):
        for r in range(len(rd)):
            sel = (g == q) & (rr == r)
            order = np.argsort(ij[sel, 0], kind="stable")
            out[q, r] = (ij[sel][order], p.score.numpy()[sel][order])
    return sim.numpy(), out


def _check_case(qd, qb, rd, rb, matching: Matching) -> None:
    """Reference == block engine: matches identical; similarities and terms to 1e-6 with the
    study's float32 matmul (similarity_matrix, similarity_pairs, one block) and to 1e-12 with a
    float64 matmul."""
    ref = [
        [match_pair(qd[q], qb[q], rd[r], rb[r], matching) for r in range(len(rd))]
        for q in range(len(qd))
    ]
    want = np.array([[x.similarity for x in row] for row in ref])
    got = similarity_matrix(qd, qb, rd, rb, matching=matching, compute=QUIET)
    np.testing.assert_allclose(got, want, rtol=1e-6, atol=1e-6)
    pairs = np.array([(q, r) for q in range(len(qd)) for r in range(len(rd))])
    got_p = similarity_pairs(qd, qb, rd, rb, pairs, matching=matching, compute=QUIET)
    np.testing.assert_allclose(got_p, want.ravel(), rtol=1e-6, atol=1e-6)
    for compute, tol in ((QUIET, 1e-6), (F64, 1e-12)):
        sim, engine = _engine_pairs(qd, qb, rd, rb, matching, compute)
        np.testing.assert_allclose(sim, want, rtol=tol, atol=tol)
        for (q, r), (m, scores) in engine.items():
            np.testing.assert_array_equal(m, ref[q][r].matches, err_msg=f"pair {(q, r)}")
            np.testing.assert_allclose(scores, ref[q][r].scores, rtol=tol, atol=tol)


@pytest.mark.parametrize(("label", "scheme", "matching"), CASES, ids=[c[0] for c in CASES])
def test_reference_equals_block_engine_on_study_methods(landmarks, label, scheme, matching):
    qb, rb = landmarks(scheme)
    rng = np.random.default_rng([ord(c) for c in label])
    qd, rd = _descriptors(rng, [len(b) for b in qb], [len(b) for b in rb])
    _check_case(qd, qb, rd, rb, matching)


def _synthetic_sets(kind: str, rng):
    """Hand-made landmark sets: every descriptor equal, a few discrete values, and an image
    without landmarks beside images with duplicated boxes (equal scores: soft-NMS ties)."""
    box = np.array([[0, 0, 10, 10], [2, 0, 10, 10], [0, 0, 10, 10], [30, 30, 20, 10]], float)
    if kind == "all-equal":
        qd = [np.ones((4, 5), np.float32) for _ in range(2)]
        rd = [np.ones((4, 5), np.float32), 2 * np.ones((4, 5), np.float32)]
        return qd, [box, box], rd, [box, box[::-1].copy()]
    if kind == "discrete":
        qd = [rng.integers(-1, 2, (12, 4)).astype(np.float32) for _ in range(3)]
        rd = [rng.integers(-1, 2, (9, 4)).astype(np.float32) for _ in range(2)]
        qb = [np.tile(box, (3, 1)) for _ in range(3)]
        rb = [np.tile(box, (3, 1))[:9] for _ in range(2)]
        return qd, qb, rd, rb
    assert kind == "empty-image"
    d = rng.standard_normal((4, 6)).astype(np.float32)
    qd = [d, np.zeros((0, 6), np.float32)]
    rd = [d[::-1].copy(), d.copy(), np.zeros((0, 6), np.float32)]
    return qd, [box, np.zeros((0, 4))], rd, [box, box, np.zeros((0, 4))]


@pytest.mark.parametrize("kind", ["all-equal", "discrete", "empty-image"])
@pytest.mark.parametrize(
    "matching",
    [
        Matching(),
        Matching(soft_nms_iou=0.3),
        Matching(spatial="consistency"),
        Matching(soft_nms_iou=0.5, spatial="consistency"),
    ],
    ids=["eq1", "soft-nms0.3", "spatial", "soft-nms0.5+spatial"],
)
def test_reference_equals_block_engine_on_exact_ties(kind, matching):
    _check_case(*_synthetic_sets(kind, np.random.default_rng(5)), matching)


def test_reference_equals_independent_oracle(landmarks):
    """The package's reference against the test oracle written from docs/DEFINITIONS.md."""
    qb, rb = landmarks(METHODS["classical"].landmarks)
    qd, rd = _descriptors(np.random.default_rng(3), [len(b) for b in qb], [len(b) for b in rb])
    for t in (None, 0.3, 0.7):
        for spatial in (None, "consistency"):
            m = Matching(soft_nms_iou=t, spatial=spatial)
            for q in range(3):
                for r in range(3):
                    got = match_pair(qd[q], qb[q], rd[r], rb[r], m)
                    want = oracle.match_landmarks(qd[q], qb[q], rd[r], rb[r], t, spatial=spatial)
                    np.testing.assert_array_equal(got.matches, want["matches"])
                    np.testing.assert_allclose(got.scores, want["scores"], rtol=1e-12, atol=1e-14)
                    assert got.similarity == pytest.approx(want["similarity"], abs=1e-12)


def test_one_pair_functions_are_the_reference(monkeypatch):
    """match_landmarks, image_similarity and reciprocal_matches compute by pairwise.match_pair."""
    rng = np.random.default_rng(9)
    qd, rd = _descriptors(rng, [12], [10])
    qb = rng.uniform(1, 30, (12, 4))
    rb = rng.uniform(1, 30, (10, 4))
    m = Matching(soft_nms_iou=0.4, spatial="consistency")
    want = match_pair(qd[0], qb, rd[0], rb, m)
    got = match_landmarks(qd[0], qb, rd[0], rb, m)
    for field in ("matches", "distances", "shape", "raw_scores", "spatial_weights", "scores"):
        np.testing.assert_array_equal(getattr(got, field), getattr(want, field))
    assert got.similarity == want.similarity
    assert image_similarity(qd[0], qb, rd[0], rb, matching=m) == want.similarity
    calls = []

    def spy(*args, **kwargs):
        calls.append(args)
        return match_pair(*args, **kwargs)

    monkeypatch.setattr(similarity_module, "match_pair", spy)
    image_similarity(qd[0], qb, rd[0], rb)
    reciprocal_matches(qd[0], rd[0])
    assert len(calls) == 2


def test_one_pair_refuses_a_weighting_naming_the_block_engine():
    d, b = np.ones((3, 4)), np.ones((3, 4))
    for w in ("contrast", "idf"):
        with pytest.raises(ValueError, match="weighted_matches .* the block engine"):
            match_landmarks(d, b, d, b, Matching(weighting=w))


def test_no_descriptor_dimension_scores_zero_like_the_engine():
    d, b = np.ones((3, 4)), np.ones((3, 4))
    for a in (np.ones((3, 0)), np.zeros((0, 4))):
        r = match_landmarks(a, np.ones((len(a), 4)), d, b)
        engine = similarity_matrix([a], [np.ones((len(a), 4))], [d], [b], compute=QUIET)
        assert r.similarity == engine[0, 0] == 0.0 and r.matches.shape == (0, 2)
        assert (r.n_a, r.n_b) == (len(a), 3)
        assert match_landmarks(d, b, a, np.ones((len(a), 4))).similarity == 0.0


def test_reference_by_hand():
    """Eq. (1)-(2) by hand on two landmarks: one exact match, one at cosine 0.8 and double width."""
    a = np.array([[1.0, 0.0], [0.0, 1.0]])
    b = np.array([[1.0, 0.0], [0.6, 0.8]])
    ba = np.array([[0, 0, 10, 10], [0, 0, 10, 10]], float)
    bb = np.array([[0, 0, 10, 10], [0, 0, 20, 10]], float)
    r = match_pair(a, ba, b, bb)
    np.testing.assert_array_equal(r.matches, [[0, 0], [1, 1]])
    assert r.similarity == pytest.approx((1.0 + 1.0 - 0.2 * math.exp(0.25)) / 2.0, abs=1e-15)
