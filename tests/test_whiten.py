"""(Not in the paper) whitening of the landmark descriptors on the reference database (issue 62):
the definition of docs/DEFINITIONS.md against an independent numpy oracle, its edge cases, its
content key, and the value through run_method (None bit for bit), the engine and the CLI."""

from __future__ import annotations

import contextlib
import dataclasses
import shutil
import warnings

import numpy as np
import pytest

from vpr_core.matching import (
    Matching,
    match_landmarks,
    similarity_matrix,
    similarity_pairs,
    weighted_matches,
)
from vpr_core.matching.whiten import (
    WHITEN_CACHE_SIZE,
    WHITEN_FLOOR,
    WHITEN_K,
    clear_whitening_cache,
    fit_whitening,
    whiten_descriptors,
    whiten_landmarks,
    whitening_cache_keys,
    whitening_key,
)


def _sets(rng, n, dim, kmin=0, kmax=12, scale=None):
    """``n`` images' ``(K_i, dim)`` float32 descriptors (some empty), with uneven norms."""
    out = []
    for k in rng.integers(kmin, kmax + 1, n):
        d = rng.standard_normal((k, dim)) + 0.8  # a shared offset, as CNN features have
        if scale is not None:
            d = d * scale
        out.append((d * rng.uniform(0.5, 3.0, (k, 1))).astype(np.float32))
    return out


def _oracle(query, reference, k):
    """The definition, written out again: fit on the references only, then transform."""

    def l2(x):
        n = np.linalg.norm(x, axis=1, keepdims=True)
        return np.where(n > 0, x / np.where(n > 0, n, 1), 0.0)

    x = l2(np.concatenate([np.asarray(d, np.float64) for d in reference if len(d)]))
    m = x.mean(0)
    cov = np.cov(x, rowvar=False, bias=True)  # population covariance
    lam, u = np.linalg.eigh(cov)
    lam, u = lam[::-1], u[:, ::-1]
    keep = [i for i in range(min(k, len(lam))) if lam[i] > WHITEN_FLOOR * lam[0]]
    p = u[:, keep] / np.sqrt(lam[keep])

    def f(side):
        return [l2((l2(np.asarray(d, np.float64)) - m) @ p) if len(d) else d for d in side]

    return f(query), f(reference), lam[keep]


def _gram(side):
    x = np.concatenate([d for d in side if len(d)])
    return np.asarray(x, np.float64) @ np.asarray(x, np.float64).T


def test_fit_and_transform_equal_an_independent_oracle():
    rng = np.random.default_rng(62)
    q, r = _sets(rng, 5, 24), _sets(rng, 9, 24)
    r[3] = np.zeros((0, 24), np.float32)  # an image without landmarks adds nothing
    for k in (6, 24, 256):
        with pytest.warns(UserWarning, match="kept 24") if k > 24 else contextlib.nullcontext():
            got_q, got_r, fit = whiten_landmarks(q, r, k)
        want_q, want_r, lam = _oracle(q, r, k)
        assert fit.kept == len(lam) == min(k, 24)
        np.testing.assert_allclose(fit.eigenvalues, lam, rtol=1e-9)
        assert all(a.dtype == np.float32 for a in got_q + got_r)
        assert [a.shape for a in got_r] == [(len(d), fit.kept) for d in r]
        # the cosines do not depend on an eigenvector's sign: compare Gram matrices
        for got, want in ((got_q, want_q), (got_r, want_r)):
            np.testing.assert_allclose(_gram(got), _gram(want), atol=2e-6)
        # each landmark comes out a unit vector
        norms = np.linalg.norm(np.concatenate(got_q), axis=1)
        np.testing.assert_allclose(norms, 1.0, atol=1e-6)


def test_queries_never_enter_the_fit():
    rng = np.random.default_rng(1)
    r = _sets(rng, 8, 16, kmin=3)
    q1, q2 = _sets(rng, 4, 16), _sets(rng, 7, 16)
    a_q, a_r, fit_a = whiten_landmarks(q1, r, 8)
    b_q, b_r, fit_b = whiten_landmarks(q2, r, 8)
    assert fit_a is fit_b and fit_a.key == whitening_key(r, 8)
    for x, y in zip(a_r, b_r, strict=True):
        np.testing.assert_array_equal(x, y)
    # a query's whitened descriptor is the same whatever the other queries are
    np.testing.assert_array_equal(whiten_descriptors(q1[:1], fit_a)[0], a_q[0])
    clear_whitening_cache()
    np.testing.assert_array_equal(
        np.concatenate(whiten_landmarks(q2, r, 8)[1]), np.concatenate(a_r)
    )


