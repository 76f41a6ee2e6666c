"""Pickled and ``.npy`` inputs read as data, never as code, and never larger than the file allows:
one restricted, size-bounded unpickler (:class:`_RestrictedUnpickler`, :func:`read_npy`) for every
pickle we read (VPR-Bench's ``ground_truth_new.npy`` and ``precomputed_data_corrected.npy``)."""

from __future__ import annotations

import io
import os
import pickle
import re
import struct
from pathlib import Path
from typing import Any, NoReturn

import numpy as np
from numpy.lib import format as npy_format

__all__ = ["ALLOWED_DTYPE_KINDS", "ALLOWED_GLOBALS", "MAX_PICKLE_DEPTH", "read_npy"]

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
#: Deepest nesting of containers accepted in a pickle (VPR-Bench's files nest 3 levels).
MAX_PICKLE_DEPTH = 32
#: Elements (container items and array entries, each reference counted) a pickle may hold per
#: byte of the file, plus a fixed allowance: a pickle needs at least one byte per stored item,
#: so more means one object referenced again and again, which ``np.asarray`` would expand.
_ELEMENTS_PER_BYTE, _ELEMENTS_FLOOR = 8, 10_000
_NPY_MAGIC, _ZIP_MAGIC = b"\x93NUMPY", b"PK\x03\x04"
_HEADERS = {
    (1, 0): npy_format.read_array_header_1_0,
    (2, 0): npy_format.read_array_header_2_0,
    (3, 0): npy_format.read_array_header_2_0,
}


#: The numpy dtypes a pickled input may hold (VPR-Bench's files: bool, integer, float, object
#: and string arrays; complex too, which the readers refuse by name): a dtype string of one of
#: these kinds, e.g. ``f8``, ``O8``, ``U5``.
ALLOWED_DTYPE_KINDS = "biufcOUS"
_DTYPE = re.compile(rf"[<>|=]?[{ALLOWED_DTYPE_KINDS}]\d{{1,6}}")


class _UnsafePickleError(ValueError):
    """A pickle asked to run something other than rebuilding arrays, numbers and strings."""


def _element_budget(n_bytes: int) -> int:
    """Elements a pickle of ``n_bytes`` may hold (see :data:`_ELEMENTS_PER_BYTE`)."""
    return _ELEMENTS_PER_BYTE * n_bytes + _ELEMENTS_FLOOR


def _too_large(source: str, what: str, n_bytes: int) -> ValueError:
    return ValueError(
        f"{source} asks for {what} from a {n_bytes:,}-byte pickle (more than "
        f"{_element_budget(n_bytes):,} elements); it was not loaded, nothing was allocated "
        "(damaged or hostile file): use the file from its original source."
    )


