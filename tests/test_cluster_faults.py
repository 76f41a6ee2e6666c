"""Cluster faults while gathering Dask results: one line naming the address, cached work kept."""

from __future__ import annotations

import time

import pytest

distributed = pytest.importorskip("distributed")

from vpr_study.cluster import client as engine_client  # noqa: E402


@pytest.fixture
def cluster_without_workers():
    cluster = distributed.LocalCluster(
        n_workers=0, processes=True, host="127.0.0.1", dashboard_address=None
    )
    client = distributed.Client(cluster, set_as_default=False)
    yield client
    client.close()
    cluster.close()


def test_cancelled_tasks_are_one_line_naming_the_address(cluster_without_workers):
    client = cluster_without_workers
    future = client.submit(time.sleep, 30)
    future.cancel()
    with pytest.raises(ConnectionError) as info:
        engine_client.gather_in_order(client, [future], "similarity (dask)")
    text = str(info.value)
    assert client.scheduler.address in text and "cached work is kept" in text
    assert "similarity (dask)" in text and "\n" not in text


def test_no_worker_left_ends_the_wait(cluster_without_workers, monkeypatch):
    monkeypatch.setattr(engine_client, "POLL_S", 0.2)
    monkeypatch.setenv("VPR_SCHEDULER_TIMEOUT", "0.5")
    future = cluster_without_workers.submit(sum, [1, 2])
    t0 = time.perf_counter()
    with pytest.raises(ConnectionError, match="no worker left.*cached work is kept"):
        engine_client.gather_in_order(cluster_without_workers, [future], "features (dask)")
    assert time.perf_counter() - t0 < 10


@pytest.mark.parametrize("value", ["inf", "nan", "-1", "soon"])
def test_scheduler_timeout_must_be_finite(monkeypatch, value):
    from vpr_core import settings

    monkeypatch.setenv("VPR_SCHEDULER_TIMEOUT", value)
    with pytest.raises(ValueError, match="VPR_SCHEDULER_TIMEOUT"):
        settings.scheduler_timeout()
