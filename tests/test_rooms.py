"""One room per kind of step (issue 59): a weighting and a normalisation added as one function and
one table entry, from this file alone, run end to end: ``run_method`` -> ``compare`` -> notebook
07's steps table and its figure; and a whole-matrix step has one door."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import pytest  # noqa: E402
import torch  # noqa: E402

from vpr_core import (  # noqa: E402
    NORMALISATIONS,
    WEIGHTINGS,
    Matching,
    Normalisation,
    Weighting,
    compare,
    load_dataset,
    normalise_result,
    run_method,
    similarity_matrix,
    step_changes,
)
from vpr_study.viz import plot_paired_differences  # noqa: E402


def halve_weak(c: torch.Tensor, mu: torch.Tensor, sd: torch.Tensor) -> torch.Tensor:
    """A toy weighting: a term counts half when its cosine is below the landmark's mean."""
    return torch.where(c.clamp(-1.0, 1.0) >= mu, 1.0, 0.5).to(c.dtype)


def rank_rows(similarity: np.ndarray, database: np.ndarray | None) -> np.ndarray:
    """A toy normalisation: each row's values replaced by their ranks (NaN stays NaN)."""
    order = np.argsort(np.argsort(np.where(np.isnan(similarity), -np.inf, similarity), axis=1))
    return np.where(np.isnan(similarity), np.nan, order.astype(np.float64) + 1.0)


@pytest.fixture()
def rooms(monkeypatch):
    monkeypatch.setitem(WEIGHTINGS, "halve_weak", Weighting(halve_weak))
    monkeypatch.setitem(NORMALISATIONS, "rank_rows", Normalisation(rank_rows))


def test_a_new_weighting_and_normalisation_run_end_to_end(rooms):
    ds = load_dataset("synthetic", n_places=6, image_size=(64, 112))
    kw = {"dim": 32, "n_bootstrap": 100}
    # notebook 07's steps cell, with the two new steps beside one of the package's
    steps = {
        "contrast": {"weighting": "contrast"},
        "halve_weak": {"weighting": "halve_weak"},
        "rank_rows": {"normalise": "rank_rows"},
        "halve_weak + rank_rows": {"weighting": "halve_weak", "normalise": "rank_rows"},
    }
    tables = []
    for m in ("dense", "global"):
        group = [run_method(m, ds, **kw)]
        group += [run_method(m, ds, **opts, **kw) for opts in steps.values()]
        tables.append(compare(group, baseline=0))
    table = pd.concat(tables)
    runs = " ".join(table["run"])
    for key in ("weighting=halve_weak", "normalise=rank_rows"):
        assert runs.count(key) == 4, runs  # each method, alone and together
    fig = plot_paired_differences(table, title="toy steps")
    labels = [t.get_text() for ax in fig.axes for t in ax.get_yticklabels()]
    assert any("halve_weak" in t for t in labels) and any("rank_rows" in t for t in labels)
    matplotlib.pyplot.close(fig)
    # the steps computed what they say: the weighting inside Eq. (1), the normalisation once,
    # on the result's matrix (NaN kept), by the one door result_from_matrix
    plain = run_method("dense", ds, **kw)
    ranked = run_method("dense", ds, normalise="rank_rows", **kw)
    np.testing.assert_array_equal(ranked.similarity, rank_rows(plain.similarity, None))
    np.testing.assert_array_equal(
        normalise_result(plain, "rank_rows").similarity, ranked.similarity
    )
    halved = run_method("dense", ds, weighting="halve_weak", keep_descriptors=True, **kw)
    assert not np.array_equal(halved.similarity, plain.similarity)
    assert (halved.similarity <= plain.similarity + 1e-12).all()  # weights 0.5 or 1
    assert "halve_weak" in halved.label and "rank_rows" in ranked.label
    # what a step changed, query by query, reads the table entry too
    changes = step_changes(plain, ranked, n_queries=1, top=2)
    assert changes.empty or changes["why"].str.contains("rank_rows").all()


def test_a_new_weighting_is_keyed_by_its_code(rooms, monkeypatch):
    """Its matrix is cached by what the weighting computes: the same name with other code
    gives another matrix, never the first one's from the cache."""
    ds = load_dataset("synthetic", n_places=5, image_size=(64, 112))
    kw = {"dim": 32, "per_scale": 4, "n_bootstrap": 0}
    first = run_method("dense", ds, weighting="halve_weak", **kw)

    def quarter_weak(c, mu, sd):
        return torch.where(c.clamp(-1.0, 1.0) >= mu, 1.0, 0.25).to(c.dtype)

    monkeypatch.setitem(WEIGHTINGS, "halve_weak", Weighting(quarter_weak))
    second = run_method("dense", ds, weighting="halve_weak", **kw)
    assert not np.array_equal(first.similarity, second.similarity)


def test_a_whole_matrix_step_has_one_door(rooms):
    """``similarity_matrix`` refuses a normalisation (it is a step on a result's matrix) and
    names the door; an unknown step lists the table's names."""
    rng = np.random.default_rng(0)
    d = [rng.normal(size=(3, 8)).astype(np.float32) for _ in range(2)]
    b = [np.tile([0.0, 0.0, 4.0, 4.0], (3, 1)) for _ in range(2)]
    with pytest.raises(ValueError, match=r"similarity_matrix: normalise='rank_rows' is a step"):
        similarity_matrix(d, b, d, b, matching=Matching(normalise="rank_rows"))
    with pytest.raises(ValueError, match=r"weighting='nope' is not valid.*'halve_weak'"):
        Matching(weighting="nope")
    with pytest.raises(ValueError, match=r"normalise='nope' is not valid.*'rank_rows'"):
        Matching(normalise="nope")
