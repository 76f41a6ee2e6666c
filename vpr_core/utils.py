"""Small shared helpers: logging, seeding, cache folders, config slugs, progress bars, CSV rows."""

from __future__ import annotations

import ctypes
import hashlib
import json
import logging
import os
import random
import sys
import types
import warnings
from collections.abc import Callable, Iterable, Mapping, Sized
from pathlib import Path
from typing import Any

import numpy as np
import torch
from tqdm.auto import tqdm as tqdm_auto
from tqdm.std import tqdm as tqdm_std

from . import paths, settings
from .checks import check_choice
from .notices import VPRWarning

__all__ = [
    "ALLOCATOR_KEEP_BYTES",
    "LINE_INTERVAL_S",
    "STAGE_SOURCES",
    "array_sha256",
    "cache_dir",
    "code_digest",
    "code_sha256",
    "code_version",
    "config_slug",
    "configure_logging",
    "file_fingerprint",
    "file_sha256",
    "logger",
    "make_deterministic",
    "progress",
    "short_hash",
    "tune_allocator",
]

logger = logging.getLogger("vpr_core")
logger.addHandler(logging.NullHandler())  # library convention: the application configures output


def make_deterministic(seed: int = 0) -> None:
    """Seed python, numpy and torch and ask torch for deterministic kernels."""
    random.seed(seed)
    np.random.seed(seed)
    torch.manual_seed(seed)
    torch.use_deterministic_algorithms(True, warn_only=True)


#: Free memory glibc keeps at the top of the heap once :func:`tune_allocator` ran (bytes).
ALLOCATOR_KEEP_BYTES = 1 << 30


def tune_allocator() -> bool:
    """Let glibc reuse freed memory for large tensors instead of mapping fresh pages each time.

    Sets ``M_MMAP_MAX = 0`` and ``M_TRIM_THRESHOLD`` = :data:`ALLOCATOR_KEEP_BYTES`, process-wide
    (about half of ``crop`` mode's time is page faults without it; ``bench_features.py``). Never
    changes a number; only the CLI, the runner and a notebook's first cell call it. No-op off
    glibc and when ``$VPR_TUNE_MALLOC=0``.

    Returns:
        True when the tuning is in effect in this process after the call.
    """
    if not settings.tune_malloc():
        return False
    try:
        libc = ctypes.CDLL(None)
        libc.gnu_get_libc_version  # noqa: B018 - AttributeError off glibc
    except (OSError, AttributeError):
        return False
    m_trim_threshold, m_mmap_max = -1, -4  # <malloc.h>
    ok = bool(libc.mallopt(m_mmap_max, 0) and libc.mallopt(m_trim_threshold, ALLOCATOR_KEEP_BYTES))
    logger.debug("glibc allocator tuning: %s", "on" if ok else "mallopt refused")
    return ok


class _LiveStreamHandler(logging.StreamHandler):
    """A StreamHandler writing to whatever ``sys.stderr`` / ``sys.stdout`` is at each record
    (pytest and notebook kernels replace and close the original stream)."""

    def __init__(self, to: str = "stderr") -> None:
        self.to = to
        super().__init__(getattr(sys, to))

    @property
    def stream(self):  # type: ignore[override]
        return getattr(sys, self.to)

    @stream.setter
    def stream(self, value) -> None:  # StreamHandler.__init__ assigns it
        pass


def configure_logging(
    level: str | int = "INFO", stream: str = "stderr", silence_warnings: bool = False
) -> None:
    """Send ``vpr_core`` log records to ``stream`` as ``[vpr_core LEVEL] message`` (idempotent;
    returns nothing, so a cell ending with it shows no ``<Logger ...>``: the logger is
    ``logging.getLogger("vpr_core")``).

    Args:
        level: the log level.
        stream: ``"stderr"`` (the CLI) or ``"stdout"`` (notebooks).
        silence_warnings: also stop Python printing a :class:`VPRWarning` a second time
            (a process-wide filter, set only when asked).
    """
    check_choice(stream, "configure_logging stream", ("stderr", "stdout"))
    for h in [h for h in logger.handlers if isinstance(h, _LiveStreamHandler)]:
        logger.removeHandler(h)
    h = _LiveStreamHandler(stream)
    h.setFormatter(logging.Formatter("[vpr_core %(levelname)s] %(message)s"))
    logger.addHandler(h)
    logger.setLevel(level)
    logger.propagate = False
    if silence_warnings:
        warnings.simplefilter("ignore", VPRWarning)


def cache_dir(*parts: str) -> Path:
    """``paths.cache_root()/parts...``, created."""
    return paths.make_dir(paths.cache_root().joinpath(*parts), "VPR_CACHE_DIR")


def short_hash(obj: Any, n: int = 10) -> str:
    """Stable short hex hash of a JSON-serialisable object (dict keys sorted)."""
    blob = json.dumps(obj, sort_keys=True, default=str).encode()
    return hashlib.sha1(blob).hexdigest()[:n]


def config_slug(name: str, conf: Mapping[str, Any]) -> str:
    """Readable slug + short hash for a named config, used in cache and figure names."""
    safe = "".join(c if c.isalnum() or c in "-_." else "-" for c in str(name))
    return f"{safe}-{short_hash(dict(conf))}"


class _Lines:
    """A file for tqdm outside a terminal: each refresh becomes one plain line."""

    def __init__(self, stream: Any) -> None:
        self.stream = stream

    def write(self, text: str) -> None:
        line = text.replace("\r", "").strip()
        if line:
            self.stream.write(line + "\n")

    def flush(self) -> None:
        self.stream.flush()