def test_the_key_changes_with_k_and_the_references_and_the_cache_is_bounded():
    rng = np.random.default_rng(2)
    r = _sets(rng, 6, 16, kmin=4)
    key = whitening_key(r, 8)
    assert whitening_key(r, 8) == key and whitening_key(r, 9) != key
    edited = [d.copy() for d in r]
    edited[2][0, 0] += 1e-3
    assert whitening_key(edited, 8) != key
    assert whitening_key([d.astype(np.float64) for d in r], 8) != key  # dtype is content
    clear_whitening_cache()
    fits = [fit_whitening(_sets(rng, 6, 16, kmin=4), 4) for _ in range(WHITEN_CACHE_SIZE + 1)]
    kept = whitening_cache_keys()
    assert len(kept) == WHITEN_CACHE_SIZE and fits[0].key not in kept and fits[-1].key in kept
    assert clear_whitening_cache() == WHITEN_CACHE_SIZE and whitening_cache_keys() == []


def test_fewer_landmarks_than_k_and_a_rank_deficient_covariance():
    rng = np.random.default_rng(3)
    # 7 reference landmarks in 32 dimensions: their centred span has at most 6 directions
    few = [rng.standard_normal((3, 32)).astype(np.float32), rng.standard_normal((4, 32))]
    with pytest.warns(UserWarning, match=r"whiten=256 kept 6 components \(7 reference"):
        q, r, fit = whiten_landmarks([rng.standard_normal((5, 32))], few, WHITEN_K)
    assert fit.kept == 6 and q[0].shape == (5, 6) and "not 256" in fit.shortfall()
    # 200 landmarks in a 5-d subspace of 40-d (plus float32 rounding): 5 components kept
    basis = rng.standard_normal((5, 40))
    sub = [(rng.standard_normal((20, 5)) @ basis + 2.0).astype(np.float32) for _ in range(10)]
    fit = fit_whitening(sub, 16)
    _, _, lam = _oracle([], sub, 16)
    assert fit.kept <= 6 and len(lam) == fit.kept  # the mean adds at most one direction
    assert fit.shortfall() is not None
    # enough landmarks: nothing said
    assert fit_whitening(_sets(rng, 20, 8, kmin=5), 8).shortfall() is None
    # fewer than two distinct landmarks: refused with the reason
    with pytest.raises(ValueError, match="at least two distinct reference landmarks"):
        fit_whitening([np.ones((1, 8), np.float32)], 4)
    with pytest.raises(ValueError, match="no component above"):
        fit_whitening([np.ones((5, 8), np.float32)], 4)
    with pytest.raises(ValueError, match="whiten"):
        fit_whitening(sub, 0)
    fit = fit_whitening(sub, 16)
    with pytest.raises(ValueError, match="same encoder"):
        whiten_descriptors([np.ones((2, 8), np.float32)], fit)


@pytest.mark.parametrize("bad", [0, -1, 2.5, True, "256", [256]])
def test_matching_checks_whiten_in_its_constructor(bad):
    with pytest.raises(ValueError, match=r"option whiten=.* expected None or an integer >= 1"):
        Matching(whiten=bad)


def test_names_labels_and_run_keys_name_it_and_none_changes_nothing():
    from vpr_core.landmarks.schemes import Dense
    from vpr_core.methods import METHODS, as_method, get_method, method_label, run_key

    assert Matching(whiten=256.0).whiten == 256 and "whiten" in Matching().options()
    assert Matching(whiten=None) == Matching() and Matching().note() == ""
    m = get_method("dense", whiten=256, weighting="contrast", normalise="query_batch")
    assert run_key(m) == "dense(normalise=query_batch, weighting=contrast, whiten=256)"
    assert "whitened: 256" in method_label(m)
    assert as_method(METHODS["dense"], whiten=8).matching.whiten == 8  # a value takes it too
    assert as_method(Dense(per_scale=4), whiten=8).matching == Matching(whiten=8)
    assert run_key(get_method("dense", whiten=None)) == "dense"
    assert method_label(get_method("dense", whiten=None)) == method_label(get_method("dense"))


