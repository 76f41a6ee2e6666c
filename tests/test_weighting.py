"""(Not in the paper) database weighting of the Eq. (1) terms: ``weighting="contrast" | "idf"``
against the NumPy oracle (oracle_pairwise.py), its hand-made cases and its plumbing."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import oracle_pairwise as oracle
import pandas as pd
import pytest
import torch
from test_matching import _random_sets

from vpr_core.matching import (
    WEIGHTINGS,
    Compute,
    similarity_matrix,
    similarity_pairs,
    weighted_matches,
)
from vpr_core.matching.core import Problem
from vpr_core.matching.weighting import (
    CONTRAST_SAMPLE,
    WEIGHTING_SAMPLE,
    clear_reference_cache,
    reference_cache_keys,
    reference_stats,
    sample_matches,
    weighting_sample,
)
from vpr_core.methods import Matching, as_method, get_method, method_label, run_key

#: The values these tests pass again and again: float64 blocks, each weighting.
F64 = Compute(matmul_dtype="float64")
CONTRAST, IDF = Matching(weighting="contrast"), Matching(weighting="idf")
BOX = [0.0, 0.0, 10.0, 10.0]


def _sets(seed: int, nq: int = 6, nr: int = 7, dim: int = 48):
    rng = np.random.default_rng(seed)
    qd, qb = _random_sets(rng, nq, 1, 14, dim)
    rd, rb = _random_sets(rng, nr, 1, 14, dim)
    rd[2], rb[2] = qd[3].copy(), qb[3].copy()  # every landmark of query 3 matches reference 2
    qd[nq - 1], qb[nq - 1] = np.zeros((0, dim), np.float32), np.zeros((0, 4))  # no landmark
    return qd, qb, rd, rb


@pytest.mark.parametrize("weighting", tuple(WEIGHTINGS))
@pytest.mark.parametrize(("t", "spatial"), [(None, None), (0.3, None), (None, "consistency")])
def test_similarity_matrix_equals_oracle(weighting, t, spatial):
    qd, qb, rd, rb = _sets(7)
    want = oracle.similarity_matrix(
        qd, qb, rd, rb, weighting=weighting, soft_nms_iou=t, spatial=spatial
    )
    kw = {"matching": Matching(t, spatial=spatial, weighting=weighting)}
    got = similarity_matrix(qd, qb, rd, rb, **kw, compute=Compute(batch_size=4, ref_batch_size=3))
    # float32 cosines: relative error ~1e-7, and two_sided's weights reach ~30x a term
    np.testing.assert_allclose(got, want, atol=1e-6, rtol=1e-6)
    np.testing.assert_allclose(
        similarity_matrix(qd, qb, rd, rb, **kw, compute=F64),
        want,
        atol=1e-12,
        rtol=0,
    )
    plain = oracle.similarity_matrix(qd, qb, rd, rb, soft_nms_iou=t, spatial=spatial)
    assert np.abs(want - plain).max() > 0.1  # the weighting changes the scores
    assert np.all(got[-1] == 0)  # a query without landmarks
    # the listed pairs give the same values (statistics over all 7 references, <= 256)
    pairs = np.array([[0, 1], [3, 2], [4, 6], [3, 2], [5, 0], [1, 1]])
    got_p = similarity_pairs(qd, qb, rd, rb, pairs, **kw, compute=Compute(ref_batch_size=2))
    np.testing.assert_allclose(got_p, got[pairs[:, 0], pairs[:, 1]], atol=1e-7, rtol=1e-7)
    # and weighted_matches gives each pair's terms with their weights
    for (i, j), res in zip(
        pairs, weighted_matches(qd, qb, rd, rb, pairs, kw["matching"]), strict=True
    ):
        o = oracle.match_landmarks(
            qd[i],
            qb[i],
            rd[j],
            rb[j],
            t,
            0.5,
            spatial,
            oracle.pair_weights(weighting, qd[i], rd, j),
        )
        np.testing.assert_array_equal(res.matches, o["matches"])
        np.testing.assert_allclose(res.weights, o["db_weights"], atol=1e-5, rtol=1e-6)
        assert res.similarity == pytest.approx(want[i, j], abs=1e-6, rel=1e-6)


@pytest.mark.parametrize("weighting", tuple(WEIGHTINGS))
def test_shortlist_statistics_come_from_the_sample(weighting):
    qd, qb, rd, rb = _sets(11, nq=4, nr=9)
    sample = np.array([0, 2, 5, 8])
    pairs = np.array([[0, 1], [1, 2], [2, 7], [0, 5]])
    got = similarity_pairs(
        qd, qb, rd, rb, pairs, sample=sample, matching=Matching(weighting=weighting)
    )
    want = oracle.similarity_matrix(qd, qb, rd, rb, weighting=weighting, sample=sample)
    np.testing.assert_allclose(got, want[pairs[:, 0], pairs[:, 1]], atol=1e-6, rtol=0)
    full = oracle.similarity_matrix(qd, qb, rd, rb, weighting=weighting)
    assert not np.allclose(got, full[pairs[:, 0], pairs[:, 1]], atol=1e-4)
    with pytest.raises(ValueError, match="outside 0..8"):
        similarity_pairs(
            qd, qb, rd, rb, pairs, sample=[0, 9], matching=Matching(weighting=weighting)
        )


def test_weighting_sample_is_fixed_and_all_references_up_to_256():
    np.testing.assert_array_equal(weighting_sample(WEIGHTING_SAMPLE), np.arange(WEIGHTING_SAMPLE))
    s = weighting_sample(716)
    assert len(s) == WEIGHTING_SAMPLE == 256 and np.all(np.diff(s) > 0) and s.max() < 716
    np.testing.assert_array_equal(s, weighting_sample(716))  # seeded
    assert len(np.setdiff1d(s, np.arange(256))) > 100  # spread over the route
    # contrast: 12 references, the same seeded draw
    c = weighting_sample(716, "contrast")
    assert len(c) == CONTRAST_SAMPLE == 12 and np.all(np.diff(c) > 0)
    want = np.sort(np.random.default_rng(0).choice(716, 12, replace=False))
    np.testing.assert_array_equal(c, want)
    np.testing.assert_array_equal(weighting_sample(12, "contrast"), np.arange(12))
    np.testing.assert_array_equal(weighting_sample(716, "idf"), s)


def _stats_oracle(qd, rd, sample):
    """DEFINITIONS.md's shortlist contrast statistics in float64 NumPy: per query landmark, the
    mean and population std of its best cosine over the sampled references with landmarks."""
    out = []
    for q in qd:
        b = [oracle.cosine_similarity(q, rd[j]).max(axis=1) for j in sample if len(rd[j])]  # b_i(r)
        b = np.stack(b, axis=1) if len(q) else np.zeros((0, 1))
        out.append((b.mean(axis=1), b.std(axis=1)))
    return out


def test_shortlist_contrast_statistics_are_12_sampled_references_row_maxima():
    qd, qb, rd, rb = _sets(21, nq=5, nr=40, dim=24)
    rd[7], rb[7] = np.zeros((0, 24), np.float32), np.zeros((0, 4))  # no landmark: not counted
    sample = weighting_sample(40, "contrast")
    assert len(sample) == 12
    # the best cosines of sample_matches are the float64 oracle's row maxima (float32 matmul)
    prob = Problem.build(qd, qb, rd, rb, CONTRAST, Compute())
    for qi in range(4):
        m = sample_matches(prob, slice(qi, qi + 1), torch.from_numpy(sample), 5)
        got = m.best[0][:, : len(qd[qi])].numpy()  # (12, Kq)
        want = [
            oracle.cosine_similarity(qd[qi], rd[j]).max(axis=1) if len(rd[j]) else None
            for j in sample
        ]
        for row, w in zip(got, want, strict=True):
            if w is not None:
                np.testing.assert_allclose(row, w, atol=1e-6, rtol=0)
    # similarity_pairs' default statistics are those of the 12 sampled references (oracle)
    pairs = np.array([[0, 1], [1, 2], [2, 30], [0, 5], [3, 39], [4, 0]])
    got = similarity_pairs(qd, qb, rd, rb, pairs, matching=CONTRAST)
    want = oracle.similarity_matrix(qd, qb, rd, rb, weighting="contrast", sample=sample)
    np.testing.assert_allclose(got, want[pairs[:, 0], pairs[:, 1]], atol=1e-6, rtol=0)
    every = oracle.similarity_matrix(qd, qb, rd, rb, weighting="contrast")
    assert not np.allclose(got, every[pairs[:, 0], pairs[:, 1]], atol=1e-4)  # not all 40
    # and weighted_matches reports the weights of those statistics
    stats = _stats_oracle(qd, rd, sample)
    for (i, _), res in zip(pairs, weighted_matches(qd, qb, rd, rb, pairs, CONTRAST), strict=True):
        mu, sd = stats[i]
        c = 1.0 - res.distances
        k = res.matches[:, 0]
        w = np.where(sd[k] > 1e-6, np.maximum(0, (c - mu[k]) / np.where(sd[k] > 0, sd[k], 1)), 0)
        np.testing.assert_allclose(res.weights, w, atol=1e-5, rtol=0)


def test_shortlist_contrast_is_deterministic_and_keyed_by_content():
    qd, qb, rd, rb = _sets(23, nq=6, nr=30, dim=24)
    pairs = np.array([[0, 3], [0, 17], [1, 2], [2, 29], [3, 3], [4, 11], [4, 12]])
    threads = torch.get_num_threads()
    try:
        runs = []
        for n in (1, 2, 1):
            torch.set_num_threads(n)
            runs.append(similarity_pairs(qd, qb, rd, rb, pairs, matching=CONTRAST))
    finally:
        torch.set_num_threads(threads)
    for other in runs[1:]:
        np.testing.assert_array_equal(runs[0], other)  # same bits, any thread count
    # a pair's value depends on the descriptors only: not on the other listed pairs, their
    # order, or where the query sits among the queries
    alone = similarity_pairs(qd, qb, rd, rb, pairs[:1], matching=CONTRAST)
    assert alone[0] == runs[0][0]
    perm = np.array([5, 4, 3, 2, 1, 0])  # query i moves to position perm^-1(i)
    inv = np.argsort(perm)
    qd2, qb2 = [qd[i] for i in perm], [qb[i] for i in perm]
    moved = np.stack([inv[pairs[:, 0]], pairs[:, 1]], axis=1)[::-1]
    got = similarity_pairs(qd2, qb2, rd, rb, moved, matching=CONTRAST)[::-1]
    np.testing.assert_array_equal(got, runs[0])
    # new statistics, new cache entries: run_method's key carries the matching code's hash,
    # which covers this module
    from vpr_core.utils import STAGE_SOURCES

    assert "matching" in STAGE_SOURCES["matching"]


def test_exhaustive_contrast_unchanged_by_the_shortlist_statistics():
    """similarity_matrix's contrast values are bit for bit those of the code before issue 46
    (these hex values were computed by it): its statistics still cover every reference."""
    rng = np.random.default_rng(46)
    qd, qb = _random_sets(rng, 5, 1, 12, 32)
    rd, rb = _random_sets(rng, 6, 1, 12, 32)
    got = similarity_matrix(qd, qb, rd, rb, matching=CONTRAST, compute=Compute(batch_size=2))
    want = [
        "0x1.28a4bc1c5edd8p-6",
        "0x0.0p+0",
        "-0x1.4865a04ac1a2ap-6",
        "0x1.9a6d6a10e156fp-4",
        "0x1.ebdde3c72d435p-6",
        "-0x1.15eb8d3373873p-7",
        "-0x1.23b53f6a7d498p-5",
        "-0x1.2870aeed57cffp-8",
        "-0x1.21b8f478e2e9cp-7",
    ]
    # the hex values are the bits of an AMD Zen 3 (AVX2); on an AVX-512 Intel Xeon the float32
    # matmul differs in the last bit (seen: -0x1.23b53f6a7d497p-5), so other CPUs get 1 ulp
    if platform_bits_match := [float(x).hex() for x in got[:3, :3].ravel()] == want:
        assert float(got.sum()).hex() == "0x1.0db2b61fd1473p-3"
    else:
        np.testing.assert_allclose(got[:3, :3].ravel(), [float.fromhex(x) for x in want], rtol=1e-6)
    assert platform_bits_match or "AVX512" in _cpu_flags()
    # and the old formula (statistics over all 6 references) in float64 agrees
    np.testing.assert_allclose(
        got, oracle.similarity_matrix(qd, qb, rd, rb, weighting="contrast"), atol=1e-6, rtol=0
    )


def _cpu_flags() -> str:
    """The CPU's feature flags, upper case (/proc/cpuinfo; empty where there is none)."""
    try:
        text = Path("/proc/cpuinfo").read_text()
    except OSError:
        return ""
    return next((ln for ln in text.splitlines() if ln.startswith("flags")), "").upper()


