"""Untrusted files stay data (issue 17 items 1 and 5, issue 25 items 8 and 9): the restricted,
size-bounded unpickler, .npy headers checked against the file, ground truth as written."""

from __future__ import annotations

import builtins
import os
import pickle
import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest

from vpr_core.datasets import load_dataset
from vpr_core.datasets.safe_pickle import _restricted_loads, _UnsafePickleError, read_npy
from vpr_study.peers import load_vprbench_precomputed, peer_from_matrix


class _System:
    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return (os.system, (f"touch {self.marker}",))


class _Open:
    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return (builtins.open, (str(self.marker), "w"))


def _images(folder: Path, n: int) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    for i in range(n):
        assert cv2.imwrite(str(folder / f"{i}.jpg"), np.full((32, 32, 3), 30 * i, np.uint8))


def _object_array(*items) -> np.ndarray:
    arr = np.empty(len(items), dtype=object)
    for k, v in enumerate(items):
        arr[k] = v
    return arr


def _hostile_files(tmp_path: Path, marker: Path) -> dict[str, Path]:
    """The same payloads in several shapes: object .npy, nested in a list, a bare pickle."""
    files = {}
    files["npy_row"] = tmp_path / "row.npy"
    np.save(files["npy_row"], _object_array([0, [0]], [1, _System(marker)]), allow_pickle=True)
    files["npy_nested"] = tmp_path / "nested.npy"
    np.save(files["npy_nested"], _object_array([0, [[1, [_Open(marker)]]]]), allow_pickle=True)
    files["bare"] = tmp_path / "bare.npy"
    files["bare"].write_bytes(pickle.dumps([[0, [0]], _System(marker)], protocol=2))
    files["bare_open"] = tmp_path / "bare_open.npy"
    files["bare_open"].write_bytes(pickle.dumps({"a": (_Open(marker),)}))
    return files


def test_hostile_pickles_never_run(tmp_path):
    marker = tmp_path / "MARKER"
    for kind, path in _hostile_files(tmp_path, marker).items():
        with pytest.raises(
            _UnsafePickleError,
            match=rf"{path.name} is a pickle that asks to run "
            r"(posix\.system|builtins\.open|io\.open)",
        ):
            read_npy(path, "test data")
        assert not marker.exists(), kind
    # np.load would have run it: the test's payload is real
    np.load(tmp_path / "row.npy", allow_pickle=True)
    assert marker.exists()


def test_hostile_vpr_bench_files_refused_by_the_loaders(tmp_path):
    marker = tmp_path / "MARKER"
    _images(tmp_path / "query", 2)
    _images(tmp_path / "ref", 2)
    gt = tmp_path / "ground_truth_new.npy"
    np.save(gt, _object_array([0, [0]], [1, _System(marker)]), allow_pickle=True)
    with pytest.raises(ValueError, match="ground_truth_new.npy is a pickle that asks to run"):
        load_dataset("vpr_bench", tmp_path)
    peer = tmp_path / "pc" / "GP" / "HOG" / "precomputed_data_corrected.npy"
    peer.parent.mkdir(parents=True)
    np.save(
        peer,
        _object_array(np.arange(2), np.arange(2), np.ones(2), np.eye(2), _Open(marker), 0.1),
        allow_pickle=True,
    )
    with pytest.raises(ValueError, match="precomputed_data_corrected.npy is a pickle that asks"):
        load_vprbench_precomputed(peer)
    np.save(tmp_path / "ground_truth.npy", _object_array(_System(marker)), allow_pickle=True)
    with pytest.raises(ValueError, match="ground_truth.npy is a pickle that asks to run"):
        load_dataset("folder", tmp_path, query="query", reference="ref")
    assert not marker.exists()


def test_legitimate_pickles_still_load(tmp_path):
    data = [
        np.arange(3),
        np.float64(2.5),
        np.int64(7),
        "s",
        b"b",
        None,
        True,
        (1, 2.0),
        np.array([[1.0, 2.0]], dtype=np.float32),
        np.array(["x"], dtype=object),
    ]
    for protocol in (2, 4, 5):
        out = _restricted_loads(pickle.dumps(data, protocol=protocol), "mem")
        assert out[:1][0].tolist() == [0, 1, 2] and out[1] == 2.5 and out[2] == 7
        assert out[3:8] == ["s", b"b", None, True, (1, 2.0)]
        assert out[8].dtype == np.float32 and out[9].tolist() == ["x"]
    # numpy 1 / Python 2 files (VPR-Bench's) name numpy.core.multiarray, GLOBAL opcode
    old = pickle.dumps(data[:3], protocol=2).replace(b"numpy._core.", b"numpy.core.")
    assert b"numpy.core.multiarray" in old
    assert _restricted_loads(old, "mem")[1] == 2.5
    path = tmp_path / "plain.npy"
    np.save(path, np.eye(2))
    assert np.array_equal(read_npy(path, "x"), np.eye(2))


