"""Shared pytest fixtures: a tiny synthetic dataset and the real Gardens Point mini subset.

The tests run on a cache of their own: a new temporary folder per session (never the
repository's ``.cache``, which a user's runs fill), unless ``VPR_CACHE_DIR`` is set by whoever
runs the tests (e.g. to reuse one between local runs). Tests that check caching use their own
tmp dirs (monkeypatch).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import pytest

os.environ.setdefault("TQDM_DISABLE", "1")
if not os.environ.get("VPR_CACHE_DIR"):
    os.environ["VPR_CACHE_DIR"] = tempfile.mkdtemp(prefix="vpr-test-cache-")
os.environ.setdefault("MPLBACKEND", "Agg")

REPO_DIR = Path(__file__).resolve().parents[1]
GARDENS_POINT_MINI = REPO_DIR.parent / "shared" / "data" / "gardens_point_mini"


@pytest.fixture(scope="session")
def tiny_synthetic():
    """The ``synthetic`` dataset with 8 places (default seed and image size), cached on disk."""
    from vpr_core.datasets import load_dataset

    return load_dataset("synthetic", n_places=8)


@pytest.fixture(scope="session")
def gardens_point_mini_root() -> Path:
    """``../shared/data/gardens_point_mini`` (10 real day/night pairs); skips when absent."""
    if (
        not (GARDENS_POINT_MINI / "query").is_dir()
        or not (GARDENS_POINT_MINI / "reference").is_dir()
    ):
        pytest.skip(f"real-data subset not found at {GARDENS_POINT_MINI}")
    return GARDENS_POINT_MINI