class _RestrictedUnpickler(pickle._Unpickler):  # the Python unpickler: BUILD can be checked
    """An unpickler that resolves only :data:`ALLOWED_GLOBALS`, each as a wrapper that checks
    its arguments (dtypes of :data:`ALLOWED_DTYPE_KINDS`, latin1 bytes, data that fills its
    array), checks every array's size against the file's before numpy allocates it, and lets
    BUILD set an object once, before anything uses it: nothing changes after its check.

    Args:
        file: Binary file positioned at the pickle.
        source: What to name in the error (the input file).
        encoding: How Python-2 ``str`` objects are decoded (``"latin1"`` for VPR-Bench's files).
        n_bytes: The pickle's size in bytes (bounds every array to :func:`_element_budget`).
    """

    def __init__(self, file: Any, source: str, encoding: str = "latin1", n_bytes: int = 0) -> None:
        super().__init__(file, encoding=encoding)
        self.source = source
        self.n_bytes = n_bytes
        # objects BUILD may still set, by id (held: an id is never reused while loading): an
        # array from _reconstruct, once; a dtype from numpy.dtype, once and before any array,
        # scalar or buffer uses it (then nothing may change it: its itemsize is their bounds)
        self._unbuilt: dict[int, Any] = {}
        self._used: dict[int, np.dtype] = {}

    def _refuse(self, what: str) -> NoReturn:
        raise _UnsafePickleError(
            f"{self.source} {what}; it was not loaded, nothing was allocated (damaged or hostile "
            "file): use the file from its original source."
        )

    def _use(self, dtype: Any) -> np.dtype:
        """``dtype`` when it is a dtype of :data:`ALLOWED_DTYPE_KINDS`, from now on unchangeable."""
        if not isinstance(dtype, np.dtype) or dtype.kind not in ALLOWED_DTYPE_KINDS:
            self._refuse(f"asks for data of type {dtype!r} (not a bool, number or string dtype)")
        if dtype.fields is not None or dtype.subdtype is not None:
            self._refuse(f"asks for a structured dtype {dtype!r}")
        self._unbuilt.pop(id(dtype), None)
        self._used[id(dtype)] = dtype
        return dtype

    def _dtype(self, obj: Any, align: Any = False, copy: Any = False) -> np.dtype:
        """numpy's dtype constructor, only for a dtype string of an allowed kind."""
        # as numpy pickles a dtype: not aligned, a copy (never numpy's own shared instance,
        # which a BUILD would change for the whole process); Python 2 wrote 0 and 1
        flags_ok = all(isinstance(f, int) and f in (0, 1) for f in (align, copy))
        if not (isinstance(obj, str) and _DTYPE.fullmatch(obj) and flags_ok) or align or not copy:
            self._refuse(
                f"asks from a {self.n_bytes:,}-byte pickle for a numpy dtype {obj!r}, of a kind "
                "no VPR-Bench file holds"
            )
        dtype = np.dtype(obj, align=False, copy=True)
        self._unbuilt[id(dtype)] = dtype
        return dtype

    def _encode(self, text: Any, encoding: Any = "latin1", *rest: Any) -> bytes:
        """``_codecs.encode`` as protocol-2 pickles use it for bytes: a str in latin1."""
        if not isinstance(text, str) or encoding not in ("latin1", "latin-1") or rest:
            self._refuse(f"asks to encode {type(text).__name__} as {str(encoding)[:40]!r}")
        return text.encode("latin1")

    def _frombuffer(self, buf: Any, dtype: Any, shape: Any, order: Any) -> np.ndarray:
        """numpy's protocol-5 array rebuilder, only for bytes that fill ``shape`` exactly."""
        dtype = self._use(dtype)
        self._check_shape(shape, dtype)
        size = int(np.prod(shape, dtype=object)) * dtype.itemsize
        if (
            not isinstance(buf, (bytes, bytearray))
            or len(buf) != size
            or order not in ("C", "F")
            or dtype.hasobject
        ):
            self._refuse(f"holds an array of shape {shape!r} whose data does not fill it")
        return self._numpy_frombuffer(buf, dtype, shape, order)

    def _check_shape(self, shape: Any, dtype: Any) -> None:
        """Refuse an array of ``shape`` and ``dtype`` larger than the pickle allows."""
        dims = shape if isinstance(shape, (tuple, list)) else (shape,)
        if not all(isinstance(d, int) and d >= 0 for d in dims):
            raise _UnsafePickleError(f"{self.source} asks for an array of shape {shape!r}.")
        size = int(np.prod(dims, dtype=object))
        itemsize = np.dtype(dtype).itemsize if dtype is not None else 8
        if size > _element_budget(self.n_bytes) or size * itemsize > 8 * _element_budget(
            self.n_bytes
        ):
            shown = ", ".join(f"{d:,}" for d in dims)
            raise _too_large(self.source, f"an array of shape ({shown})", self.n_bytes)

    def _ndarray(self, shape: Any = (), *args: Any, **kwargs: Any) -> NoReturn:
        """``numpy.ndarray(...)`` called by the pickle itself: never (an array is rebuilt by
        ``_reconstruct``; a buffer with strides could read outside it); a size beyond the file's
        is named first."""
        self._check_shape(shape, None)
        self._refuse("asks to build an array on a buffer of its own")

    def _scalar(self, dtype: Any, *args: Any) -> Any:
        """numpy's scalar rebuilder, only for a dtype the pickle's size allows (a 192-byte pickle
        may not ask for a 200 MB ``V200000000`` scalar) and data that fills it exactly."""
        if not isinstance(dtype, np.dtype):
            raise _UnsafePickleError(f"{self.source} asks for a scalar of {type(dtype).__name__}.")
        self._check_shape((), dtype)
        dtype = self._use(dtype)
        data = args[0] if len(args) == 1 else None
        filled = isinstance(data, (bytes, str)) and len(data) == dtype.itemsize  # str: py2
        if not dtype.hasobject and not filled:
            self._refuse(f"holds a {dtype} scalar whose data does not fill it")
        return self._numpy_scalar(dtype, *args)

    def _reconstruct(self, subtype: Any, shape: Any, dtype: Any) -> Any:
        if subtype != self._ndarray:  # the pickle's numpy.ndarray, resolved by find_class
            raise _UnsafePickleError(f"{self.source} asks to rebuild a {subtype!r}.")
        self._check_shape(shape, None)
        array = np.ndarray(shape, "b")
        self._unbuilt[id(array)] = array
        return array

    def _load_build(self) -> None:
        """BUILD: only an array's ``__setstate__`` (once, on an array from ``_reconstruct``,
        with a shape the pickle allows, an allowed dtype and data that fills it exactly: numpy
        reads past a short object list) and a new dtype's (once, before anything uses it, and
        only a state that keeps its kind and itemsize). Nothing changes after its check."""
        stack = self.stack  # type: ignore[attr-defined]  # the Python unpickler's stack
        state, target = stack[-1], stack[-2]
        if id(target) not in self._unbuilt:
            what = "a dtype already in use" if id(target) in self._used else type(target).__name__
            self._refuse(f"asks to change {what} after it was built")
        if isinstance(target, np.ndarray):
            if not isinstance(state, tuple) or len(state) not in (4, 5):
                raise _UnsafePickleError(f"{self.source} holds a malformed array state.")
            shape, dtype, data = state[-4], self._use(state[-3]), state[-1]
            self._check_shape(shape, dtype)
            size = int(np.prod(shape, dtype=object))
            want = size if dtype.hasobject else size * dtype.itemsize
            if not isinstance(data, (list, bytes, bytearray, str)) or len(data) != want:
                raise ValueError(
                    f"{self.source} holds an array of shape {tuple(shape)} whose data does not "
                    "fill it; it was not loaded (damaged or hostile file): use the file from "
                    "its original source."
                )
        else:  # a dtype from numpy.dtype: the state tried on a copy of it first
            trial = np.dtype(target.str, align=False, copy=True)
            trial.__setstate__(state)
            if (trial.kind, trial.itemsize) != (target.kind, target.itemsize) or (
                trial.fields is not None or trial.subdtype is not None
            ):
                self._refuse(f"asks to change the dtype {target} into {trial!r}")
        del self._unbuilt[id(target)]
        pickle._Unpickler.load_build(self)  # type: ignore[attr-defined]

    def load(self) -> Any:
        """The pickled object (the Python unpickler's KeyError and struct.error for unknown
        opcodes, memo keys and short data become :class:`pickle.UnpicklingError`)."""
        try:
            return super().load()
        except (KeyError, IndexError, struct.error) as exc:
            raise pickle.UnpicklingError(f"invalid or truncated pickle data ({exc})") from None

    dispatch = dict(pickle._Unpickler.dispatch)
    dispatch[pickle.BUILD[0]] = _load_build  # type: ignore[assignment]

    def find_class(self, module: str, name: str) -> Any:
        if (module, name) in ALLOWED_GLOBALS:  # each a checking wrapper of its callable
            if name == "scalar":
                self._numpy_scalar = super().find_class(module, name)
            elif name == "_frombuffer":
                self._numpy_frombuffer = super().find_class(module, name)
            wrapper = {
                "ndarray": self._ndarray,
                "_reconstruct": self._reconstruct,
                "scalar": self._scalar,
                "_frombuffer": self._frombuffer,
                "dtype": self._dtype,
                "encode": self._encode,
            }
            return wrapper[name]
        raise _UnsafePickleError(
            f"{self.source} is a pickle that asks to run {module}.{name}; it was not loaded. Only "
            "numpy arrays, lists, tuples, numbers and strings are read from pickled inputs "
            "(restricted unpickler), so this file is damaged, of another format, or hostile: "
            "use the file from its original source."
        )

    def persistent_load(self, pid: Any) -> Any:
        raise _UnsafePickleError(
            f"{self.source} is a pickle with persistent ids; it was not loaded."
        )


