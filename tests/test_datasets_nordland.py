"""Tests for vpr_core.datasets.nordland (season folders matched by file name)."""

from __future__ import annotations

import logging
from pathlib import Path

import cv2
import numpy as np
import pytest

from vpr_core.datasets import load_dataset

NORDLAND = Path(__file__).resolve().parents[2] / "shared" / "data" / "nordland_64x32"


def _tree(root: Path, seasons: dict[str, list[str]]) -> None:
    for k, (season, names) in enumerate(seasons.items()):
        (root / season).mkdir(parents=True)
        for i, n in enumerate(names):
            img = np.full((32, 64, 3), (10 * i + 50 * k) % 256, np.uint8)
            assert cv2.imwrite(str(root / season / n), img)


NAMES = [f"images-{10 * i:05d}.png" for i in range(1, 13)]  # 12 places


def test_nordland_tree_step_tolerance_and_names(tmp_path):
    _tree(tmp_path, {"summer": NAMES, "winter": NAMES, "spring": NAMES[:2]})
    ds = load_dataset("nordland", tmp_path)
    assert ds.name == tmp_path.name and ds.meta["loader"] == "nordland"
    assert ds.tolerance == 1 and len(ds) == 12
    assert (
        ds.query_paths[0].parent.name == "winter" and ds.reference_paths[0].parent.name == "summer"
    )
    assert [p.name for p in ds.query_paths] == [p.name for p in ds.reference_paths] == NAMES
    q, r = np.indices((12, 12))
    assert np.array_equal(ds.ground_truth, np.abs(q - r) <= 1)
    sub = load_dataset(
        "nordland", tmp_path, query="summer", reference="winter", step=5, tolerance=0
    )
    assert [p.name for p in sub.query_paths] == [NAMES[0], NAMES[5], NAMES[10]]
    assert sub.query_paths[0].parent.name == "summer"
    assert np.array_equal(sub.ground_truth, np.eye(3, dtype=bool))
    assert sub.meta["step"] == 5 and sub.meta["seasons_found"] == ["spring", "summer", "winter"]
    assert sub.load_image("query", 2).shape == (32, 64, 3)
    # titles name the subset (the name stays the data folder's)
    assert ds.title == ds.name and sub.title == f"{tmp_path.name}, every 5th place"
    for step, text in [(2, "2nd"), (11, "11th"), (12, "12th"), (21, "21st"), (50, "50th")]:
        titled = load_dataset("nordland", tmp_path, step=step, tolerance=0)
        assert titled.title.endswith(f"every {text} place")


@pytest.mark.parametrize("step", [0, -1, 1.5, "2", True])
def test_nordland_bad_step(tmp_path, step):
    _tree(tmp_path, {"summer": NAMES[:2], "winter": NAMES[:2]})
    with pytest.raises(ValueError, match="step must be a positive int"):
        load_dataset("nordland", tmp_path, step=step)


def test_nordland_unknown_season_lists_found(tmp_path):
    _tree(tmp_path, {"summer": NAMES[:2], "fall": NAMES[:2]})
    with pytest.raises(FileNotFoundError, match=r"'winter' not found.*seasons found: fall, summer"):
        load_dataset("nordland", tmp_path)


def test_nordland_mismatched_names(tmp_path, caplog):
    _tree(tmp_path, {"summer": NAMES[:5], "winter": NAMES[1:6]})
    with pytest.raises(
        ValueError,
        match=r"1 file\(s\) only in winter.*images-00060.png.*"
        r"1 only in summer.*images-00010.png",
    ):
        load_dataset("nordland", tmp_path)
    with caplog.at_level(logging.WARNING, logger="vpr_core"):
        ds = load_dataset("nordland", tmp_path, missing="intersect")
    assert [p.name for p in ds.query_paths] == NAMES[1:5]
    assert [p.name for p in ds.reference_paths] == NAMES[1:5]
    assert "keeping the 4 file names present in both" in caplog.text
    with pytest.raises(
        ValueError, match="unknown nordland missing 'drop'; valid: error, intersect"
    ):
        load_dataset("nordland", tmp_path, missing="drop")


@pytest.mark.skipif(not (NORDLAND / "summer").is_dir(), reason=f"{NORDLAND} not present")
def test_nordland_real_folder():
    full = load_dataset("nordland", NORDLAND, tolerance=0)
    assert full.n_query == full.n_reference == 3576
    ds = load_dataset("nordland", NORDLAND, step=10, tolerance=1)
    assert ds.n_query == ds.n_reference == 358  # ceil(3576 / 10)
    assert all(q.name == r.name for q, r in zip(ds.query_paths, ds.reference_paths, strict=True))
    assert (
        ds.query_paths[0].name == "images-00010.png"
        and ds.query_paths[1].name == "images-00110.png"
    )
    assert (
        ds.query_paths[5].parent.name == "winter" and ds.reference_paths[5].parent.name == "summer"
    )
    assert ds.ground_truth.sum() == 358 + 2 * 357  # |i-j| <= 1 over the kept places
    assert ds.ground_truth[10, 11] and not ds.ground_truth[10, 12]
    assert ds.queries_with_ground_truth == 358
    img = ds.load_image("query", 100)
    assert img.shape == (32, 64, 3) and img.dtype == np.uint8