#: Outside a terminal (a redirected log, a pipe): a progress line with the rate and the
#: estimate at most every this many seconds, none for loops shorter than that.
LINE_INTERVAL_S = 30.0


def progress(iterable: Iterable | None, **kwargs: Any):
    """A progress bar: on a terminal ``tqdm``'s bar; in Jupyter, or with ``VPR_PROGRESS=text``,
    a plain text bar on stdout that stays at its final count (a saved notebook and a second
    browser tab show it, never "Loading widget..."); elsewhere (stdout piped or redirected) one
    line with the estimate every :data:`LINE_INTERVAL_S` seconds. Disabled by
    ``TQDM_DISABLE=1``; nothing at all for no work (a cached set: no empty bar)."""
    kwargs.setdefault("disable", settings.progress_disabled())
    total = kwargs.get("total", len(iterable) if isinstance(iterable, Sized) else None)
    if total == 0:
        kwargs["disable"] = True
    if settings.progress_style() == "text" or "ipykernel" in sys.modules:
        kwargs.setdefault("file", sys.stdout)
        kwargs.setdefault("leave", True)
        kwargs.setdefault("mininterval", 2.0)
        kwargs.setdefault("ascii", True)
        return tqdm_std(iterable, **kwargs)
    stream = kwargs.get("file") or sys.stderr
    if not getattr(stream, "isatty", lambda: False)():
        kwargs["file"] = _Lines(stream)
        kwargs.setdefault("delay", LINE_INTERVAL_S)
        kwargs.setdefault("mininterval", LINE_INTERVAL_S)
        kwargs.setdefault("maxinterval", LINE_INTERVAL_S)
        kwargs.setdefault("ascii", True)
        kwargs.setdefault("ncols", 100)
        return tqdm_std(iterable, **kwargs)
    kwargs.setdefault("leave", False)
    return tqdm_auto(iterable, **kwargs)


#: The source files each cached stage's results depend on (folders of ``vpr_core``, or files).
STAGE_SOURCES: dict[str, tuple[str, ...]] = {
    # cache.py in each: a change of the entries' format gives new keys, so entries of
    # the old format are never read (not healed one by one, each with a warning)
    "landmarks": (
        "landmarks",
        "boxes.py",
        "checks.py",
        "cache.py",
    ),
    "features": ("features", "backbones", "cache.py"),
    "matching": ("matching", "boxes.py", "run.py", "cache.py"),
}
_CODE_VERSIONS: dict[str, str] = {}


def code_version(stage: str) -> str:
    """A short hash of the source code a cached stage depends on (:data:`STAGE_SOURCES`).

    Cache keys carry it, so after any change to, e.g., the matching code a stored similarity
    matrix is never reused: it is recomputed. Computed once per process.

    Raises:
        ValueError: unknown stage (the message lists the stages).
    """
    check_choice(stage, "stage", STAGE_SOURCES)
    if stage not in _CODE_VERSIONS:
        pkg = Path(__file__).resolve().parent
        h = hashlib.sha1()
        for entry in STAGE_SOURCES[stage]:
            target = pkg / entry
            for f in sorted(target.rglob("*.py")) if target.is_dir() else [target]:
                h.update(f.relative_to(pkg).as_posix().encode())
                h.update(f.read_bytes())
        _CODE_VERSIONS[stage] = h.hexdigest()[:10]
    return _CODE_VERSIONS[stage]


def file_fingerprint(path: str | os.PathLike) -> str:
    """Content hash (sha1, 16 hex) of a file, for cache keys that survive moves and touch."""
    h = hashlib.sha1()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()[:16]


def file_sha256(path: str | os.PathLike) -> str:
    """Hex sha256 of a file's contents, read on every call (never memoised by path, size or
    modification time: a file overwritten in place gets its new identity)."""
    digest = hashlib.sha256()
    with open(Path(path).expanduser(), "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


def array_sha256(arrays: Iterable[np.ndarray]) -> str:
    """Hex sha256 of arrays' dtypes, shapes and bytes, in order (a cache key from content)."""
    digest = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(a)
        digest.update(f"{a.dtype.str}{a.shape}|".encode())
        digest.update(a.tobytes())
    return digest.hexdigest()


def _code_digest(code: types.CodeType, digest: Any) -> None:
    digest.update(code.co_code)
    digest.update(repr(code.co_names).encode())
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            _code_digest(const, digest)
        elif isinstance(const, frozenset):
            digest.update(repr(sorted(map(repr, const))).encode())
        else:
            digest.update(repr(const).encode())


def code_digest(functions: Iterable[Callable]) -> str:
    """Hex sha256 of the bytecode of ``functions`` (a step defined in a notebook cell)."""
    digest = hashlib.sha256()
    for func in functions:
        code = getattr(func, "__code__", None)
        if code is None:  # a callable object: its class's code
            digest.update(code_sha256([type(func)]).encode())
        else:
            _code_digest(code, digest)
    return digest.hexdigest()


def code_sha256(classes: Iterable[type], prefix: str = "") -> str:
    """Hex sha256 of the bytecode of the methods of ``classes`` (those of vpr_core, torch and
    builtins skipped): a class edited in a notebook cell gets a new identity."""
    digest = hashlib.sha256(prefix.encode())
    for cls in sorted(set(classes), key=lambda c: f"{c.__module__}.{c.__qualname__}"):
        if cls.__module__.split(".")[0] in ("vpr_core", "torch", "builtins"):
            continue
        for name, attr in sorted(vars(cls).items()):
            func = getattr(attr, "__func__", attr)
            if isinstance(func, types.FunctionType):
                digest.update(f"{cls.__qualname__}.{name}".encode())
                _code_digest(func.__code__, digest)
    return digest.hexdigest()
