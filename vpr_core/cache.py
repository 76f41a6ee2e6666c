"""On-disk cache entries: atomic writes, and reads that heal a corrupted, edited or foreign entry
(each records its identity and the sha256 of every array, checked on read; a file that fails is
logged, removed and recomputed, so a damaged cache never stops a run and never changes a number).

Memory-mapped arrays (the per-image feature stores' descriptors) are not hashed on read, which
would read every row: they are protected by the atomic rename (never a partial file), the zip's
member size and the ``.npy`` header (a truncated or resized array is refused), the dtype and
shape recorded beside their checksum, and the checksums of the arrays read in full (the store's
index: boxes and costs)."""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import struct
import tempfile
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from .datasets.base import SIDES
from .utils import logger, short_hash

__all__ = [
    "CHECKSUMS",
    "atomic_savez",
    "dataset_fingerprint",
    "images_fingerprint",
    "load_npz",
    "n_images",
]

_REPORTED: set[str] = set()
_UNREADABLE = (zipfile.BadZipFile, EOFError, OSError, ValueError, KeyError)


class _ForeignEntryError(ValueError):
    """A readable cache entry that is not the one asked for (another identity, wrong shape)."""


class _DamagedEntryError(ValueError):
    """A readable cache entry whose arrays do not match the checksums written beside them
    (edited by hand, damaged on disk, or written by a version without checksums)."""


#: Name of the array of an entry that holds ``{key: [dtype, shape, sha256]}`` of every other one.
CHECKSUMS = "_checksums"


def _digest(a: np.ndarray) -> str:
    """Hex sha256 of an array's bytes in C order (no copy when already contiguous)."""
    a = np.ascontiguousarray(a)
    return hashlib.sha256(a.reshape(-1).view(np.uint8).data if a.size else b"").hexdigest()


def _checksums(arrays: dict[str, Any]) -> str:
    """``{key: [dtype, shape, sha256]}`` of ``arrays`` as JSON (what :func:`load_npz` checks)."""
    out = {}
    for k, v in arrays.items():
        a = np.asanyarray(v)
        out[k] = [a.dtype.str, list(a.shape), _digest(a) if not a.dtype.hasobject else ""]
    return json.dumps(out, sort_keys=True)


def _verify(z: Any, out: dict[str, np.ndarray], mapped: tuple[str, ...]) -> None:
    """Raise :class:`_DamagedEntryError` unless each array of ``out`` matches the checksum the
    entry records: dtype and shape always, the sha256 of its bytes unless memory-mapped."""
    if CHECKSUMS not in z.files:
        raise _DamagedEntryError("it carries no checksums (written by an older version)")
    try:
        recorded = json.loads(str(z[CHECKSUMS]))
    except ValueError:
        raise _DamagedEntryError("its checksums do not read") from None
    for k, a in out.items():
        dtype, shape, digest = recorded.get(k, (None, None, None))
        if (dtype, shape) != (a.dtype.str, list(a.shape)):
            raise _DamagedEntryError(f"{k!r} is not the {dtype} {shape} array it was written as")
        if k not in mapped and digest != _digest(a):
            raise _DamagedEntryError(f"the bytes of {k!r} do not match its checksum (edited?)")


def _cache_folder_error(path: Path, exc: OSError) -> OSError:
    """The error for a cache folder that cannot be written, naming it and the fix."""
    return type(exc)(
        exc.errno,
        f"cannot write the cache entry {path} ({exc.strerror}); the "
        f"cache folder comes from VPR_CACHE_DIR (or <output root>/.cache): point "
        "VPR_CACHE_DIR at a writable folder with free space",
    )


def atomic_savez(path: Path, identity: str | None = None, **arrays: Any) -> None:
    """Write ``arrays`` to ``path`` (``.npz``) via a temporary file and an atomic rename, with
    the dtype, shape and sha256 of each array beside them (:data:`CHECKSUMS`).

    Args:
        path: the entry.
        identity: what the entry was computed from (checked by :func:`load_npz`).
        **arrays: the arrays.

    Raises:
        OSError: the folder cannot be written (read-only, a file, full): the message names the
            entry, ``VPR_CACHE_DIR`` and the fix; no partial file is left.
    """
    if identity is not None:
        arrays["_identity"] = np.array(identity)
    arrays[CHECKSUMS] = np.array(_checksums(arrays))
    tmp = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(suffix=".npz", dir=path.parent)
        os.close(fd)
        np.savez(tmp, **arrays)
        os.replace(tmp, path)
    except OSError as exc:
        raise _cache_folder_error(path, exc) from exc
    finally:
        if tmp is not None and os.path.exists(tmp):
            os.remove(tmp)