def _check_bounded(obj: Any, source: str, n_bytes: int) -> Any:
    """Return ``obj`` if it holds at most ``8 * n_bytes + 10,000`` elements (shared sub-objects
    counted at every reference) nested at most :data:`MAX_PICKLE_DEPTH` deep; the walk stops as
    soon as a bound is passed, so it costs at most the bound.

    Raises:
        ValueError: a bound is exceeded (names ``source``).
    """
    budget = _element_budget(n_bytes)
    count = 0
    stack: list[tuple[Any, int]] = [(obj, 0)]
    while stack:
        item, depth = stack.pop()
        if depth > MAX_PICKLE_DEPTH:
            raise ValueError(
                f"{source} nests containers more than {MAX_PICKLE_DEPTH} deep; it was not loaded "
                "(damaged or hostile file): use the file from its original source."
            )
        children: Any = ()
        if isinstance(item, np.ndarray):
            count += item.size
            if item.dtype.hasobject:
                children = item.flat
        elif isinstance(item, (list, tuple)):
            count += len(item)
            children = item
        elif isinstance(item, dict):
            count += 2 * len(item)
            children = [*item.keys(), *item.values()]
        else:
            count += 1
        if count > budget:
            raise ValueError(
                f"{source} would expand to more than {budget:,} elements from a {n_bytes:,}-byte "
                "pickle (one object referenced again and again); it was not loaded (damaged or "
                "hostile file): use the file from its original source."
            )
        stack.extend((child, depth + 1) for child in children)
    return obj


