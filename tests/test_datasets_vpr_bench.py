"""Tests for vpr_core.datasets.vpr_bench (query/, ref/, ground_truth_new.npy)."""

from __future__ import annotations

import logging
from pathlib import Path

import cv2
import numpy as np
import pytest

from vpr_core.datasets import load_dataset
from vpr_core.datasets.vpr_bench import read_vprbench_ground_truth


def _images(folder: Path, names) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    for i, n in enumerate(names):
        assert cv2.imwrite(str(folder / n), np.full((32, 32, 3), 20 * i, np.uint8))


def _save_gt(path: Path, rows, two_d: bool = True) -> None:
    """Write rows [query index, [reference indices]] as a pickled object array (as VPR-Bench)."""
    if two_d:
        arr = np.empty((len(rows), 2), dtype=object)
        for k, (q, refs) in enumerate(rows):
            arr[k, 0], arr[k, 1] = q, refs
    else:
        arr = np.empty(len(rows), dtype=object)
        for k, row in enumerate(rows):
            arr[k] = list(row)
    np.save(path, arr, allow_pickle=True)


def _tree(root: Path, nq: int = 4, nr: int = 5) -> None:
    _images(root / "query", [f"{i}.jpg" for i in range(nq)])
    _images(root / "ref", [f"{i}.jpg" for i in range(nr)])


@pytest.mark.parametrize("two_d", [True, False])
def test_vpr_bench_layout_rows_lists_arrays_scalars(tmp_path, two_d):
    _tree(tmp_path)
    rows = [(0, [0, 1]), (1, np.array([2])), (np.int64(2), 3), (3, [4, 3])]
    _save_gt(tmp_path / "ground_truth_new.npy", rows, two_d)
    ds = load_dataset("vpr_bench", tmp_path)
    assert ds.name == tmp_path.name == ds.meta["dataset"] and ds.meta["loader"] == "vpr_bench"
    assert ds.tolerance == 0
    assert ds.reference_paths[3].parent.name == "ref"
    assert ds.gt_pairs() == [(0, 0), (0, 1), (1, 2), (2, 3), (3, 3), (3, 4)]
    wide = load_dataset("vpr_bench", tmp_path, tolerance=1)
    assert wide.ground_truth[1].tolist() == [False, True, True, True, False]


def test_vpr_bench_natural_order_and_option(tmp_path, caplog):
    names = [f"{i}.jpg" for i in range(12)]  # natural 0..11; lexicographic 0, 1, 10, 11, 2, ...
    _images(tmp_path / "query", names)
    _images(tmp_path / "ref", names)
    _save_gt(tmp_path / "ground_truth_new.npy", [(i, [i]) for i in range(12)])
    with caplog.at_level(logging.WARNING, logger="vpr_core"):
        ds = load_dataset("vpr_bench", tmp_path)
    assert "sort differently naturally and lexicographically" in caplog.text
    assert [p.name for p in ds.query_paths][:3] == ["0.jpg", "1.jpg", "2.jpg"]
    assert ds.query_paths[10].name == "10.jpg"
    lex = load_dataset("vpr_bench", tmp_path, order="lexicographic")
    assert [p.name for p in lex.query_paths][:3] == ["0.jpg", "1.jpg", "10.jpg"]
    with pytest.raises(
        ValueError, match="unknown vpr_bench order 'mtime'; valid: natural, lexicographic"
    ):
        load_dataset("vpr_bench", tmp_path, order="mtime")


def test_vpr_bench_errors(tmp_path):
    _tree(tmp_path)
    gt = tmp_path / "ground_truth_new.npy"
    with pytest.raises(FileNotFoundError, match="ground_truth_new.npy"):
        load_dataset("vpr_bench", tmp_path)
    for rows, msg in (
        ([(0, [5])], r"row 0: reference index 5 out of range.*0..4"),
        ([(0, [1]), (4, [1])], r"row 1: query index 4 out of range"),
        ([(0, ["a"])], r"row 0: the reference indices must be integer"),
        ([(0, [0.5])], r"row 0: the reference indices must be integer"),
    ):
        _save_gt(gt, rows)
        with pytest.raises(ValueError, match=msg):
            load_dataset("vpr_bench", tmp_path)
    bad = np.empty(2, dtype=object)
    bad[0], bad[1] = [0, [1], 7], [1, [2]]
    np.save(gt, bad, allow_pickle=True)
    with pytest.raises(
        ValueError, match=r"row 0: expected rows \[query index, \[reference indices\]\]"
    ):
        load_dataset("vpr_bench", tmp_path)
    np.save(gt, np.zeros((2, 3, 4)))
    with pytest.raises(ValueError, match=r"shape \(2, 3, 4\)"):
        load_dataset("vpr_bench", tmp_path)
    gt.write_bytes(b"not a numpy file")
    with pytest.raises(
        ValueError, match="not a readable .npy file.*expected a VPR-Bench ground-truth file"
    ):
        load_dataset("vpr_bench", tmp_path)
    _save_gt(gt, [(0, [])])
    with pytest.raises(ValueError, match="no positive pair"):
        load_dataset("vpr_bench", tmp_path)


def test_read_vprbench_ground_truth_list_of_rows(tmp_path):
    path = tmp_path / "gt.npy"
    rows = np.empty(3, dtype=object)
    rows[0], rows[1], rows[2] = [0, np.array([1, 2])], [1, 0], [2, []]
    np.save(path, rows, allow_pickle=True)
    gt = read_vprbench_ground_truth(path, 3, 3)
    assert gt.tolist() == [[False, True, True], [True, False, False], [False, False, False]]


def test_vpr_bench_missing_folders(tmp_path):
    _images(tmp_path / "query", ["0.jpg"])
    with pytest.raises(FileNotFoundError, match=r"traverse folder .*ref not found"):
        load_dataset("vpr_bench", tmp_path)
