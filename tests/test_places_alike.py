"""Notebook 07 (not in the paper): ``plot_carried_landmarks``, the landmarks that carried a top-1
the contrast weighting changed, and the silenced ones."""

from __future__ import annotations

import dataclasses

import matplotlib.pyplot as plt
import numpy as np
import pytest

from vpr_core.evaluation.steps import CARRIED_COLUMNS, SILENT_WEIGHT
from vpr_core.matching import weighted_matches
from vpr_study import viz
from vpr_study.viz._shared import FIG_WIDTH


@pytest.fixture(scope="module")
def runs():
    """A repetitive 6-place synthetic set where contrast fixes one query and breaks another."""
    from vpr_core import run_method
    from vpr_core.datasets import load_dataset

    ds = load_dataset("synthetic", n_places=6, image_size=(64, 112), repetition=0.9)
    kw = {"dim": 64, "n_bootstrap": 0, "keep_descriptors": True, "per_scale": 4}
    plain = run_method("dense", ds, **kw)
    weighted = run_method("dense", ds, weighting="contrast", **kw)
    return ds, plain, weighted


def _terms(ds, weighted, q, r):
    d, b = weighted.descriptors, weighted.boxes
    sample = np.arange(len(d["reference"]))
    (m,) = weighted_matches(
        d["query"], b["query"], d["reference"], b["reference"], [(q, r)],
        weighted.config.matching, sample,
    )  # fmt: skip
    return m


def test_carried_are_the_k_largest_terms_and_silenced_weigh_zero(runs):
    ds, plain, weighted = runs
    fig, table = viz.plot_carried_landmarks(ds, plain, weighted, n_queries=2, k=3)
    assert tuple(table.columns) == CARRIED_COLUMNS
    assert set(table["case"]) == {"fixed", "broken"}  # one query fixed, one broken
    gt = np.asarray(ds.ground_truth, dtype=bool)
    for q, rows in table.groupby("query"):
        carried = rows[rows["role"] == "carried"]
        (r,) = set(carried["reference"])
        assert r == np.nanargmax(weighted.similarity[q])  # the weighted top-1
        m = _terms(ds, weighted, q, r)
        want = np.sort(m.scores)[::-1][:3]
        np.testing.assert_allclose(carried["weighted term"], want, rtol=1e-6)
        assert list(carried["rank"]) == [1, 2, 3]
        silenced = rows[rows["role"] == "silenced"]
        assert len(silenced) >= 1 and (silenced["weight"] <= SILENT_WEIGHT).all()
        (rp,) = set(silenced["reference"])
        assert rp == np.nanargmax(plain.similarity[q])  # the plain top-1
        mp = _terms(ds, weighted, q, rp)
        plain_terms = (mp.raw_scores * mp.spatial_weights)[mp.weights <= SILENT_WEIGHT]
        want = np.sort(plain_terms)[::-1][: len(silenced)]
        np.testing.assert_allclose(silenced["plain term"], want, rtol=1e-6)
        assert (silenced["weighted term"] == 0).all()
        assert bool(gt[q, r]) == (rows["case"].iloc[0] == "fixed")
        # the place it also matches: another reference, with a cosine of that landmark
        assert (rows["also matches"] != rows["reference"]).all()
        assert rows["its cosine"].between(-1, 1).all()
    plt.close(fig)


def test_captions_read_at_the_displayed_size(runs):
    ds, plain, weighted = runs
    fig, table = viz.plot_carried_landmarks(ds, plain, weighted, n_queries=2, k=5)
    assert len(table)
    shown_at = min(1.0, 9.5 / fig.get_figwidth())
    assert fig.get_figwidth() == FIG_WIDTH
    texts = [t for t in fig.texts if t.get_text()] + [fig._suptitle]
    assert len(texts) > 10 and all(t.get_fontsize() * shown_at >= 9 for t in texts)
    assert "carried the score" in fig._suptitle.get_text()
    assert viz.layout_problems(fig) == []
    # a crop pair per landmark and a context panel per row
    assert len(fig.axes) == len(table) + 2 * table["query"].nunique()
    plt.close(fig)


def test_refuses_runs_it_cannot_explain(runs):
    from vpr_core import run_method
    from vpr_core.datasets import load_dataset

    ds, plain, weighted = runs
    with pytest.raises(ValueError, match="has no weighting"):
        viz.plot_carried_landmarks(ds, plain, plain)
    with pytest.raises(ValueError, match="must be the paper's Eq. \\(1\\)"):
        viz.plot_carried_landmarks(ds, weighted, weighted)
    bare = dataclasses.replace(weighted, descriptors=None)
    with pytest.raises(ValueError, match="keep_descriptors=True"):
        viz.plot_carried_landmarks(ds, plain, bare)
    with pytest.raises(ValueError, match="k must be a positive integer"):
        viz.plot_carried_landmarks(ds, plain, weighted, k=0)
    with pytest.raises(ValueError, match="n_queries must be"):
        viz.plot_carried_landmarks(ds, plain, weighted, n_queries=True)
    other = load_dataset("synthetic", n_places=5, image_size=(64, 112), repetition=0.9)
    kw = {"dim": 64, "n_bootstrap": 0, "per_scale": 4}
    with pytest.raises(
        ValueError, match="plot_carried_landmarks: .* was run on another dataset than"
    ):
        viz.plot_carried_landmarks(other, plain, weighted)
    other_plain = run_method("dense", other, **kw)
    with pytest.raises(
        ValueError, match="plot_carried_landmarks: .* was run on another dataset than"
    ):
        viz.plot_carried_landmarks(ds, other_plain, weighted)
    classical = run_method("dense", ds, spatial="consistency", **kw)
    with pytest.raises(ValueError, match="differ in more than the weighting"):
        viz.plot_carried_landmarks(ds, classical, weighted)