def test_vpr_bench_mask_rows_read_as_masks(tmp_path):
    _images(tmp_path / "query", 2)
    _images(tmp_path / "ref", 3)
    gt = tmp_path / "ground_truth_new.npy"
    np.save(
        gt,
        _object_array([0, np.array([False, True, True])], [1, [True, False, False]]),
        allow_pickle=True,
    )
    ds = load_dataset("vpr_bench", tmp_path)
    assert ds.ground_truth.tolist() == [[False, True, True], [True, False, False]]
    np.save(gt, _object_array([0, np.array([False, True])], [1, [0]]), allow_pickle=True)
    with pytest.raises(
        ValueError,
        match=r"row 0: the references are a boolean mask of length 2, "
        r"but the ref folder has 3 images",
    ):
        load_dataset("vpr_bench", tmp_path)


def test_npz_named_npy_is_a_clear_error(tmp_path):
    _images(tmp_path / "query", 2)
    _images(tmp_path / "reference", 2)
    with open(tmp_path / "ground_truth.npy", "wb") as f:
        np.savez(f, gt=np.eye(2, dtype=bool))
    with pytest.raises(
        ValueError,
        match=r"ground_truth.npy is not a readable .npy file .*\.npz "
        r"\(zip\) archive.*expected a \(2, 2\) bool",
    ):
        load_dataset("folder", tmp_path)


def test_csv_bom_accepted_without_false_warning(tmp_path):
    _images(tmp_path / "query", 3)
    _images(tmp_path / "reference", 3)
    (tmp_path / "ground_truth.csv").write_bytes(
        "query,reference\n0,1\n1,2\n2,0\n".encode("utf-8-sig")
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ds = load_dataset("folder", tmp_path)
    assert ds.gt_pairs() == [(0, 1), (1, 2), (2, 0)]


def test_latin1_csv_names_file_line_and_encoding(tmp_path):
    _images(tmp_path / "query", 2)
    _images(tmp_path / "reference", 2)
    (tmp_path / "ground_truth.csv").write_bytes(
        "query,reference\n0.jpg,1.jpg\n1.jpg,caf\xe9.jpg\n".encode("latin-1")
    )
    with pytest.raises(
        ValueError,
        match=r"ground_truth.csv, line 3: not UTF-8 text \(byte 0xe9"
        r".*save the file as UTF-8",
    ):
        load_dataset("folder", tmp_path)


# -- issue 25 items 8 and 9: nothing builds more than the file holds ---------------------------


def _shared_list_bomb(levels: int = 5, width: int = 100) -> bytes:
    """A tiny pickle whose nested lists all reuse one inner list: ``width ** levels`` leaves."""
    inner: list = [0] * width
    for _ in range(levels - 1):
        inner = [inner] * width
    return pickle.dumps(inner, protocol=2)


def test_shared_reference_pickle_bomb_is_refused(tmp_path):
    data = _shared_list_bomb()
    assert len(data) < 2_000  # 10^10 leaves from a few hundred bytes
    with pytest.raises(ValueError, match=r"mem would expand to more than .* elements"):
        _restricted_loads(data, "mem")
    # the same inside a VPR-Bench ground truth (an object .npy) and as a bare pickle file
    _images(tmp_path / "query", 2)
    _images(tmp_path / "ref", 2)
    gt = tmp_path / "ground_truth_new.npy"
    row = [0, [[0] * 100] * 100]
    np.save(gt, _object_array(*([row] * 100)), allow_pickle=True)
    with pytest.raises(ValueError, match=r"ground_truth_new\.npy would expand to more than"):
        read_npy(gt, "x")
    with pytest.raises(ValueError, match=r"ground_truth_new\.npy would expand"):
        load_dataset("vpr_bench", tmp_path)
    bare = tmp_path / "bare.npy"
    bare.write_bytes(data)
    with pytest.raises(ValueError, match=r"bare\.npy would expand"):
        read_npy(bare, "x")


def test_deeply_nested_pickle_is_refused_by_name(tmp_path):
    deep: list = [0]
    for _ in range(200):
        deep = [deep]
    path = tmp_path / "deep.npy"
    path.write_bytes(pickle.dumps(deep, protocol=2))
    with pytest.raises(ValueError, match=r"deep\.npy nests containers more than 32 deep"):
        read_npy(path, "x")


def test_large_legitimate_ground_truth_is_within_the_bound(tmp_path):
    rows = _object_array(*[[q, list(range(q, q + 5))] for q in range(2_000)])
    path = tmp_path / "gt.npy"
    np.save(path, rows, allow_pickle=True)
    assert len(read_npy(path, "x")) == 2_000


def _npy_claiming(path: Path, shape: tuple[int, ...], dtype: str = "<f8") -> None:
    """A ``.npy`` whose header claims ``shape`` but that holds 16 bytes of data."""
    with open(path, "wb") as f:
        np.lib.format.write_array_header_1_0(
            f, {"descr": dtype, "fortran_order": False, "shape": shape}
        )
        f.write(b"\0" * 16)


def test_npy_header_bomb_is_refused_before_allocating(tmp_path):
    bomb = tmp_path / "peer.npy"
    _npy_claiming(bomb, (10**6, 10**6))
    with pytest.raises(ValueError, match=r"peer 'x': .*peer\.npy .*claims .*\(1000000, 1000000\)"):
        peer_from_matrix(bomb, "x")
    _images(tmp_path / "query", 2)
    _images(tmp_path / "reference", 2)
    _npy_claiming(tmp_path / "ground_truth.npy", (10**6, 10**6), "|b1")
    with pytest.raises(ValueError, match=r"ground_truth\.npy is not a readable .npy file .*claims"):
        load_dataset("folder", tmp_path)
