"""vpr_core.datasets.safe_pickle: the restricted unpickler builds nothing it has not checked, and
nothing it built changes after its check; every exception while reading a file names the file.
The hostile files are written opcode by opcode (a pickler would never emit them)."""

from __future__ import annotations

import pickle
import struct

import numpy as np
import pytest

from vpr_core.datasets.safe_pickle import read_npy


def _str(text: str) -> bytes:
    data = text.encode()
    return b"\x8c" + bytes([len(data)]) + data  # SHORT_BINUNICODE


def _int(n: int) -> bytes:
    return b"J" + struct.pack("<i", n)  # BININT


def _bytes(data: bytes) -> bytes:
    return b"C" + bytes([len(data)]) + data  # SHORT_BINBYTES


def _global(module: str, name: str) -> bytes:
    return b"c" + module.encode() + b"\n" + name.encode() + b"\n"


def _tuple(*items: bytes) -> bytes:
    return b"(" + b"".join(items) + b"t"


def _dtype(code: str, state_size: int = -1, align: int = -1) -> bytes:
    """``numpy.dtype(code, False, True)`` then BUILD with a state of ``state_size``, memo 0."""
    state = _tuple(_int(3), _str("|"), b"N", b"N", b"N", _int(state_size), _int(align), _int(0))
    return _global("numpy", "dtype") + _tuple(_str(code), b"\x89", b"\x88") + b"R" + state + b"b"


def _array_on_memo0(n: int, itemsize: int) -> bytes:
    """``_reconstruct(ndarray, (0,), b'b')``, BUILD ``(1, (n,), <memo 0>, False, data)``."""
    rebuild = _global("numpy._core.multiarray", "_reconstruct")
    args = _tuple(_global("numpy", "ndarray"), _tuple(_int(0)), _bytes(b"b"))
    state = _tuple(_int(1), _tuple(_int(n)), b"h\x00", b"\x89", _bytes(b"\x01" * n * itemsize))
    return rebuild + args + b"R" + state + b"b"


def _dtype_changed_after_use() -> bytes:
    """The issue's 183-byte file: a dtype, an array on it, then the same dtype's itemsize set to
    1 GiB (the array then reads out of bounds)."""
    body = _dtype("S8", 8, 1) + b"q\x00" + b"0"  # memo 0: the dtype, popped
    body += _array_on_memo0(4, 8) + b"q\x01" + b"0"  # memo 1: an array of 4 S8 items
    body += b"h\x00" + _state(1 << 30) + b"b0"
    return b"\x80\x02" + body + b"h\x01."


def _state(size: int) -> bytes:
    """A flexible dtype's BUILD state giving it ``size`` bytes per item."""
    return _tuple(_int(3), _str("|"), b"N", b"N", b"N", _int(size), _int(1), _int(0))


def _dtype_built_twice() -> bytes:
    return b"\x80\x02" + _dtype("S8", 8, 1) + _state(8) + b"b."


def _dtype_state_changing_size() -> bytes:
    return b"\x80\x02" + _dtype("S8", 1 << 30, 1) + b"."


def _codec(name: str) -> bytes:
    return b"\x80\x02" + _global("_codecs", "encode") + _tuple(_str("abc"), _str(name)) + b"R."


def _array_built_twice() -> bytes:
    body = _dtype("f8") + b"q\x00" + b"0" + _array_on_memo0(2, 8)
    state = _tuple(_int(1), _tuple(_int(2)), b"h\x00", b"\x89", _bytes(b"\x02" * 16))
    return b"\x80\x02" + body + state + b"b."


def _ndarray_on_a_buffer() -> bytes:
    args = _tuple(_tuple(_int(4)), _str("f8"), _bytes(b"\x00" * 8), _int(0), _tuple(_int(-8)))
    return b"\x80\x02" + _global("numpy", "ndarray") + args + b"R."


def _shared_dtype() -> bytes:
    """``numpy.dtype('f8', False, False)``: numpy's own float64 instance, which a BUILD would
    change for the whole process."""
    return b"\x80\x02" + _global("numpy", "dtype") + _tuple(_str("f8"), b"\x89", b"\x89") + b"R."


def _void_dtype() -> bytes:
    return b"\x80\x02" + _dtype("V16") + b"."


def _build_on_a_list() -> bytes:
    return b"\x80\x02]" + _tuple(_int(1)) + b"b."


HOSTILE = {
    "dtype changed after an array used it": (_dtype_changed_after_use, "a dtype already in use"),
    "dtype built twice": (_dtype_built_twice, "asks to change .* after it was built"),
    "dtype state changing its itemsize": (_dtype_state_changing_size, "asks to change the dtype"),
    "unknown codec": (lambda: _codec("no-such-codec"), "asks to encode str as 'no-such-codec'"),
    "codec other than latin1": (lambda: _codec("rot13"), "asks to encode str as 'rot13'"),
    "array built twice": (_array_built_twice, "asks to change .* after it was built"),
    "ndarray on a buffer with strides": (_ndarray_on_a_buffer, "build an array on a buffer"),
    "void dtype": (_void_dtype, "dtype 'V16', of a kind no VPR-Bench file holds"),
    "numpy's shared dtype": (_shared_dtype, "dtype 'f8', of a kind no VPR-Bench file holds"),
    "BUILD on a list": (_build_on_a_list, "asks to change list after it was built"),
}


@pytest.mark.parametrize("name", list(HOSTILE))
def test_a_hostile_pickle_is_refused_naming_the_file(tmp_path, name):
    make, words = HOSTILE[name]
    path = tmp_path / "ground_truth_new.npy"
    path.write_bytes(make())
    with pytest.raises(ValueError, match=rf"^{path}[ :].*{words}"):
        read_npy(path, "VPR-Bench's ground truth")


def test_the_issue_file_is_small():
    assert len(_dtype_changed_after_use()) < 250


@pytest.mark.parametrize(
    "data",
    [b"\x80\x02" + _global("_codecs", "encode") + b"R.", b"\x80\x02K\x01K\x02\x93.", b"\x80\x02"],
    ids=["REDUCE without arguments", "STACK_GLOBAL of numbers", "no STOP"],
)
def test_any_exception_while_reading_names_the_file(tmp_path, data):
    path = tmp_path / "precomputed_data_corrected.npy"
    path.write_bytes(data)
    with pytest.raises(ValueError, match=rf"^{path}"):
        read_npy(path, "a precomputed file")


@pytest.mark.parametrize("protocol", [2, 4, 5])
def test_what_vpr_bench_files_hold_still_loads(tmp_path, protocol):
    rows = np.empty(3, dtype=object)
    rows[:] = [[0, [0, 1]], [1, np.array([1])], [2, []]]
    data = [rows, np.eye(2), np.float64(0.5), np.int64(3), np.array(["ab", "c"]), b"x"]
    path = tmp_path / "x.npy"
    path.write_bytes(pickle.dumps(data, protocol=protocol))
    out = read_npy(path, "x")
    assert out[0][1][1].tolist() == [1] and np.array_equal(out[1], np.eye(2))
    assert out[2] == 0.5 and out[3] == 3 and out[4].tolist() == ["ab", "c"] and out[5] == b"x"