def test_the_engine_refuses_it_naming_run_method():
    rng = np.random.default_rng(4)
    d = _sets(rng, 3, 8, kmin=2)
    b = [np.c_[rng.uniform(0, 20, (len(x), 2)), rng.uniform(5, 20, (len(x), 2))] for x in d]
    w = Matching(whiten=4)
    for call in (
        lambda: similarity_matrix(d, b, d, b, matching=w),
        lambda: similarity_pairs(d, b, d, b, [[0, 0]], matching=w),
        lambda: weighted_matches(d, b, d, b, [[0, 0]], dataclasses.replace(w, weighting="idf")),
        lambda: match_landmarks(d[0], b[0], d[1], b[1], w),
    ):
        with pytest.raises(ValueError, match=r"run_method\(\.\.\., whiten=4\).*whiten_landmarks"):
            call()


@pytest.fixture(scope="module")
def small():
    from vpr_core.datasets import load_dataset

    return load_dataset("synthetic", n_places=5, image_size=(64, 112))


KW = {"dim": 32, "n_bootstrap": 0, "per_scale": 4, "keep_descriptors": True}


def test_none_is_bit_for_bit_and_keeps_the_matrix_key(small):
    from vpr_core import run_method
    from vpr_core.cache import images_fingerprint
    from vpr_core.utils import array_sha256, cache_dir, code_version, config_slug

    base = run_method("dense", small, **KW)
    none = run_method("dense", small, whiten=None, **KW)
    np.testing.assert_array_equal(base.similarity, none.similarity)
    assert none.label == base.label and none.warnings == base.warnings
    # the matrix key is the one written before `whiten` existed (its five Matching fields)
    d, b = base.descriptors, base.boxes
    inputs = [a for s in ("query", "reference") for p in zip(b[s], d[s], strict=True) for a in p]
    key = {
        "inputs": array_sha256(inputs),
        "matching": {
            "soft_nms_iou": None,
            "sigma": 0.5,
            "spatial": None,
            "weighting": None,
            "normalise": None,
        },
        "shortlist": None,
        "code": code_version("matching"),
    }
    folder = cache_dir("results", f"{small.name}-{images_fingerprint(small)}")
    assert (folder / f"{config_slug('dense', key)}.npz").is_file()


def test_run_method_whitens_both_sides_once_and_composes(small):
    from vpr_core import run_method
    from vpr_core.matching import normalise_matrix

    plain = run_method("dense", small, **KW)
    d, b = plain.descriptors, plain.boxes
    wq, wr, fit = whiten_landmarks(d["query"], d["reference"], 8)
    run = run_method("dense", small, whiten=8, **KW)
    assert run.warnings == [] and run.config.matching.whiten == 8
    for got, want in zip(run.descriptors["reference"], wr, strict=True):  # what Eq. (1) saw
        np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(
        run.similarity, similarity_matrix(wq, b["query"], wr, b["reference"])
    )
    assert not np.array_equal(run.similarity, plain.similarity)
    # with a weighting and a normalisation: Eq. (1) on the whitened descriptors, then the step
    c = Matching(weighting="contrast")
    want = similarity_matrix(wq, b["query"], wr, b["reference"], matching=c)
    got = run_method("dense", small, whiten=8, weighting="contrast", **KW)
    np.testing.assert_array_equal(got.similarity, want)
    got = run_method("dense", small, whiten=8, weighting="contrast", normalise="query_batch", **KW)
    np.testing.assert_array_equal(got.similarity, normalise_matrix(want, "query_batch"))
    # a shortlist: the same pairs as without whitening (whole-image descriptors unwhitened)
    s_plain = run_method("dense", small, shortlist=3, **KW)
    s_white = run_method("dense", small, shortlist=3, whiten=8, weighting="two_sided", **KW)
    assert np.array_equal(np.isnan(s_plain.similarity), np.isnan(s_white.similarity))
    pairs = np.argwhere(~np.isnan(s_white.similarity))
    vals = similarity_pairs(
        wq, b["query"], wr, b["reference"], pairs, Matching(weighting="two_sided")
    )
    np.testing.assert_array_equal(s_white.similarity[pairs[:, 0], pairs[:, 1]], vals)
    # more components than the 32-d descriptors have: said on the result
    with pytest.warns(UserWarning, match="kept 32"):
        many = run_method("dense", small, whiten=WHITEN_K, **KW)
    assert any("kept 32 components (80 reference landmarks" in w for w in many.warnings)
    assert many.descriptors["query"][0].shape == (16, 32)