def _contrast_case():
    """Query landmark 0 matches every reference equally well (a wall); landmark 1 matches
    reference 0 far better than the others (a rare object)."""
    e = np.eye(6)
    wall, rare = e[0], e[1]
    qd = [np.stack([wall, rare])]
    rd = [
        np.stack([0.8 * wall + 0.6 * e[2], 0.9 * rare + math.sqrt(0.19) * e[3]]),
        np.stack([0.8 * wall + 0.6 * e[4], 0.1 * rare + math.sqrt(0.99) * e[5]]),
        np.stack([0.8 * wall + 0.6 * e[3], 0.1 * rare + math.sqrt(0.99) * e[2]]),
    ]
    boxes = [np.array([BOX, BOX])] * 3
    return qd, [boxes[0]], rd, boxes


def test_contrast_by_hand_a_landmark_matching_every_place_carries_nothing():
    qd, qb, rd, rb = _contrast_case()
    plain = similarity_matrix(qd, qb, rd, rb, compute=F64)
    # cosines: wall 0.8 everywhere; rare 0.9, 0.1, 0.1 -> plain Eq. (1) (0.8 + 0.9) / 2 for r0
    np.testing.assert_allclose(plain[0], [0.85, 0.45, 0.45], atol=1e-12)
    got = similarity_matrix(qd, qb, rd, rb, matching=CONTRAST, compute=F64)
    # wall: sigma 0 -> weight 0. rare: mu 1.1/3, sigma sqrt(((0.9 - mu)^2 + 2 (0.1 - mu)^2) / 3)
    mu = 1.1 / 3
    sd = math.sqrt(((0.9 - mu) ** 2 + 2 * (0.1 - mu) ** 2) / 3)
    w0 = (0.9 - mu) / sd  # = sqrt(2): above the mean by sqrt(2) standard deviations
    assert w0 == pytest.approx(math.sqrt(2))
    np.testing.assert_allclose(got[0], [0.9 * w0 / 2, 0, 0], atol=1e-12)
    res = weighted_matches(qd, qb, rd, rb, [[0, 0], [0, 1]], CONTRAST)
    np.testing.assert_allclose(res[0].weights, [0.0, w0], atol=1e-6)
    np.testing.assert_allclose(res[1].weights, [0.0, 0.0], atol=1e-6)  # 0.1 < mu: clipped to 0
    # one reference: sigma 0 for every landmark, every weight 0
    one = similarity_matrix(qd, qb, rd[:1], rb[:1], matching=CONTRAST)
    assert one[0, 0] == 0.0


