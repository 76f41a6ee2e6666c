"""Pickled inputs read as data, never as code: one restricted unpickler for every pickle we read.

VPR-Bench's ``ground_truth_new.npy`` and ``precomputed_data_corrected.npy`` are numpy object arrays,
i.e. a ``.npy`` header followed by a pickle. numpy's pickle-enabled loading would let such a file run
any code (a pickle can ask to call ``os.system``). :func:`read_npy` parses the ``.npy`` header itself
and unpickles the rest with :class:`RestrictedUnpickler`, which rebuilds only what those formats
contain: numpy arrays, dtypes and scalars, lists, tuples, dicts, numbers, strings, bytes, None and
bools. Anything else is refused with :class:`UnsafePickleError`, naming the file and the callable
the pickle asked for, before anything runs.
"""

from __future__ import annotations

import io
import os
import pickle
from pathlib import Path
from typing import Any

import numpy as np
from numpy.lib import format as npy_format

__all__ = [
    "ALLOWED_GLOBALS",
    "RestrictedUnpickler",
    "UnsafePickleError",
    "read_npy",
    "restricted_loads",
]

#: The only callables a pickle may name: numpy's array / dtype / scalar rebuilders (both the
#: numpy 1 ``numpy.core`` and numpy 2 ``numpy._core`` spellings) and ``_codecs.encode``, which
#: Python 3 protocol-2 pickles use to write bytes.
ALLOWED_GLOBALS = frozenset(
    {
        (core + ".multiarray", n)
        for core in ("numpy.core", "numpy._core")
        for n in ("_reconstruct", "scalar")
    }
    | {(core + ".numeric", "_frombuffer") for core in ("numpy.core", "numpy._core")}
    | {("numpy", "ndarray"), ("numpy", "dtype"), ("_codecs", "encode")}
)
_NPY_MAGIC, _ZIP_MAGIC = b"\x93NUMPY", b"PK\x03\x04"
_HEADERS = {
    (1, 0): npy_format.read_array_header_1_0,
    (2, 0): npy_format.read_array_header_2_0,
    (3, 0): npy_format.read_array_header_2_0,
}


class UnsafePickleError(ValueError):
    """A pickle asked to run something other than rebuilding arrays, numbers and strings."""


class RestrictedUnpickler(pickle.Unpickler):
    """``pickle.Unpickler`` that resolves only :data:`ALLOWED_GLOBALS`.

    Args:
        file: Binary file positioned at the pickle.
        source: What to name in the error (the input file).
        encoding: How Python-2 ``str`` objects are decoded (``"latin1"`` for VPR-Bench's files).
    """

    def __init__(self, file: Any, source: str, encoding: str = "latin1") -> None:
        super().__init__(file, encoding=encoding)
        self.source = source

    def find_class(self, module: str, name: str) -> Any:
        if (module, name) in ALLOWED_GLOBALS:
            return super().find_class(module, name)
        raise UnsafePickleError(
            f"{self.source} is a pickle that asks to run {module}.{name}; it was not loaded. Only "
            "numpy arrays, lists, tuples, numbers and strings are read from pickled inputs "
            "(restricted unpickler), so this file is damaged, of another format, or hostile: "
            "use the file from its original source."
        )

    def persistent_load(self, pid: Any) -> Any:
        raise UnsafePickleError(
            f"{self.source} is a pickle with persistent ids; it was not loaded."
        )


def restricted_loads(data: bytes, source: str, encoding: str = "latin1") -> Any:
    """Unpickle ``data`` with :class:`RestrictedUnpickler` (``source`` is named in errors)."""
    return RestrictedUnpickler(io.BytesIO(data), source, encoding).load()


def read_npy(path: str | os.PathLike, expected: str, encoding: str = "latin1") -> Any:
    """Read a ``.npy`` file, object arrays included, without ever running code from it.

    A plain ``.npy`` is read by numpy with ``allow_pickle=False``; an object array's pickle is
    rebuilt with :class:`RestrictedUnpickler`; a file that is a bare pickle (no ``.npy`` header)
    is unpickled the same way.

    Args:
        path: The file.
        expected: The format the caller expects, quoted in the errors.
        encoding: Decoding of Python-2 strings in the pickle.

    Returns:
        An ``np.ndarray`` (or, for a bare pickle, the object it holds).

    Raises:
        UnsafePickleError: the pickle names anything but arrays, numbers and strings.
        ValueError: a ``.npz`` archive or another format, a damaged file (the message names the
            file and the expected format).
    """
    path = Path(path)
    with open(path, "rb") as f:
        head = f.read(6)
        f.seek(0)
        try:
            if head.startswith(_ZIP_MAGIC):
                raise ValueError("it is a .npz (zip) archive, not a .npy array")
            if head != _NPY_MAGIC:
                return RestrictedUnpickler(f, str(path), encoding).load()
            version = npy_format.read_magic(f)
            if version not in _HEADERS:
                raise ValueError(f".npy format version {version} is not supported")
            _, _, dtype = _HEADERS[version](f)
            if not dtype.hasobject:
                f.seek(0)
                return np.load(f, allow_pickle=False)
            return RestrictedUnpickler(f, str(path), encoding).load()
        except UnsafePickleError:
            raise
        except (
            OSError,
            ValueError,
            EOFError,
            TypeError,
            AttributeError,
            IndexError,
            pickle.UnpicklingError,
        ) as exc:
            raise ValueError(
                f"{path} is not a readable .npy file ({type(exc).__name__}: {exc}); expected "
                f"{expected}."
            ) from None