def test_run_method_applies_what_the_rooms_table_names(small, tmp_path, monkeypatch):
    """The whitening is one function and one entry of its room's table: run_method applies the
    function ``DESCRIPTOR_STEPS["whiten"]`` names, once, with the run's value, and Eq. (1) sees
    what it returns (here a step that changes nothing: the matrix is the plain one)."""
    from vpr_core import run_method
    from vpr_core.matching.whiten import DESCRIPTOR_STEPS

    monkeypatch.setenv("VPR_CACHE_DIR", str(tmp_path / "cache"))
    plain = run_method("dense", small, **KW)
    calls = []

    def unchanged(query, reference, value):
        calls.append((len(query), len(reference), value))
        return list(query), list(reference), None

    monkeypatch.setitem(DESCRIPTOR_STEPS, "whiten", unchanged)
    run = run_method("dense", small, whiten=8, **KW)
    assert calls == [(len(small.query_paths), len(small.reference_paths), 8)]
    np.testing.assert_array_equal(run.similarity, plain.similarity)
    assert run.config.matching.whiten == 8 and "whitened: 8" in run.label


class _Recording:
    """A fake :class:`vpr_core.run.Executor`: matches in-process and records what it got."""

    def __init__(self) -> None:
        self.seen: list = []

    def encode(self, *args):
        raise AssertionError("the features are cached: nothing to encode")

    def similarity_matrix(self, qd, qb, rd, rb, matching):
        self.seen.append((qd, rd, matching))
        return similarity_matrix(qd, qb, rd, rb, matching=matching)

    def similarity_pairs(self, qd, qb, rd, rb, pairs, matching):
        self.seen.append((qd, rd, matching))
        return similarity_pairs(qd, qb, rd, rb, pairs, matching)


def test_an_executor_gets_whitened_descriptors_and_a_matching_without_whiten(
    small, tmp_path, monkeypatch
):
    from vpr_core import run_method

    monkeypatch.setenv("VPR_CACHE_DIR", str(tmp_path / "cache"))
    local = [run_method("dense", small, whiten=8, shortlist=s, **KW) for s in (None, 3)]
    shutil.rmtree(tmp_path / "cache" / "results")  # the features stay cached, the matrices go
    ex = _Recording()
    remote = [
        run_method("dense", small, whiten=8, shortlist=s, executor=ex, **KW) for s in (None, 3)
    ]
    assert len(ex.seen) == 2
    for qd, rd, matching in ex.seen:
        assert matching.whiten is None and matching == Matching()
        np.testing.assert_array_equal(
            np.concatenate(rd), np.concatenate(local[0].descriptors["reference"])
        )
        assert all(d.shape[1] == 8 for d in qd)
    for a, b in zip(local, remote, strict=True):
        np.testing.assert_array_equal(a.similarity, b.similarity)


def test_cli_eval_whiten_both_pairs_each_method_with_itself(tmp_path, capsys):
    import pandas as pd

    from vpr_study import cli

    args = ["eval", "--dataset", "synthetic", "--n-places", "6", "--method", "dense"]
    rc = cli.main([*args, "--whiten", "both", "--n-bootstrap", "50", "--out", str(tmp_path)])
    assert rc == 0
    out = " ".join(capsys.readouterr().out.split())  # the lines wrap at the terminal's width
    assert "whitening on the reference database, each method with minus without" in out
    (table,) = (tmp_path / "results" / "synthetic").glob("eval_*_whiten.csv")
    got = pd.read_csv(table)
    assert list(got["run"]) == ["dense(whiten=256)"] and list(got["baseline"]) == ["dense"]
    with pytest.raises(SystemExit):
        cli.main([*args, "--whiten", "0"])
    assert "none, both or an integer >= 1" in capsys.readouterr().err


def test_a_best_score_at_or_below_zero_is_said_under_the_ratio_protocol():
    from vpr_core.matching.whiten import score_sign_notice

    s = np.array([[0.3, -0.1, np.nan], [-0.2, -0.4, -0.3], [np.nan, np.nan, np.nan], [0.0, -1, -1]])
    gt = np.array([[1, 0, 0], [0, 1, 0], [1, 0, 0], [0, 0, 0]], dtype=bool)
    with pytest.warns(UserWarning, match=r"whitening: 1 of 2 queries have a best score <= 0"):
        score_sign_notice(s, gt, "ratio")  # the query without ground truth is not counted
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        score_sign_notice(s, gt, "best_match")  # only the ratio protocol divides by S1
        score_sign_notice(np.abs(s) + 0.1, gt, "ratio")