def _restricted_loads(data: bytes, source: str, encoding: str = "latin1") -> Any:
    """Unpickle ``data`` with :class:`_RestrictedUnpickler`, size-bounded (``source`` is named in
    errors)."""
    obj = _RestrictedUnpickler(io.BytesIO(data), source, encoding, len(data)).load()
    return _check_bounded(obj, source, len(data))


def _check_npy_size(path: Path, shape: tuple[int, ...], dtype: np.dtype, n_data: int) -> None:
    """Refuse a ``.npy`` whose header claims more data than the file holds (before allocating)."""
    claimed = int(np.prod(shape, dtype=object)) * dtype.itemsize
    if claimed > n_data:
        raise ValueError(
            f"its header claims a {dtype} array of shape {shape} ({claimed:,} bytes) but the "
            f"file holds {n_data:,} bytes of data: the file is truncated or damaged"
        )


def read_npy(
    path: str | os.PathLike, expected: str, encoding: str = "latin1", allow_pickle: bool = True
) -> Any:
    """Read a ``.npy`` file, object arrays included, without ever running code from it.

    A plain ``.npy`` is read by numpy with ``allow_pickle=False`` after checking that its header's
    shape fits the file; an object array's pickle is rebuilt with :class:`_RestrictedUnpickler` and
    bounded (elements per byte of the file, depth); a file that is a bare pickle (no ``.npy``
    header) is unpickled the same way.

    Args:
        path: The file.
        expected: The format the caller expects, quoted in the errors.
        encoding: Decoding of Python-2 strings in the pickle.
        allow_pickle: False refuses object arrays and bare pickles.

    Returns:
        An ``np.ndarray`` (or, for a bare pickle, the object it holds).

    Raises:
        _UnsafePickleError: the pickle names anything but arrays, numbers and strings.
        ValueError: a ``.npz`` archive or another format, a damaged file, a header claiming more
            than the file holds, a pickle expanding beyond its bound (the message names the file
            and the expected format).
    """
    path = Path(path)
    n_bytes = path.stat().st_size
    with open(path, "rb") as f:
        head = f.read(6)
        f.seek(0)
        try:
            if head.startswith(_ZIP_MAGIC):
                raise ValueError("it is a .npz (zip) archive, not a .npy array")
            if head != _NPY_MAGIC:
                if not allow_pickle:
                    raise ValueError("it has no .npy header")
                return _restricted_loads(f.read(), str(path), encoding)  # the whole file
            version = npy_format.read_magic(f)
            if version not in _HEADERS:
                raise ValueError(f".npy format version {version} is not supported")
            shape, _, dtype = _HEADERS[version](f)
            if not dtype.hasobject:
                _check_npy_size(path, shape, dtype, n_bytes - f.tell())
                f.seek(0)
                return np.load(f, allow_pickle=False)
            if not allow_pickle:
                raise ValueError("it holds Python objects (an object array), not numbers")
            obj = _RestrictedUnpickler(io.BytesIO(f.read()), str(path), encoding, n_bytes).load()
            return _check_bounded(obj, str(path), n_bytes)
        except _UnsafePickleError:
            raise
        except Exception as exc:  # whatever a damaged file raises (LookupError, ...): named
            if isinstance(exc, ValueError) and str(path) in str(exc):  # names the file already
                raise
            raise ValueError(
                f"{path} is not a readable .npy file ({type(exc).__name__}: {str(exc)[:200]}); "
                f"expected {expected}."
            ) from None
