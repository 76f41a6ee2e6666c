"""Tests for vpr_study.peers (VPR-Bench precomputed peer results)."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pytest

from vpr_core.datasets import PlaceDataset
from vpr_core.evaluation import auc_pr, pr_curve, recall_at_100_precision
from vpr_study.peers import (
    PRECOMPUTED_FILE,
    find_vprbench_peers,
    load_vprbench_precomputed,
    peer_from_descriptors,
    peer_from_matrix,
    peer_similarity_for,
)


def _write(path: Path, sim: np.ndarray, queries=None, encode=0.0123, match=0.0045, as_list=False):
    """Write a file as VPR-Bench does: an object array of 6 items saved with pickling."""
    nq = sim.shape[0]
    queries = np.arange(nq) if queries is None else np.asarray(queries)
    top = np.argmax(sim, axis=-1) * np.ones(nq, int)
    items = [queries, top, np.max(sim, axis=-1) * np.ones(nq), sim, encode, match]
    path.parent.mkdir(parents=True, exist_ok=True)
    if as_list:
        arr = np.empty((), dtype=object)
        arr[()] = items
    else:
        arr = np.empty(len(items), dtype=object)
        for k, item in enumerate(items):
            arr[k] = item
    np.save(path, arr, allow_pickle=True)
    return path


def _sim(nq=4, nr=5, seed=0):
    return np.random.default_rng(seed).random((nq, nr))


def _dataset(nq, nr):
    return PlaceDataset(
        "t",
        [f"q{i}.png" for i in range(nq)],
        [f"r{i}.png" for i in range(nr)],
        np.eye(nq, nr, dtype=bool),
        0,
    )


@pytest.mark.parametrize("as_list", [False, True])
def test_load_precomputed_roundtrip(tmp_path, as_list):
    sim = _sim()
    path = _write(
        tmp_path / "precomputed_matches" / "GardensPointWalking" / "NetVLAD" / PRECOMPUTED_FILE,
        sim,
        as_list=as_list,
    )
    peer = load_vprbench_precomputed(path)
    assert peer.name == "NetVLAD" and peer.dataset == "GardensPointWalking"
    assert peer.source == path and peer.similarity.shape == (4, 5)
    np.testing.assert_array_equal(peer.similarity, sim)
    assert peer.similarity.dtype == np.float64
    assert peer.encode_seconds == pytest.approx(0.0123) and peer.match_seconds == pytest.approx(
        0.0045
    )
    np.testing.assert_array_equal(peer.top1_reference, np.argmax(sim, axis=1))
    np.testing.assert_array_equal(peer_similarity_for(_dataset(4, 5), peer), sim)


def test_peer_rows_follow_query_indices(tmp_path):
    sim = _sim()
    perm = np.array([2, 0, 3, 1])
    peer = load_vprbench_precomputed(_write(tmp_path / "d" / "HOG" / PRECOMPUTED_FILE, sim, perm))
    out = peer_similarity_for(_dataset(4, 5), peer)
    for k, q in enumerate(perm):
        np.testing.assert_array_equal(out[q], sim[k])


def test_peer_shape_and_query_mismatch(tmp_path):
    peer = load_vprbench_precomputed(_write(tmp_path / "d" / "CoHOG" / PRECOMPUTED_FILE, _sim()))
    with pytest.raises(
        ValueError, match=r"the peer has 4 x 5 .*the dataset .t. has 3 x 5: compute the peer"
    ):
        peer_similarity_for(_dataset(3, 5), peer)
    dup = load_vprbench_precomputed(
        _write(tmp_path / "d" / "CALC" / PRECOMPUTED_FILE, _sim(), [0, 0, 1, 2])
    )
    with pytest.raises(ValueError, match="query indices are not 0..3 each once"):
        peer_similarity_for(_dataset(4, 5), dup)


def test_load_precomputed_bad_files(tmp_path):
    path = tmp_path / "d" / "X" / PRECOMPUTED_FILE
    with pytest.raises(FileNotFoundError, match="not found"):
        load_vprbench_precomputed(path)
    path.parent.mkdir(parents=True)
    arr = np.empty(5, dtype=object)
    for k in range(5):
        arr[k] = np.zeros(3)
    np.save(path, arr, allow_pickle=True)
    with pytest.raises(ValueError, match=rf"{PRECOMPUTED_FILE}.*found 5 items.*Expected 6 items"):
        load_vprbench_precomputed(path)
    np.save(path, np.zeros((4, 5)))
    with pytest.raises(ValueError, match=r"found a float64 array of shape \(4, 5\)"):
        load_vprbench_precomputed(path)
    sim = _sim()
    _write(path, sim, queries=np.arange(3))
    with pytest.raises(ValueError, match=r"item 0 \(query indices\) has 3 values.*4 rows"):
        load_vprbench_precomputed(path)
    _write(path, sim[0])
    with pytest.raises(ValueError, match=r"similarity matrix\) has shape \(5,\)"):
        load_vprbench_precomputed(path)
    _write(path, sim, encode=[0.1, 0.2])
    with pytest.raises(ValueError, match=r"item 4 \(encode seconds\) must be one number"):
        load_vprbench_precomputed(path)
    path.write_bytes(b"garbage")
    with pytest.raises(ValueError, match="not a readable .npy file"):
        load_vprbench_precomputed(path)


def test_distance_matrix_is_flagged(tmp_path, caplog):
    sim = _sim(8, 8)
    path = tmp_path / "d" / "D" / PRECOMPUTED_FILE
    items = np.empty(6, dtype=object)
    for k, it in enumerate([np.arange(8), np.argmin(sim, 1), sim.min(1), sim, 1.0, 2.0]):
        items[k] = it
    path.parent.mkdir(parents=True)
    np.save(path, items, allow_pickle=True)
    with caplog.at_level(logging.WARNING, logger="vpr_core"):
        load_vprbench_precomputed(path)
    assert "not a distance" in caplog.text


def test_find_peers(tmp_path, monkeypatch):
    base = tmp_path / "VPR-Bench" / "precomputed_matches"
    for tech in ("NetVLAD", "AMOSNet", "HOG"):
        _write(base / "SPEDTEST" / tech / PRECOMPUTED_FILE, _sim())
    (base / "SPEDTEST" / "empty").mkdir()
    (base / "Corridor").mkdir()
    peers = find_vprbench_peers(tmp_path / "VPR-Bench", "SPEDTEST")
    assert [p.name for p in peers] == ["AMOSNet", "HOG", "NetVLAD"]
    assert [p.name for p in find_vprbench_peers(base, "spedtest")] == ["AMOSNet", "HOG", "NetVLAD"]
    monkeypatch.setenv("VPR_BENCH_ROOT", str(tmp_path / "VPR-Bench"))
    assert len(find_vprbench_peers(None, "SPEDTEST")) == 3
    with pytest.raises(FileNotFoundError, match="datasets there: Corridor, SPEDTEST"):
        find_vprbench_peers(None, "Nordland")
    with pytest.raises(FileNotFoundError, match="no <technique>/precomputed_data_corrected.npy"):
        find_vprbench_peers(None, "Corridor")
    monkeypatch.delenv("VPR_BENCH_ROOT")
    with pytest.raises(ValueError, match="VPR_BENCH_ROOT"):
        find_vprbench_peers(None, "SPEDTEST")
    with pytest.raises(FileNotFoundError, match="neither a VPR-Bench checkout"):
        find_vprbench_peers(tmp_path, "SPEDTEST")


def test_peer_from_matrix_and_distance(tmp_path):
    sim = np.array([[0.9, 0.1, 0.2], [0.3, 0.8, 0.1]])
    np.save(tmp_path / "sim.npy", sim)
    peer = peer_from_matrix(tmp_path / "sim.npy", "mine")
    assert peer.name == "mine" and peer.source == tmp_path / "sim.npy"
    assert np.isnan(peer.encode_seconds) and np.isnan(peer.match_seconds)
    assert np.array_equal(peer_similarity_for(_dataset(2, 3), peer), sim)
    dist = peer_from_matrix(1 - sim, "mine_d", distance=True)
    assert dist.source is None and np.array_equal(dist.top1_reference, [0, 1])
    assert np.allclose(dist.similarity, 0.9 / (1 - sim))  # 1 / (d / max d)
    with pytest.raises(ValueError, match=r"the peer has 2 x 3 .*has 3 x 3: compute the peer on"):
        peer_similarity_for(_dataset(3, 3), peer)
    bad = sim.copy()
    bad[0, 1] = np.nan
    with pytest.raises(
        ValueError, match=r"peer 'x': the similarity matrix in the array holds 1 NaN"
    ):
        peer_from_matrix(bad, "x")
    with pytest.raises(
        ValueError, match=r"has shape \(3,\); it must be a non-empty 2-d \(Nq, Nr\)"
    ):
        peer_from_matrix(np.ones(3), "x")
    np.save(tmp_path / "obj.npy", np.array([[1, "a"]], dtype=object), allow_pickle=True)
    with pytest.raises(ValueError, match=r"obj.npy is not a readable .npy file .*Python objects"):
        peer_from_matrix(tmp_path / "obj.npy", "x")
    with pytest.raises(FileNotFoundError, match="similarity matrix file not found"):
        peer_from_matrix(tmp_path / "none.npy", "x")


def test_peer_from_descriptors_cosine_and_l2(tmp_path):
    rng = np.random.default_rng(0)
    q, r = rng.normal(size=(3, 8)), rng.normal(size=(5, 8))
    np.save(tmp_path / "queries_descriptors.npy", q.astype(np.float32))
    np.save(tmp_path / "database_descriptors.npy", r.astype(np.float32))
    peer = peer_from_descriptors(
        tmp_path / "queries_descriptors.npy", tmp_path / "database_descriptors.npy", "mine"
    )
    want = np.array([[a @ b / np.linalg.norm(a) / np.linalg.norm(b) for b in r] for a in q])
    assert peer.similarity.shape == (3, 5) and np.allclose(peer.similarity, want, atol=1e-6)
    l2 = peer_from_descriptors(q, r, "mine", metric="L2")
    d = np.array([[np.linalg.norm(a - b) for b in r] for a in q])
    assert np.allclose(l2.similarity, d.max() / d)
    with pytest.raises(ValueError, match="query descriptors are 8-d but database descriptors 4-d"):
        peer_from_descriptors(q, r[:, :4], "x")
    with pytest.raises(ValueError, match="unknown metric 'dot'; valid: cosine, l2"):
        peer_from_descriptors(q, r, "x", metric="dot")
    with pytest.raises(ValueError, match="all zero"):
        peer_from_descriptors(np.zeros((1, 8)), r, "x")
    with pytest.raises(ValueError, match=r"query descriptors in the array has shape \(3, 2, 4\)"):
        peer_from_descriptors(q.reshape(3, 2, 4), r, "x")


# the hand example of issue 25: two queries, both with reference 0 as the place; query 0's best
# match (d = 1) is right with ratio d1/d2 = 1/4, query 1's (d = 2, reference 1) wrong with 2/3.
# Accept query 0 first: (R, P) = (0.5, 1), then both: (1, 0.5) -> AUC 0.5 + 0.375 = 0.875.
HAND_D = np.array([[1.0, 4.0, 5.0], [3.0, 2.0, 6.0]])
HAND_GT = np.array([[True, False, False], [True, False, False]])


def _ratio_metrics(sim: np.ndarray) -> tuple[float, float]:
    curve = pr_curve(sim, HAND_GT, protocol="ratio")
    return auc_pr(curve), recall_at_100_precision(curve)


def test_distance_peer_ratio_is_d1_over_d2():
    peer = peer_from_matrix(HAND_D, "dist", distance=True)
    sim = peer.similarity
    assert (sim > 0).all()
    s_sorted = np.sort(sim, axis=1)[:, ::-1]
    np.testing.assert_allclose(s_sorted[:, 1] / s_sorted[:, 0], [1 / 4, 2 / 3])
    auc, r100 = _ratio_metrics(sim)
    assert auc == pytest.approx(0.875) and r100 == pytest.approx(0.5)
    # the same distances from l2 descriptors (1-d points: q 0, 10; r 1, 14, 5 -> hand D rows
    # [1, 14, 5] and [9, 4, 5]: q0 right with 1/5, q1 wrong (reference 1) with 4/5)
    q, r = np.array([[0.0], [10.0]]), np.array([[1.0], [14.0], [5.0]])
    l2 = peer_from_descriptors(q, r, "l2", metric="l2")
    np.testing.assert_array_equal(l2.top1_reference, [0, 1])
    assert _ratio_metrics(l2.similarity) == pytest.approx((0.875, 0.5))
    # huge magnitudes do not overflow (the ratio is scale-free)
    big = peer_from_descriptors(q * 1e300, r * 1e300, "big", metric="l2")
    np.testing.assert_allclose(big.similarity, l2.similarity)


def test_distance_peer_zero_and_negative():
    d = np.array([[0.0, 2.0, 3.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]])
    sim = peer_from_matrix(d, "z", distance=True).similarity
    assert np.isfinite(sim).all() and (sim > 0).all()
    assert sim[0, 1] / sim[0, 0] < 1e-100  # an exact match: ratio ~ 0
    assert sim[1, 0] == sim[1, 1] and sim[2, 0] == sim[2, 2]  # ties stay ties: ratio 1
    with pytest.raises(ValueError, match=r"1 negative values; distances must be >= 0"):
        peer_from_matrix(np.array([[1.0, -1.0]]), "n", distance=True)


@pytest.mark.parametrize(
    "matrix",
    [
        np.array([[1 + 1j, 0.5], [0.2, 0.9]]),
        np.array([["2020-01-01", "2020-01-02"]], dtype="datetime64[D]"),
        np.array([[np.timedelta64(1, "s"), np.timedelta64(2, "s")]]),
        np.array([["0.1", "0.2"]]),
    ],
)
def test_peer_matrix_refuses_non_real(matrix, tmp_path):
    with pytest.raises(ValueError, match="is not real numbers"):
        peer_from_matrix(matrix, "x")
    np.save(tmp_path / "m.npy", matrix)
    with pytest.raises(ValueError, match=r"m.npy is not real numbers .*save a float array"):
        peer_from_matrix(tmp_path / "m.npy", "x")


def test_cosine_descriptors_of_huge_magnitude():
    q = np.array([[1e300, 1e300], [1e300, -1e300]])
    r = np.array([[1e300, 1e300], [-1e300, 1e300]])
    peer = peer_from_descriptors(q, r, "big")
    np.testing.assert_allclose(peer.similarity, [[1.0, 0.0], [0.0, -1.0]], atol=1e-12)


def test_vprbench_file_with_a_complex_matrix_is_refused(tmp_path):
    path = tmp_path / "precomputed_matches" / "DS" / "T" / PRECOMPUTED_FILE
    _write(path, np.array([[1 + 2j, 0.5], [0.1, 0.9]]))
    with pytest.raises(ValueError, match=r"item 3 \(similarity matrix\) is not a numeric"):
        load_vprbench_precomputed(path)
