"""On-disk cache entries: atomic writes, and reads that heal a corrupted entry.

Every stage stores ``.npz`` files under :func:`vpr_core.utils.cache_dir`. A file that cannot be
read (truncated by a crash or a full disk, or damaged) is treated as missing: its path is
logged once, the file is removed, and the caller recomputes it, so a damaged cache never stops a
run and never changes a number.
"""

from __future__ import annotations

import os
import tempfile
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from ..utils import logger, short_hash

__all__ = ["atomic_savez", "dataset_fingerprint", "load_npz", "n_images"]

SIDES = ("query", "reference")
_REPORTED: set[str] = set()
_UNREADABLE = (zipfile.BadZipFile, EOFError, OSError, ValueError, KeyError)


def atomic_savez(path: Path, **arrays: Any) -> None:
    """Write ``arrays`` to ``path`` (``.npz``) via a temporary file and an atomic rename."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(suffix=".npz", dir=path.parent)
    os.close(fd)
    try:
        np.savez(tmp, **arrays)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)


def load_npz(path: Path, keys: tuple[str, ...]) -> dict[str, np.ndarray] | None:
    """Read ``keys`` from a cached ``.npz``; ``None`` if it is absent or unreadable.

    An unreadable file (``BadZipFile``, ``EOFError``, a missing key, a damaged array) is logged
    once with its path, removed, and reported as missing so the caller recomputes it.

    Args:
        path: the cache entry.
        keys: the arrays the caller needs (all are read eagerly, so damage surfaces here).

    Returns:
        ``{key: array}`` or ``None``.
    """
    if not path.exists():
        return None
    try:
        with np.load(path, allow_pickle=False) as z:
            return {k: np.asarray(z[k]) for k in keys}
    except _UNREADABLE as exc:
        if str(path) not in _REPORTED:
            _REPORTED.add(str(path))
            logger.warning("cache entry %s is unreadable (%s: %s); removed, recomputing it",
                           path, type(exc).__name__, exc)
        try:
            path.unlink()
        except FileNotFoundError:
            pass
        return None


def n_images(dataset, side: str) -> int:
    """Number of images on one side (``"query"`` or ``"reference"``) of a dataset."""
    return len(dataset.query_paths if side == "query" else dataset.reference_paths)


def dataset_fingerprint(dataset) -> str:
    """Short hash of a dataset's image contents and ground truth (cache key of results)."""
    keys = [dataset.image_key(s, i) for s in SIDES for i in range(n_images(dataset, s))]
    gt = np.asarray(dataset.ground_truth, dtype=bool)
    return short_hash([dataset.name, keys, short_hash(gt.tobytes().hex()), list(gt.shape)])
