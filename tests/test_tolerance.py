"""Tolerance has one home, the dataset (issue 47 item 4): a run is scored against its dataset's
ground truth as loaded, the Eq. (1) matrix cache does not depend on it (a sweep reuses every
matrix), ``Evaluation`` holds no tolerance, a ``tolerance=`` override is refused naming the
fix, ``compare`` names both tolerances of runs scored at two, and ``with_tolerance`` rebuilds
frame-aligned ground truth only."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from vpr_core import run as run_module
from vpr_core import run_method
from vpr_core.datasets import PlaceDataset, load_dataset
from vpr_core.datasets._layout import widen
from vpr_core.datasets.ground_truth import frame_aligned
from vpr_core.evaluation import Evaluation, compare, evaluate
from vpr_study.peers import peer_result

#: A wide tolerance on 4 places saturates the ground truth: expected here, not checked.
pytestmark = pytest.mark.filterwarnings("ignore:saturated ground truth")

NORDLAND = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "nordland_64x32"
#: A cheap run: a HOG backbone on a 4-box dense grid, no intervals.
CHEAP = {"backbone": "hog", "dim": 32, "scales": (0.25,), "per_scale": 4, "n_bootstrap": 0}


@pytest.fixture()
def isolated_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("VPR_CACHE_DIR", str(tmp_path / "cache"))
    return tmp_path / "cache"


@pytest.fixture()
def matrices(monkeypatch):
    """The Eq. (1) matrices run_method computes (not read from the cache), counted."""
    computed: list[int] = []
    real = run_module._match

    def counting(*args, **kwargs):
        computed.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(run_module, "_match", counting)
    return computed


@pytest.fixture(scope="module")
def four():
    return load_dataset("synthetic", n_places=4, image_size=(64, 112))


def _sweep(load, matrices, isolated_cache, **options):
    """Runs at tolerance 0..3, each on the dataset ``load(t)`` gives; the matrices computed
    before each run."""
    runs, before = [], []
    for t in range(4):
        before.append(len(matrices))
        runs.append(run_method("dense", load(t), **options))
    assert len(list((isolated_cache / "results").rglob("*.npz"))) == 1  # one matrix for all
    return runs, before


@pytest.mark.skipif(not NORDLAND.is_dir(), reason=f"no Nordland subset at {NORDLAND}")
def test_a_tolerance_sweep_on_nordland_computes_one_matrix(matrices, isolated_cache):
    """Nordland every 50th place loaded at tolerance 0..3 (the study's roi pooling): the first
    run computes the Eq. (1) matrix, the second to fourth compute none, and their metrics are
    the same matrix scored against each tolerance's ground truth."""

    def load(t):
        return load_dataset("nordland", NORDLAND, step=50, tolerance=t)

    roi = {**CHEAP, "backbone": "efficientnet_lite0", "pooling": "roi"}  # the study's encoder
    runs, before = _sweep(load, matrices, isolated_cache, **roi)
    assert before == [0, 1, 1, 1] and len(matrices) == 1
    n = runs[0].similarity.shape[0]
    for t, r in enumerate(runs):
        np.testing.assert_array_equal(r.similarity, runs[0].similarity)
        np.testing.assert_array_equal(r.ground_truth, frame_aligned(n, n, t))
        assert r.tolerance == t
        assert r.metrics == evaluate(r.similarity, frame_aligned(n, n, t), Evaluation())
    r1 = [r.metrics["r@1"] for r in runs]
    assert r1 == sorted(r1) and r1[3] > r1[0]  # a wider truth counts more top-1 as correct


def test_with_tolerance_equals_loading_at_it_and_reuses_the_matrix(four, matrices, isolated_cache):
    """``four.with_tolerance(t)`` is what loading with ``tolerance=t`` gives; a sweep over it
    computes one matrix."""
    for t in (1, 3):
        loaded = load_dataset("synthetic", n_places=4, image_size=(64, 112), tolerance=t)
        again = four.with_tolerance(t)
        np.testing.assert_array_equal(again.ground_truth, loaded.ground_truth)
        assert again.tolerance == t and again.meta == loaded.meta
        assert again.query_paths == four.query_paths and four.tolerance == 0  # four unchanged
    runs, before = _sweep(four.with_tolerance, matrices, isolated_cache, **CHEAP)
    assert before == [0, 1, 1, 1]
    assert runs[1].metrics != runs[0].metrics  # 4 places, +-1: the truth changed the numbers
    # a subset of a frame-aligned dataset stays frame-aligned
    np.testing.assert_array_equal(
        four.subset(3).with_tolerance(1).ground_truth, frame_aligned(3, 3, 1)
    )
    with pytest.raises(ValueError, match=r"tolerance \(frames\) must be a non-negative int"):
        four.with_tolerance(-1)


def test_with_tolerance_refuses_a_files_a_distance_rule_and_soft_truth(tmp_path):
    paths = [tmp_path / f"{i}.png" for i in range(6)]
    file_gt = np.zeros((6, 6), dtype=bool)
    file_gt[[0, 1, 2, 3, 4, 5], [0, 0, 2, 5, 4, 4]] = True  # many-to-one, not the diagonal
    meta = {"ground_truth_file": "gt.csv", "ground_truth_rule": "file"}
    cases = {
        "file": PlaceDataset("f", paths, paths, widen(file_gt, 1), 1, meta=meta),
        "25 m": PlaceDataset("u", paths, paths, np.eye(6, dtype=bool), "25 m"),
        "soft": PlaceDataset(
            "s",
            paths,
            paths,
            np.eye(6, dtype=bool),
            0,
            meta={"frame_aligned": True},
            ground_truth_soft=np.ones((6, 6), bool),
        ),
    }
    for ds in cases.values():
        with pytest.raises(ValueError, match=r"not frame-aligned.*load the dataset again with "):
            ds.with_tolerance(2)


def test_evaluation_holds_no_tolerance():
    assert [f.name for f in dataclasses.fields(Evaluation)] == ["protocol", "n_bootstrap"]
    ev = Evaluation("best_match", 0)
    assert (ev.protocol, ev.n_bootstrap) == ("best_match", 0)
    with pytest.raises(TypeError, match="tolerance"):
        Evaluation(tolerance=1)


def test_a_tolerance_override_is_refused_naming_the_fix(four, isolated_cache, monkeypatch):
    """``run_method(..., tolerance=N)`` and ``peer_result(..., tolerance=N)`` are refused before
    any work, naming both ways to load the truth at N."""
    from vpr_study.peers import peer_from_matrix

    def no_work(*args, **kwargs):
        raise AssertionError("work started before the tolerance was refused")

    monkeypatch.setattr(run_module, "extract_landmarks", no_work)
    fix = r"load the dataset with tolerance=2 .*or ds\.with_tolerance\(2\)"
    with pytest.raises(TypeError, match=r"run_method\(tolerance=2\).*" + fix):
        run_method("dense", four, tolerance=2, **CHEAP)
    peer = peer_from_matrix(np.random.default_rng(0).random((4, 4)), "mine")
    with pytest.raises(TypeError, match=r"peer_result\(tolerance=2\).*" + fix):
        peer_result(peer, four, tolerance=2, n_bootstrap=0)
    wide = four.with_tolerance(2)
    at_2 = peer_result(peer, wide, n_bootstrap=0)
    assert at_2.tolerance == 2 and np.array_equal(at_2.ground_truth, wide.ground_truth)


def test_compare_names_both_tolerances(four, isolated_cache):
    """Runs of one dataset loaded at two tolerances (their fingerprints differ too) are refused
    naming both tolerances and the fix."""
    at_0 = run_method("dense", four, **CHEAP)
    at_1 = run_method("dense", four.with_tolerance(1), label="at 1", **CHEAP)
    assert at_0.dataset_fingerprint != at_1.dataset_fingerprint
    with pytest.raises(ValueError, match=r"'at 1' was scored at tolerance 1 and .* tolerance 0"):
        compare([at_0, at_1], n_bootstrap=0)
    unset = dataclasses.replace(at_1, dataset_fingerprint="")  # the ground truth decides
    with pytest.raises(ValueError, match=r"tolerance 1 and .* tolerance 0.*load the dataset at"):
        compare([at_0, unset], n_bootstrap=0)
    assert len(compare([at_0, dataclasses.replace(at_0, label="again")], n_bootstrap=0)) == 2