def test_the_per_query_figures_refuse_in_the_shared_wording(runs):
    """One wording per rule (issue 47): the count of queries shown, a run without descriptors."""
    ds, plain, weighted = runs
    bare = dataclasses.replace(weighted, descriptors=None)
    with pytest.raises(ValueError, match=r"n \(queries shown\) must be a positive integer"):
        viz.plot_disagreements(ds, plain, weighted, n=0)
    for call, name in (
        (viz.plot_disagreements, "plot_disagreements"),
        (viz.plot_carried_landmarks, "carried_landmarks"),
    ):
        with pytest.raises(ValueError, match=rf"^{name} needs the landmark descriptors of"):
            call(ds, plain, bare)
    with pytest.raises(ValueError, match="n_queries must be a positive integer, got 0"):
        viz.plot_carried_landmarks(ds, plain, weighted, n_queries=0)
    with pytest.raises(ValueError, match=r"^'dense[^']*' has no weighting: pass the run of"):
        viz.plot_carried_landmarks(ds, plain, plain)
    from vpr_core.datasets import load_dataset

    other = load_dataset("synthetic", n_places=5, image_size=(64, 112), repetition=0.9)
    for call in (viz.plot_disagreements, viz.plot_carried_landmarks):
        with pytest.raises(ValueError, match=rf"^{call.__name__}: .* another dataset than"):
            call(other, plain, weighted)


def test_no_changed_top1_says_so(runs):
    ds, plain, weighted = runs
    same = dataclasses.replace(weighted, similarity=np.asarray(plain.similarity).copy())
    fig, table = viz.plot_carried_landmarks(ds, plain, same)
    assert table.empty and tuple(table.columns) == CARRIED_COLUMNS
    assert any("changed no query's top-1" in t.get_text() for t in fig.texts)
    assert "(0 of 6 queries; 0 shown)" in fig._suptitle.get_text().replace("\n", " ")
    plt.close(fig)


def test_notebook_07_runs_on_every_study_label():
    from vpr_study import catalogue, runner
    from vpr_study.figures import expected_figures

    assert "07_places_alike" in runner.REAL_DATA_NOTEBOOKS
    for label in ("synthetic", "gardens_point_mini", "nordland_step50"):
        assert "07_places_alike" in catalogue.LABEL_NOTEBOOKS[label], label
    assert expected_figures()["07_places_alike"] == [
        "places_alike_pr",
        "places_alike_carried",
        "places_alike_steps",
        "places_alike_vs_contrast",
        "places_alike_changes",
        "places_alike_whitening",
    ]
    assert catalogue.TABLES["07_places_alike"] == (
        "places_alike",
        "places_alike_carried",
        "places_alike_steps",
        "places_alike_vs_contrast",
        "places_alike_changes",
        "places_alike_vs_best",
        "places_alike_whitening",
    )


def test_whitening_figure_reads_at_a_glance_and_refuses_what_it_cannot_explain(runs):
    """(Not in the paper, issue 62) ``plot_whitening``: the shares of a match's cosine before and
    after, each chosen query's references by rank, one table row per query and reference."""
    from vpr_core import run_method
    from vpr_core.evaluation.whitening import WHITENING_COLUMNS

    ds, plain, weighted = runs
    kw = {"dim": 64, "n_bootstrap": 0, "keep_descriptors": True, "per_scale": 4}
    white = run_method("dense", ds, whiten=16, **kw)
    fig, table = viz.plot_whitening(ds, plain, white, n_queries=2)
    assert tuple(table.columns) == WHITENING_COLUMNS and len(table)
    assert fig.get_figwidth() == FIG_WIDTH and viz.layout_problems(fig) == []
    assert len(fig.axes) == 1 + table["query"].nunique()
    assert (table["shared share"].dropna().between(-1, 2)).all() and table["why"].str.len().gt(
        0
    ).all()
    for _q, rows in table.groupby("query"):  # the top-1 before and after are among the rows
        assert 1 in set(rows["rank before"]) and 1 in set(rows["rank after"])
    texts = [t for ax in fig.axes for t in ax.texts] + [fig._suptitle]
    assert all(t.get_fontsize() >= 9 for t in texts)
    assert "16 components" in fig._suptitle.get_text()
    plt.close(fig)
    with pytest.raises(ValueError, match="is not whitened"):
        viz.plot_whitening(ds, plain, plain)
    with pytest.raises(ValueError, match="without whitening"):
        viz.plot_whitening(ds, white, white)
    with pytest.raises(ValueError, match="differ in more than the whitening"):
        viz.plot_whitening(ds, weighted, white)
    with pytest.raises(ValueError, match="whitening_changes needs the landmark descriptors"):
        viz.plot_whitening(ds, plain, dataclasses.replace(white, descriptors=None))