def test_idf_by_hand():
    qd, qb, rd, rb = _contrast_case()
    got = similarity_matrix(qd, qb, rd, rb, matching=IDF, compute=F64)
    # the wall matches all 3 references: log(4 / 4) = 0; the rare landmark is reciprocal in all
    # three too (each reference's landmark 1 is nearest to it), so every term weighs 0 ...
    np.testing.assert_allclose(got, 0.0, atol=1e-12)
    # ... until a reference offers the rare landmark nothing nearer than the wall
    rd2 = [rd[0], rd[1][:1], rd[2][:1]]
    rb2 = [rb[0], rb[1][:1], rb[2][:1]]
    got = similarity_matrix(qd, qb, rd2, rb2, matching=IDF, compute=F64)
    assert got[0, 0] == pytest.approx(0.9 * math.log(4 / 2) / 2, abs=1e-12)
    np.testing.assert_allclose(got[0, 1:], 0.0, atol=1e-12)


def test_weighted_same_bits_for_any_thread_count():
    qd, qb, rd, rb = _sets(13, nq=10, nr=9)
    threads = torch.get_num_threads()
    try:
        out = []
        for n in (1, 2):
            torch.set_num_threads(n)
            out.append(
                similarity_matrix(qd, qb, rd, rb, matching=CONTRAST, compute=Compute(batch_size=3))
            )
    finally:
        torch.set_num_threads(threads)
    np.testing.assert_array_equal(out[0], out[1])


