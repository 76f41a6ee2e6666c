"""(Not in the paper) normalisation of a similarity matrix (issue 55): the definitions of
docs/DEFINITIONS.md on hand-made matrices, and the value through run_method and compare."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vpr_core.matching import Matching, needs_query_batch, normalise_matrix
from vpr_core.matching.normalise import (
    NORMALISE_K,
    database_normalise,
    database_offsets,
    query_batch_normalise,
)


def test_query_batch_by_hand():
    s = np.array([[1.0, 0.0], [3.0, 2.0]])
    # rows: mean .5 / 2.5, std .5 -> (+1, -1) each; columns: means 2 / 1, std 1 -> (-1, +1)
    want = np.array([[1.0 - 1.0, -1.0 - 1.0], [1.0 + 1.0, -1.0 + 1.0]])
    np.testing.assert_allclose(query_batch_normalise(s), want, atol=1e-15)
    np.testing.assert_allclose(normalise_matrix(s, "query_batch"), np.exp(want), atol=1e-15)
    assert needs_query_batch("query_batch") and not needs_query_batch("database")
    assert not needs_query_batch(None)


def test_query_batch_depends_on_the_other_queries_and_skips_nan():
    s = np.array([[0.9, 0.2, np.nan], [0.1, 0.8, 0.3], [0.5, 0.5, 0.4]])
    z = query_batch_normalise(s)
    assert np.isnan(z[0, 2]) and np.isfinite(z[[1, 2]]).all()
    # row 0's z over its two ranked entries: +1, -1
    row = (s[0, :2] - s[0, :2].mean()) / s[0, :2].std()
    col = (s[0, :2] - np.nanmean(s[:, :2], 0)) / np.nanstd(s[:, :2], 0)
    np.testing.assert_allclose(z[0, :2], row + col, atol=1e-12)
    # another batch changes query 0's values (it needs the batch)
    other = query_batch_normalise(s[[0, 1]])
    assert not np.allclose(other[0, :2], z[0, :2])
    # a constant row or a column with one ranked entry: that term is 0
    c = query_batch_normalise(np.array([[0.5, 0.5], [0.1, 0.9]]))
    np.testing.assert_allclose(c[0], (np.array([0.5, 0.5]) - [0.3, 0.7]) / 0.2 + 0.0, atol=1e-12)


def test_database_offsets_by_hand():
    db = np.array(
        [
            [9.0, 0.8, 0.2, 0.5],
            [0.8, 9.0, 0.1, np.nan],
            [0.2, 0.1, 9.0, 0.3],
            [0.5, np.nan, 0.3, 9.0],
        ]
    )
    # the diagonal is left out; k = 2 largest others
    np.testing.assert_allclose(database_offsets(db, 2), [0.65, 0.45, 0.25, 0.4], atol=1e-15)
    # k larger than the ranked others: their mean; NaN left out
    np.testing.assert_allclose(database_offsets(db, 10), [0.5, 0.45, 0.2, 0.4], atol=1e-15)
    np.testing.assert_array_equal(database_offsets(np.array([[1.0]]), 10), [0.0])  # no other
    assert NORMALISE_K == 10
    s = np.array([[0.7, 0.6, 0.1, 0.4]])
    got = database_normalise(s, db, 2)
    np.testing.assert_allclose(got, s - [0.65, 0.45, 0.25, 0.4], atol=1e-15)
    # a single query: its row depends on itself and the database only
    two = np.vstack([s, [[0.0, 0.0, 1.0, 0.0]]])
    np.testing.assert_array_equal(database_normalise(two, db, 2)[0], got[0])
    np.testing.assert_allclose(
        normalise_matrix(s, "database", db), np.exp(database_normalise(s, db)), atol=1e-15
    )


def test_normalise_errors_name_the_fix():
    with pytest.raises(ValueError, match="needs the references scored against each other"):
        normalise_matrix(np.ones((2, 2)), "database")
    with pytest.raises(
        ValueError, match="unknown normalise 'zscore'; valid: query_batch, database"
    ):
        normalise_matrix(np.ones((2, 2)), "zscore")
    with pytest.raises(ValueError, match="normalise='zscore' is not valid"):
        Matching(normalise="zscore")
    with pytest.raises(ValueError, match="square"):
        database_offsets(np.ones((2, 3)))
    with pytest.raises(ValueError, match="score the same references"):
        database_normalise(np.ones((2, 3)), np.ones((2, 2)))
    assert normalise_matrix(np.ones((2, 2)), None) is not None


def test_the_value_in_the_engine_and_run_method():
    from test_matching import _random_sets

    from vpr_core import run_method
    from vpr_core.datasets import load_dataset
    from vpr_core.matching import similarity_matrix, similarity_pairs
    from vpr_core.methods import get_method, method_label, run_key

    rng = np.random.default_rng(55)
    qd, qb = _random_sets(rng, 4, 2, 9, 16)
    rd, rb = _random_sets(rng, 5, 2, 9, 16)
    plain = similarity_matrix(qd, qb, rd, rb)
    db = similarity_matrix(rd, rb, rd, rb)
    assert np.isfinite(normalise_matrix(plain, "database", db)).all()
    # one door: a whole-matrix step is refused by every matching call, named with the fix
    for call in (
        lambda m: similarity_matrix(qd, qb, rd, rb, matching=m),
        lambda m: similarity_pairs(qd, qb, rd, rb, [[0, 0]], matching=m),
    ):
        with pytest.raises(
            ValueError, match=r"a step on a whole .* run_method\(\.\.\., normalise="
        ):
            call(Matching(normalise="database"))
    # names and labels; the paper's keys unchanged
    m = get_method("dense", normalise="query_batch")
    assert run_key(m) == "dense(normalise=query_batch)"
    assert method_label(m) == "dense (normalised: query_batch, needs the query batch)"
    assert run_key(get_method("dense")) == "dense"
    # run_method: the Eq. (1) matrix is reused, the step applied after
    ds = load_dataset("synthetic", n_places=5, image_size=(64, 112))
    kw = {"dim": 32, "n_bootstrap": 0, "per_scale": 4, "keep_descriptors": True}
    base = run_method("dense", ds, **kw)
    q = run_method("dense", ds, normalise="query_batch", **kw)
    np.testing.assert_allclose(q.similarity, normalise_matrix(base.similarity, "query_batch"))
    d = run_method("dense", ds, normalise="database", **kw)
    dd, bb = base.descriptors, base.boxes
    self_sim = similarity_matrix(dd["reference"], bb["reference"], dd["reference"], bb["reference"])
    np.testing.assert_allclose(
        d.similarity, normalise_matrix(base.similarity, "database", self_sim), atol=1e-12
    )
    # the shortlist path: NaN off the shortlist stays NaN
    s = run_method("dense", ds, normalise="query_batch", shortlist=3, **kw)
    assert np.isnan(s.similarity).sum() == 5 * 2
    assert math.isfinite(s.metrics["auc"])


def test_a_peer_normalised_and_compare_says_where_the_batch_is_needed():
    from vpr_core import normalise_result
    from vpr_core.datasets import load_dataset
    from vpr_core.evaluation import compact, compare
    from vpr_study.peers import peer_from_matrix, peer_result

    ds = load_dataset("synthetic", n_places=6, image_size=(64, 112))
    rng = np.random.default_rng(3)
    m = rng.random((6, 6)) + np.eye(6) * 0.3
    peer = peer_result(peer_from_matrix(m, "mine"), ds, n_bootstrap=50)
    q = normalise_result(peer, "query_batch")
    np.testing.assert_allclose(q.similarity, normalise_matrix(peer.similarity, "query_batch"))
    assert q.label == f"{peer.label} (normalised: query_batch)" and len(q.intervals) == 4
    d = normalise_result(peer, "database", database=m.T @ m)
    table = compare([peer, q, d], n_bootstrap=50)
    assert list(table["query batch"]) == ["not needed", "needed", "not needed"]
    # a table without a query-batch normalisation keeps the paper's columns (byte-identical)
    assert "query batch" not in compare([peer, d], n_bootstrap=50).columns
    shown = compact(table)
    assert shown.loc[q.label, "query batch"] == "needed"
    assert shown.loc[peer.label, "query batch"] == ""
    assert {"dAUC verdict", "dR@1 verdict"} <= set(table.columns)


def test_cli_eval_normalise_both_pairs_each_method_with_itself(tmp_path, capsys):
    import pandas as pd

    from vpr_study import cli

    args = ["eval", "--dataset", "synthetic", "--n-places", "6", "--method", "dense"]
    rc = cli.main([*args, "--normalise", "both", "--n-bootstrap", "50", "--out", str(tmp_path)])
    assert rc == 0
    out = capsys.readouterr().out
    assert "normalisation, each method with minus without" in out
    (table,) = (tmp_path / "results" / "synthetic").glob("eval_*_normalise.csv")
    got = pd.read_csv(table)
    assert list(got["run"]) == ["dense(normalise=query_batch)", "dense(normalise=database)"]
    assert list(got["baseline"]) == ["dense", "dense"]
    assert list(got["query batch"]) == ["needed", "not needed"]


def test_step_changes_names_what_moved_each_reference():
    from vpr_core import run_method, step_changes
    from vpr_core.datasets import load_dataset

    ds = load_dataset("synthetic", n_places=6, image_size=(64, 112))
    kw = {"dim": 32, "n_bootstrap": 0, "per_scale": 4}
    plain = run_method("dense", ds, **kw)
    two = run_method("dense", ds, weighting="two_sided", keep_descriptors=True, **kw)
    t = step_changes(plain, two, n_queries=2, top=3)
    assert len(t) and set(t["query"]) <= set(range(6))
    assert t["why"].str.contains("w_r").any() or t["why"].str.contains("no reciprocal").all()
    for how, word in (("query_batch", "column z"), ("database", "rho")):
        t = step_changes(plain, run_method("dense", ds, normalise=how, **kw), top=2)
        assert t["why"].str.contains(word).all()
        for _q, rows in t.groupby("query"):
            assert list(rows["rank after"]) == sorted(rows["rank after"])
    with pytest.raises(ValueError, match="one more step"):
        step_changes(plain, run_method("dense", ds, dim=32, n_bootstrap=0, per_scale=9))


def test_degenerate_matrices_are_named_and_a_scale_changes_no_z_score():
    """Issue 60 item 8: a positive scale changes no normalisation (1e300 overflowed into a
    constant matrix), an infinite entry is refused naming the fix (it became 'not ranked'), a
    peer whose rows are each constant gets the chance notice, and no result is normalised
    twice."""
    from vpr_core import normalise_result
    from vpr_core.datasets import load_dataset
    from vpr_study.peers import peer_from_matrix, peer_result

    rng = np.random.default_rng(8)
    s = rng.random((6, 7))
    s[1, 2] = np.nan
    want = normalise_matrix(s, "query_batch")
    for scale in (1e300, 1e-300, 1e-9, 1e9):
        np.testing.assert_allclose(normalise_matrix(s * scale, "query_batch"), want, rtol=1e-9)
    bad = s.copy()
    bad[2, 3] = np.inf
    with pytest.raises(ValueError, match=r"similarity\[2, 3\] is inf: normalise='query_batch'"):
        normalise_matrix(bad, "query_batch")
    ds = load_dataset("synthetic", n_places=6, image_size=(64, 112))
    rows = np.repeat(np.arange(6.0)[:, None], 6, axis=1)  # each row one value of its own
    with pytest.warns(UserWarning, match="each query's row of the similarity matrix is constant"):
        peer = peer_result(peer_from_matrix(rows, "rows"), ds, n_bootstrap=0)
    assert any("each query's row" in w for w in peer.warnings)
    m = rng.random((6, 6))
    scaled = peer_result(peer_from_matrix(m * 1e300, "big"), ds, n_bootstrap=0)
    small = peer_result(peer_from_matrix(m, "small"), ds, n_bootstrap=0)
    once = normalise_result(scaled, "query_batch")
    np.testing.assert_allclose(
        once.similarity, normalise_result(small, "query_batch").similarity, rtol=1e-9
    )
    with pytest.raises(ValueError, match="is already normalised \\('query_batch'\\)"):
        normalise_result(once, "query_batch")
