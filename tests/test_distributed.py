"""The Dask engine (vpr_study.cluster.features) against a LocalCluster on 127.0.0.1.

The cluster has two worker processes with one thread each (Dask's nanny also sets
OMP_NUM_THREADS=1 there), while this process runs torch with its default thread count: the
results must still equal the in-process ones exactly.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch

from vpr_core.features import LandmarkEncoder
from vpr_core.landmarks import dense_sampling
from vpr_core.matching import Compute, Matching, similarity_matrix, similarity_pairs
from vpr_core.matching.shortlist import rerank, shortlist_pairs
from vpr_core.matching.weighting import weighting_sample
from vpr_core.settings import SCHEDULER_ENV
from vpr_study.cluster import (
    extract_features_distributed,
    get_client,
    scheduler_address,
    similarity_blocks_distributed,
    similarity_pairs_distributed,
)

distributed = pytest.importorskip("distributed")

#: Small encoders: 16 landmarks per image fill one crop batch; ``roi`` is one pass per image.
ENCODER = {"backbone": "efficientnet_lite0", "dim": 64, "seed": 0, "batch_size": 16}
ENCODER_ROI = {**ENCODER, "pooling": "roi"}


@pytest.fixture(scope="module")
def client():
    """A Client on a two-process LocalCluster bound to 127.0.0.1 (closed after the module)."""
    cluster = distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None
    )
    with cluster, get_client(cluster.scheduler_address) as c:
        yield c


@pytest.fixture(scope="module")
def small_set():
    from vpr_core.datasets import load_dataset

    return load_dataset("synthetic", n_places=4, image_size=(64, 112))


def _random_sets(rng, n, dim=48, kmin=6, kmax=20):
    desc, boxes = [], []
    for k in rng.integers(kmin, kmax + 1, n):
        desc.append(rng.standard_normal((k, dim)).astype(np.float32))
        boxes.append(np.c_[rng.uniform(0, 60, (k, 2)), rng.uniform(5, 60, (k, 2))])
    return desc, boxes


def test_cluster_is_local_and_workers_single_threaded(client):
    workers = client.scheduler_info()["workers"]
    assert len(workers) == 2
    assert all(addr.startswith("tcp://127.0.0.1:") for addr in workers)
    threads = client.run(torch.get_num_threads)
    assert set(threads.values()) == {1}


@pytest.mark.parametrize("conf", [ENCODER, ENCODER_ROI], ids=["crop", "roi"])
def test_features_on_cluster_equal_in_process(client, small_set, conf):
    enc = LandmarkEncoder(**conf)
    for side in ("query", "reference"):
        n = len(small_set.paths(side))
        boxes = [dense_sampling(small_set.image_size(side, i), per_scale=4) for i in range(n)]
        got, secs = extract_features_distributed(
            client, small_set, side, conf, boxes=boxes, shard_size=3
        )
        assert len(got) == n and len(secs) == n and all(s > 0 for s in secs)
        for i in range(n):
            want = enc.encode(small_set.load_image(side, i), boxes[i])
            assert got[i].dtype == np.float32
            assert np.array_equal(got[i], want), f"{side} image {i} differs"
    # a subset in any order comes back in that order
    idx = [3, 0]
    boxes = [dense_sampling(small_set.image_size("query", i), per_scale=1) for i in idx]
    got, _ = extract_features_distributed(
        client, small_set, "query", conf, indices=idx, boxes=boxes, shard_size=1
    )
    for g, i, b in zip(got, idx, boxes, strict=False):
        assert np.array_equal(g, enc.encode(small_set.load_image("query", i), b))


def test_global_features_on_cluster_equal_in_process(client, small_set):
    enc = LandmarkEncoder(**ENCODER_ROI)
    got, _ = extract_features_distributed(
        client, small_set, "reference", ENCODER_ROI, kind="global"
    )
    want = [enc.encode_global(small_set.load_image("reference", i)) for i in range(4)]
    assert np.array_equal(np.stack(got), np.stack(want))


def test_similarity_and_shortlist_of_real_features_equal_in_process(client, small_set):
    n = 4
    feats, boxes = {}, {}
    for side in ("query", "reference"):
        boxes[side] = [dense_sampling(small_set.image_size(side, i)) for i in range(n)]
        feats[side], _ = extract_features_distributed(
            client, small_set, side, ENCODER_ROI, boxes=boxes[side]
        )
    args = (feats["query"], boxes["query"], feats["reference"], boxes["reference"])
    want = similarity_matrix(*args, compute=Compute(show_progress=False))
    got = similarity_blocks_distributed(client, *args, block_queries=3)
    assert np.array_equal(got, want)
    gq = np.stack([d.mean(0) for d in feats["query"]])
    gr = np.stack([d.mean(0) for d in feats["reference"]])
    pairs, _ = shortlist_pairs(gq, gr, 2)
    vals = similarity_pairs_distributed(client, *args, pairs, blocks=(3, 2))
    assert np.array_equal(
        vals, similarity_pairs(*args, pairs, compute=Compute(show_progress=False))
    )
    sim = rerank(vals, pairs, n, n)
    assert np.isnan(sim).sum() == n * (n - 2)


@pytest.mark.parametrize(
    ("soft_nms_iou", "spatial"), [(None, None), (0.4, None), (None, "consistency")]
)
def test_similarity_blocks_unequal_landmark_counts_equal_in_process(client, soft_nms_iou, spatial):
    rng = np.random.default_rng(7)
    qd, qb = _random_sets(rng, 11)
    rd, rb = _random_sets(rng, 13)
    m, quiet = Matching(soft_nms_iou=soft_nms_iou, spatial=spatial), Compute(show_progress=False)
    want = similarity_matrix(qd, qb, rd, rb, matching=m, compute=quiet)
    got = similarity_blocks_distributed(client, qd, qb, rd, rb, m, block_queries=4)
    assert np.array_equal(got, want)
    # a shuffled shortlist with repeats, spread over several query and reference blocks
    pairs = np.stack([rng.integers(0, 11, 60), rng.integers(0, 13, 60)], axis=1)
    want_p = similarity_pairs(qd, qb, rd, rb, pairs, m, quiet)
    got_p = similarity_pairs_distributed(client, qd, qb, rd, rb, pairs, m, blocks=(3, 4))
    assert np.array_equal(got_p, want_p)
    # the pairs path agrees with the matrix path (bit for bit without soft-NMS; with it the
    # matcher's float64 soft-NMS scores can differ in the last bit between the two paths)
    np.testing.assert_allclose(
        got_p,
        want[pairs[:, 0], pairs[:, 1]],
        rtol=0,
        atol=0 if soft_nms_iou is None and spatial is None else 1e-15,
    )
    if spatial is not None:  # the option reaches the workers: the scores differ from Eq. (1)
        plain = similarity_blocks_distributed(client, qd, qb, rd, rb, block_queries=4)
        assert not np.array_equal(got, plain)


def test_in_process_fallback_equals_direct_call():
    rng = np.random.default_rng(8)
    qd, qb = _random_sets(rng, 3)
    rd, rb = _random_sets(rng, 4)
    want = similarity_matrix(qd, qb, rd, rb, compute=Compute(show_progress=False))
    assert np.array_equal(similarity_blocks_distributed(None, qd, qb, rd, rb), want)


def test_scheduler_address_resolution(monkeypatch):
    # None is in-process, always: the library never reads $VPR_DASK_SCHEDULER (the CLI does)
    monkeypatch.setenv(SCHEDULER_ENV, "tcp://127.0.0.1:8786")
    assert scheduler_address(None) is None
    assert get_client(None) is None
    assert scheduler_address(" tcp://127.0.0.1:9000 ") == "tcp://127.0.0.1:9000"
    with pytest.raises(ValueError, match="non-empty string"):
        scheduler_address("  ")


def test_unreachable_scheduler_names_address_and_fix():
    with pytest.raises(ConnectionError, match=r"127\.0\.0\.1:1.*dask scheduler"):
        get_client("tcp://127.0.0.1:1", timeout=2)


_D2, _B4 = [np.ones((1, 2))], [np.ones((1, 4))]


def test_feature_arguments_validated(small_set):
    with pytest.raises(ValueError, match="one boxes array per image"):
        extract_features_distributed(None, small_set, "query", ENCODER, boxes=[np.zeros((0, 4))])
    with pytest.raises(ValueError, match="unknown side 'left'"):
        extract_features_distributed(None, small_set, "left", ENCODER)
    with pytest.raises(ValueError, match="block_queries must be"):
        similarity_blocks_distributed(
            object(),
            [np.ones((1, 2))],
            [np.ones((1, 4))],
            [np.ones((1, 2))],
            [np.ones((1, 4))],
            block_queries=0,
        )


@pytest.mark.parametrize(
    ("sides", "message"),
    [
        ((_D2 + _D2, _B4, _D2, _B4), "query_desc has 2 images but query_boxes has 1"),
        ((_D2, _B4, [], []), "reference_desc is empty"),
    ],
)
def test_block_lists_refused_as_in_process(sides, message):
    """The Dask engine checks the lists by the in-process rule (one site, one wording) before a
    task is sent: the client is never touched."""
    for call in (
        lambda: similarity_blocks_distributed(object(), *sides),
        lambda: similarity_pairs_distributed(object(), *sides, np.zeros((0, 2), np.int64)),
        lambda: similarity_matrix(*sides),
    ):
        with pytest.raises(ValueError, match=message):
            call()


def _serve(handler, seconds: float = 30.0):
    """A one-shot TCP server on 127.0.0.1 (a free port) whose connections ``handler(conn)``
    answers; returns its address."""
    import socket
    import threading

    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(4)
    srv.settimeout(seconds)

    def loop():
        try:
            while True:
                conn, _ = srv.accept()
                with conn:
                    handler(conn)
        except OSError:
            pass
        finally:
            srv.close()

    threading.Thread(target=loop, daemon=True).start()
    return f"tcp://127.0.0.1:{srv.getsockname()[1]}"


def test_a_silent_server_is_not_a_scheduler_and_fails_within_the_timeout():
    import time

    # like `python -m http.server`: accepts, then waits for a request that never comes
    addr = _serve(lambda conn: conn.recv(1) and time.sleep(5))
    t0 = time.perf_counter()
    with pytest.raises(ConnectionError, match=r"sent no Dask handshake within 1 s.*not a Dask"):
        get_client(addr, timeout=1)
    assert time.perf_counter() - t0 < 10


def test_a_server_speaking_another_protocol_is_refused_before_dask_reads_it():
    addr = _serve(lambda conn: conn.sendall(b"HTTP/1.0 400 Bad request\r\n\r\n"))
    with pytest.raises(ConnectionError, match=r"not Dask's protocol .*b'HTTP/1.0'"):
        get_client(addr, timeout=2)
    closed = _serve(lambda conn: None)  # accepts and closes at once
    with pytest.raises(ConnectionError, match="closed the connection"):
        get_client(closed, timeout=2)


def test_a_malformed_address_is_refused_at_once(capsys):
    import time

    from vpr_study import cli

    t0 = time.perf_counter()
    with pytest.raises(ValueError, match=r"'notanaddress' is not a Dask scheduler address"):
        get_client("notanaddress", timeout=5)
    assert scheduler_address("127.0.0.1:8786") == "tcp://127.0.0.1:8786"
    rc = cli.main(
        [
            "eval",
            "--dataset",
            "synthetic",
            "--n-places",
            "3",
            "--method",
            "global",
            "--backbone",
            "hog",
            "--scheduler",
            "notanaddress",
        ]
    )
    err = capsys.readouterr().err
    assert rc == 2 and "tcp://HOST:PORT" in err and "Traceback" not in err
    assert time.perf_counter() - t0 < 30  # no stall in a client's __del__


@pytest.mark.parametrize(
    ("weighting", "nr"), [("contrast", 12), ("contrast", 13), ("idf", 13), ("contrast", 300)]
)
def test_weighting_on_cluster_equals_in_process(client, weighting, nr):
    """(Not in the paper) database weighting: a task's statistics are the in-process ones (all
    references, or with more than the weighting's sample the seeded sample, scattered to every
    worker)."""
    rng = np.random.default_rng(9)
    qd, qb = _random_sets(rng, 11, dim=16, kmin=1, kmax=6)
    rd, rb = _random_sets(rng, nr, dim=16, kmin=1, kmax=6)
    kw = {"matching": Matching(weighting=weighting)}
    want = similarity_matrix(qd, qb, rd, rb, **kw, compute=Compute(show_progress=False))
    got = similarity_blocks_distributed(client, qd, qb, rd, rb, block_queries=4, **kw)
    assert np.array_equal(got, want)
    assert not np.array_equal(
        got, similarity_matrix(qd, qb, rd, rb, compute=Compute(show_progress=False))
    )
    pairs = np.stack([rng.integers(0, 11, 60), rng.integers(0, nr, 60)], axis=1)
    want_p = similarity_pairs(qd, qb, rd, rb, pairs, **kw, compute=Compute(show_progress=False))
    got_p = similarity_pairs_distributed(client, qd, qb, rd, rb, pairs, blocks=(3, 4), **kw)
    assert np.array_equal(got_p, want_p)
    every = len(weighting_sample(nr, weighting)) == nr  # contrast: 12 references, idf: 256
    assert every == (nr <= (12 if weighting == "contrast" else 256))
    if every:  # statistics over every reference: the matrix path's values
        np.testing.assert_allclose(got_p, want[pairs[:, 0], pairs[:, 1]], atol=1e-7, rtol=0)
    else:
        assert not np.allclose(got_p, want[pairs[:, 0], pairs[:, 1]], atol=1e-7, rtol=0)