def test_unknown_weighting_lists_the_valid_ones():
    with pytest.raises(ValueError, match="expected None or one of 'contrast', 'idf'"):
        Matching(weighting="Contrast")
    with pytest.raises(ValueError, match="weighting='tfidf' is not valid"):
        Matching(weighting="tfidf")


def test_matching_value_keeps_default_keys_and_labels():
    assert Matching().weighting is None
    for name in ("dense", "classical", "overlap_scheme2"):
        m = get_method(name)
        assert run_key(m) == name and "weighting" not in method_label(m)
    m = get_method("dense", weighting="contrast")
    assert run_key(m) == "dense(weighting=contrast)"
    assert method_label(m) == "dense (weighting: contrast)"
    assert (
        run_key(get_method("overlap_scheme2", weighting="idf")) == "overlap_scheme2(weighting=idf)"
    )
    # a matching option of every method, bare schemes and Method values included
    from vpr_core.landmarks.schemes import Dense

    assert as_method(Dense(), weighting="idf").matching == Matching(weighting="idf")
    both = as_method("classical", spatial="consistency", weighting="contrast")
    assert both.matching == Matching(spatial="consistency", weighting="contrast")
    assert as_method(get_method("dense"), weighting="idf").matching.weighting == "idf"


def test_run_method_passes_the_weighting_to_the_matcher():
    from vpr_core import run_method
    from vpr_core.datasets import load_dataset

    ds = load_dataset("synthetic", n_places=5, image_size=(64, 112))
    kw = {"dim": 64, "n_bootstrap": 0, "keep_descriptors": True}
    plain = run_method("dense", ds, per_scale=4, **kw)
    for weighting in tuple(WEIGHTINGS):
        r = run_method("dense", ds, per_scale=4, weighting=weighting, **kw)
        assert (
            r.config.matching.weighting == weighting
            and r.run == f"dense(per_scale=4, weighting={weighting})"
        )
        d, b = r.descriptors, r.boxes
        want = similarity_matrix(
            d["query"],
            b["query"],
            d["reference"],
            b["reference"],
            matching=Matching(weighting=weighting),
        )
        np.testing.assert_array_equal(r.similarity, want)
        assert not np.allclose(r.similarity, plain.similarity)
    # the shortlist path: Eq. (1) with the weights on each query's top 3
    r = run_method("dense", ds, per_scale=4, weighting="contrast", shortlist=3, **kw)
    assert np.isnan(r.similarity).sum() == 5 * 2
    full = run_method("dense", ds, per_scale=4, weighting="contrast", **kw).similarity
    kept = ~np.isnan(r.similarity)
    np.testing.assert_allclose(r.similarity[kept], full[kept], atol=1e-7, rtol=0)


