"""vpr_core.methods.step_between: a step (a weighting, a normalisation) is credited only when the
runs differ by that step alone, one check for every function that credits one (step_changes, and
through it plot_step_changes; plot_carried_landmarks; findings' steps table): dataset, method,
landmarks, encoder, shortlist, protocol and every other matching field (issue 60 item 7)."""

from __future__ import annotations

import pandas as pd
import pytest

from vpr_core import run_method, step_between, step_changes
from vpr_core.datasets import load_dataset
from vpr_study import findings

KW = {"backbone": "hog", "dim": 32, "n_bootstrap": 0, "per_scale": 4, "keep_descriptors": True}


@pytest.fixture(scope="module")
def six():
    return load_dataset("synthetic", n_places=6, image_size=(64, 112))


@pytest.fixture(scope="module")
def plain(six):
    return run_method("dense", six, **KW)


@pytest.mark.parametrize(
    ("other", "named"),
    [
        ({"dataset": "repetition"}, r"\(dataset\): dataset '[0-9a-f]+' vs '[0-9a-f]+'"),
        ({"dataset": "tolerance"}, r"\(dataset\)"),
        ({"dim": 16}, r"\(dim\): dim 32 vs 16"),
        ({"backbone": "efficientnet_lite0"}, r"\(backbone, .*\): backbone 'hog' vs 'efficientnet"),
        ({"shortlist": 3}, r"\(shortlist\): shortlist None vs 3"),
        ({"per_scale": 9}, r"\(landmarks\): landmarks Dense"),
        ({"spatial": "consistency"}, r"\(spatial\): spatial None vs 'consistency'"),
        ({"protocol": "best_match"}, r"\(protocol\): protocol 'ratio' vs 'best_match'"),
    ],
    ids=[
        "dataset",
        "tolerance",
        "dim",
        "backbone",
        "shortlist",
        "landmarks",
        "spatial",
        "protocol",
    ],
)
def test_step_changes_refuses_runs_that_differ_beside_the_step(six, plain, other, named):
    ds = six
    if other.get("dataset") == "repetition":
        ds = load_dataset("synthetic", n_places=6, image_size=(64, 112), repetition=0.9)
    elif other.get("dataset") == "tolerance":
        ds = six.with_tolerance(1)
    opts = {**KW, **{k: v for k, v in other.items() if k != "dataset"}}
    stepped = run_method("dense", ds, weighting="contrast", **opts)
    with pytest.raises(
        ValueError, match=rf"^step_changes: .* differ in more than the step {named}"
    ):
        step_changes(plain, stepped)


def test_step_changes_credits_a_step_alone(six, plain):
    stepped = run_method("dense", six, normalise="query_batch", **KW)
    assert step_between(plain, stepped, "t") == {"normalise": "query_batch"}
    assert len(step_changes(plain, stepped, top=2))
    with pytest.raises(ValueError, match=r"must be .* with one more step .* it adds none"):
        step_changes(plain, run_method("dense", six, **KW))
    with pytest.raises(ValueError, match=r"with one more step .* it removes one"):
        step_between(stepped, plain, "t")


def test_plot_carried_landmarks_uses_the_same_check(six, plain):
    from vpr_study.viz import plot_carried_landmarks

    weighted = run_method("dense", six, weighting="contrast", **KW)
    short = run_method("dense", six, shortlist=3, **KW)
    with pytest.raises(ValueError, match=r"differ in more than the weighting \(shortlist\)"):
        plot_carried_landmarks(six, short, weighted)
    both = run_method("dense", six, weighting="contrast", normalise="query_batch", **KW)
    with pytest.raises(ValueError, match=r"differ in more than the weighting \(normalise\)"):
        plot_carried_landmarks(six, plain, both)


def test_a_peer_is_not_a_run_a_step_is_credited_between(six, plain):
    from vpr_study.peers import peer_from_matrix, peer_result

    peer = peer_result(peer_from_matrix(plain.similarity, "P"), six, n_bootstrap=0)
    with pytest.raises(ValueError, match=r"is not a run_method result .* one method"):
        step_changes(peer, plain)


def test_findings_steps_table_refuses_rows_that_differ_beside_the_step(tmp_path):
    def row(method, run, baseline, backbone):
        r = {"method": method, "run": run, "baseline": baseline, "queries": 60}
        r |= {"dataset": "synthetic", "root": "synthetic-1", "tolerance": 0, "backbone": backbone}
        return r | {"pooling": "crop", "protocol": "ratio"}

    base = row("dense", "dense", None, "efficientnet_lite0")
    two = row("dense (weighting: two_sided)", "dense(weighting=two_sided)", "dense", "hog")
    for m in ("dAUC", "dR@1"):
        two |= {m: 0.1, f"{m} lo": 0.05, f"{m} hi": 0.15, f"{m} p": 0.01, f"{m} needs": 10.0}
    folder = tmp_path / "results" / "d"
    folder.mkdir(parents=True)
    csv = folder / f"{findings.STEPS_TABLE}.csv"
    pd.DataFrame([base, two]).to_csv(csv, index=False)
    with pytest.raises(ValueError, match=rf"^{csv}: .* differ in more than the step \(backbone\)"):
        findings.findings_table(["d"], out=tmp_path, claims=findings.STEP_CLAIMS)
    two["backbone"] = "efficientnet_lite0"
    pd.DataFrame([base, two]).to_csv(csv, index=False)
    table = findings.findings_table(["d"], out=tmp_path, claims=findings.STEP_CLAIMS)
    assert table["d verdict"].iloc[0] == "higher"