def _mapped(path: Path, z: Any, key: str) -> np.ndarray:
    """Array ``key`` of an uncompressed ``.npz`` as a read-only memory map: only the parts a
    caller indexes are read (a large store asked for a few rows); its CRC is not checked."""
    info = z.zip.getinfo(f"{key}.npy")
    if info.compress_type != zipfile.ZIP_STORED:
        raise ValueError(f"{key} is compressed")
    with open(path, "rb") as f:
        f.seek(info.header_offset)
        local = f.read(30)
        if local[:4] != b"PK\x03\x04":
            raise ValueError(f"no zip entry header for {key}")
        name_len, extra_len = struct.unpack("<HH", local[26:30])
        f.seek(info.header_offset + 30 + name_len + extra_len)
        start = f.tell()
        fmt = np.lib.format
        v2 = fmt.read_magic(f) == (2, 0)
        shape, fortran, dtype = (fmt.read_array_header_2_0 if v2 else fmt.read_array_header_1_0)(f)
        offset = f.tell()
    if dtype.hasobject or offset - start + dtype.itemsize * int(np.prod(shape)) > info.file_size:
        raise ValueError(f"{key} is not a plain array of its stated size")
    if 0 in shape:
        return np.zeros(shape, dtype)
    return np.memmap(
        path, dtype=dtype, mode="r", offset=offset, shape=shape, order="F" if fortran else "C"
    )


def load_npz(
    path: Path,
    keys: tuple[str, ...],
    identity: str | None = None,
    check: Callable[[dict[str, np.ndarray]], str | None] | None = None,
    mapped: tuple[str, ...] = (),
) -> dict[str, np.ndarray] | None:
    """Read ``keys`` from a cached ``.npz``; ``None`` if it is absent, unreadable or foreign.

    An unreadable file (``BadZipFile``, ``EOFError``, a missing key, a damaged array), one whose
    arrays do not match their recorded checksums (:class:`_DamagedEntryError`: an entry edited by
    hand, or one without checksums), one whose recorded identity differs from ``identity``, or
    one that ``check`` rejects is logged once with its path and the reason, removed, and
    reported as missing so the caller recomputes it.

    Args:
        path: the cache entry.
        keys: the arrays the caller needs (read eagerly, so damage surfaces here).
        identity: what the caller expects the entry to be computed from (None: not checked).
        check: returns why the arrays do not fit (e.g. ``"descriptors of 7 columns, expected
            1024"``) or None.
        mapped: keys to memory-map instead (:func:`_mapped`; their size, header, dtype and shape
            are checked, their bytes are not read).

    Returns:
        ``{key: array}`` or ``None``.
    """
    if not path.exists():
        return None
    try:
        with np.load(path, allow_pickle=False) as z:
            out = {k: _mapped(path, z, k) if k in mapped else np.asarray(z[k]) for k in keys}
            if identity is not None:
                stored = str(z["_identity"]) if "_identity" in z.files else "no identity"
                if stored != identity:
                    raise _ForeignEntryError(f"it holds {stored!r}, not {identity!r}")
            problem = check(out) if check is not None else None
            if problem:
                raise _ForeignEntryError(problem)
            _verify(z, out, mapped)  # last: an entry of the wrong shape is named for its shape
        return out
    except _UNREADABLE as exc:
        if str(path) not in _REPORTED:
            _REPORTED.add(str(path))
            what = (
                "does not hold what it is named for"
                if isinstance(exc, _ForeignEntryError)
                else "does not match its checksums"
                if isinstance(exc, _DamagedEntryError)
                else "is unreadable"
            )
            logger.warning(
                "cache entry %s %s (%s: %s); removed, recomputing it",
                path,
                what,
                type(exc).__name__.lstrip("_"),  # ForeignEntryError, BadZipFile, ...
                exc,
            )
        with contextlib.suppress(FileNotFoundError):
            path.unlink()
        return None


def n_images(dataset, side: str) -> int:
    """Number of images on one side (``"query"`` or ``"reference"``) of a dataset."""
    return len(dataset.query_paths if side == "query" else dataset.reference_paths)


def dataset_fingerprint(dataset) -> str:
    """Short hash of a dataset's name, the contents of its images in order (sha1 of each file,
    :meth:`~vpr_core.datasets.PlaceDataset.image_key`) and its ground truth: the dataset's
    identity on results and in their cache key (renaming or moving files keeps it)."""
    keys = [dataset.image_key(s, i) for s in SIDES for i in range(n_images(dataset, s))]
    gt = np.asarray(dataset.ground_truth, dtype=bool)
    return short_hash([dataset.name, keys, short_hash(gt.tobytes().hex()), list(gt.shape)])


def images_fingerprint(dataset) -> str:
    """Short hash of a dataset's name and the contents of its images in order, not its ground
    truth: the folder of its Eq. (1) matrices, which a tolerance sweep shares."""
    keys = [dataset.image_key(s, i) for s in SIDES for i in range(n_images(dataset, s))]
    return short_hash([dataset.name, keys])