def test_cli_eval_weighting_all_pairs_each_method_with_itself(tmp_path, capsys):
    from vpr_study import cli

    args = ["eval", "--dataset", "synthetic", "--n-places", "6", "--method", "dense", "global"]
    rc = cli.main([*args, "--weighting", "all", "--spatial", "both", "--out", str(tmp_path)])
    assert rc == 0
    out = capsys.readouterr().out
    assert "database weighting, each method with minus without" in out
    assert "dense (weighting: contrast)" in out and "global (geometry: consistency" in out
    folder = tmp_path / "results" / "synthetic"
    (table,) = folder.glob("eval_*_weighting.csv")
    got = dict(pd.read_csv(table)[["run", "baseline"]].itertuples(index=False))
    assert got["dense(weighting=contrast)"] == "dense"
    assert got["global(spatial=consistency, weighting=idf)"] == "global (geometry: consistency)"
    assert len(got) == 2 * 2 * len(tuple(WEIGHTINGS))  # methods x spatial x weightings
    (geometry,) = folder.glob("eval_*_geometry.csv")
    assert len(pd.read_csv(geometry)) == 2 * (1 + len(tuple(WEIGHTINGS)))  # methods x weightings


def test_cli_eval_weighting_both_is_without_and_with_contrast(tmp_path, capsys):
    """Issue 61: ``--weighting both`` ran four weightings; it is the two its word says."""
    from vpr_study import cli

    args = ["eval", "--dataset", "synthetic", "--n-places", "6", "--method", "global"]
    assert cli.main([*args, "--weighting", "both", "--n-bootstrap", "50",
                     "--out", str(tmp_path)]) == 0  # fmt: skip
    (table,) = (tmp_path / "results" / "synthetic").glob("eval_*_weighting.csv")
    got = pd.read_csv(table)
    assert list(got["run"]) == ["global(weighting=contrast)"]
    assert list(got["baseline"]) == ["global"]
    from vpr_study.arguments import command_parser

    parser = cli.build_parser()
    eval_help = " ".join(command_parser(parser, "eval").format_help().split())
    assert "'both': every method without and with contrast (two runs each)" in eval_help
    run_help = " ".join(command_parser(parser, "run").format_help().split())
    assert "without either flag: on for the full synthetic study" in run_help
    assert "(default: True)" not in run_help  # --no-real-data is not the default


# ---- (not in the paper) two-sided contrast (issue 55) --------------------------------------
TWO = Matching(weighting="two_sided")


def test_two_sided_reference_statistics_equal_the_oracle_and_exclude_the_reference_itself():
    qd, qb, rd, rb = _sets(31, nq=4, nr=9, dim=24)
    rd[5], rb[5] = np.zeros((0, 24), np.float32), np.zeros((0, 4))  # no landmark: not counted
    prob = Problem.build(qd, qb, rd, rb, TWO, F64)
    for ids in (np.arange(9), np.array([0, 2, 5, 8])):
        mu, sd = reference_stats(prob.r, ids)
        for r in range(9):
            want_mu, want_sd = oracle.reference_contrast(rd, r, ids)
            k = len(rd[r])
            np.testing.assert_allclose(mu[r, :k].numpy(), want_mu, atol=1e-12, rtol=0)
            np.testing.assert_allclose(sd[r, :k].numpy(), want_sd, atol=1e-12, rtol=0)
    # one reference: no other one, so w_r = 0 and the weight is 1 + w_q
    one = similarity_matrix(qd, qb, rd[:1], rb[:1], matching=TWO, compute=F64)
    want = oracle.similarity_matrix(qd, qb, rd[:1], rb[:1], weighting="two_sided")
    np.testing.assert_allclose(one, want, atol=1e-12, rtol=0)


def test_two_sided_reference_statistics_are_cached_by_the_database_content():
    qd, qb, rd, rb = _sets(33, nq=4, nr=6, dim=16)
    clear_reference_cache()
    first = similarity_matrix(qd, qb, rd, rb, matching=TWO, compute=F64)
    assert len(reference_cache_keys()) == 1
    (key,) = reference_cache_keys()
    again = similarity_matrix(qd, qb, rd, rb, matching=TWO, compute=F64)
    np.testing.assert_array_equal(first, again)
    assert reference_cache_keys() == [key]  # read, not recomputed
    # editing one reference's descriptors gives another key and new statistics
    rd2 = [d.copy() for d in rd]
    rd2[4][0] = -rd2[4][0]
    edited = similarity_matrix(qd, qb, rd2, rb, matching=TWO, compute=F64)
    assert len(reference_cache_keys()) == 2 and key in reference_cache_keys()
    want = oracle.similarity_matrix(qd, qb, rd2, rb, weighting="two_sided")
    np.testing.assert_allclose(edited, want, atol=1e-12, rtol=0)
    # the cached statistics equal a fresh computation on an empty cache
    clear_reference_cache()
    np.testing.assert_array_equal(
        similarity_matrix(qd, qb, rd2, rb, matching=TWO, compute=F64), edited
    )


def test_two_sided_shortlist_equals_exhaustive_up_to_12_references():
    qd, qb, rd, rb = _sets(35, nq=5, nr=12, dim=24)
    pairs = np.array([[q, r] for q in range(5) for r in (0, 3, 7, 11)])
    full = similarity_matrix(qd, qb, rd, rb, matching=TWO, compute=F64)
    got = similarity_pairs(qd, qb, rd, rb, pairs, matching=TWO, compute=F64)
    # the same statistics; the query side's best cosines come from another float64 matmul
    np.testing.assert_allclose(got, full[pairs[:, 0], pairs[:, 1]], atol=1e-9, rtol=0)
    # 13 references: the shortlist's statistics are the 12-reference sample's (oracle)
    qd, qb, rd, rb = _sets(35, nq=5, nr=13, dim=24)
    sample = weighting_sample(13, "two_sided")
    assert len(sample) == 12
    got = similarity_pairs(qd, qb, rd, rb, pairs, matching=TWO, compute=F64)
    want = oracle.similarity_matrix(qd, qb, rd, rb, weighting="two_sided", sample=sample)
    np.testing.assert_allclose(got, want[pairs[:, 0], pairs[:, 1]], atol=1e-9, rtol=0)


def test_two_sided_by_hand_an_ordinary_match_keeps_its_plain_term():
    """A reference landmark equally close to every other reference has w_r = 0 (sigma 0): the
    weight is 1 + w_q; contrast would give w_q alone (0 for an ordinary query landmark)."""
    e = np.eye(4, dtype=np.float32)
    q = [e[[0]]]
    refs = [e[[0]], e[[1]], e[[1]]]  # query landmark = reference 0's; others share another
    boxes = [np.array([BOX])] * 3
    sim = similarity_matrix(q, [np.array([BOX])], refs, boxes, matching=TWO, compute=F64)
    # query side: b = (1, 0, 0): mu 1/3, sd sqrt(2)/3 -> w_q = (1 - 1/3) / (sqrt(2)/3) = sqrt(2)
    # reference 0's landmark vs refs 1, 2: cosines (0, 0): sd 0 -> w_r = 0
    assert sim[0, 0] == pytest.approx(1.0 + math.sqrt(2), abs=1e-12)
    plain = similarity_matrix(q, [np.array([BOX])], refs, boxes, compute=F64)
    assert plain[0, 0] == pytest.approx(1.0)


def test_two_sided_refuses_a_distributed_shortlist():
    from vpr_study.cluster.blocks import similarity_pairs_distributed

    qd, qb, rd, rb = _sets(37, nq=4, nr=3, dim=8)
    with pytest.raises(ValueError, match="two_sided"):
        similarity_pairs_distributed(object(), qd, qb, rd, rb, np.array([[0, 1]]), TWO)
