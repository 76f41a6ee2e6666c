"""One-line input checks for the package's boundaries (after kornia's ``KORNIA_CHECK_SHAPE``): each
returns the parsed value or raises one error line naming the argument, the problem and the fix."""

from __future__ import annotations

import math
import numbers
import os
import stat
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np
import torch

__all__ = [
    "BOOTSTRAP_BYTES_PER_RESAMPLE",
    "check_bootstrap_memory",
    "check_boxes",
    "check_choice",
    "check_descriptors_kept",
    "check_device",
    "check_file",
    "check_finite",
    "check_image",
    "check_image_size",
    "check_int",
    "check_options",
    "check_per_match",
    "check_range",
    "check_results",
    "check_shape",
    "is_int",
    "is_number",
    "is_result",
]


def check_shape(x: Any, shape: str, name: str = "x", dtype: Any = None) -> np.ndarray:
    """Return ``x`` as an array whose shape matches ``shape``, e.g. ``"K 4"`` or ``"N 3 3"``.

    Args:
        x: array-like.
        shape: space-separated dimensions; a number is a fixed size, a name any size.
        name: the argument's name in the message.
        dtype: convert to this dtype (None: keep).

    Returns:
        The array.
    """
    arr = np.asarray(x, dtype=dtype)
    dims = shape.split()
    if arr.ndim != len(dims) or any(
        d.isdigit() and int(d) != n for d, n in zip(dims, arr.shape, strict=False)
    ):
        raise ValueError(f"{name} must have shape ({', '.join(dims)}), got {arr.shape}")
    return arr


def check_boxes(
    boxes: Any, name: str = "boxes", k: int | None = None, positive: bool = False
) -> np.ndarray:
    """Return ``boxes`` as float64 ``(K, 4)`` ``(x, y, w, h)``; an empty input gives ``(0, 4)``.

    Args:
        boxes: array-like boxes.
        name: the argument's name in the message.
        k: the number of rows required (e.g. the descriptor count), or None.
        positive: require ``w > 0`` and ``h > 0`` (else ``w, h >= 0``).
    """
    arr = np.asarray(boxes, dtype=np.float64)
    if arr.size == 0:
        arr = arr.reshape(0, 4)
    if arr.ndim != 2 or arr.shape[1] != 4:
        raise ValueError(f"{name} must have shape (K, 4) as (x, y, w, h), got {arr.shape}")
    check_finite(arr, name)
    if positive:
        bad = np.flatnonzero((arr[:, 2] <= 0) | (arr[:, 3] <= 0))
        if bad.size:
            raise ValueError(f"{name} must have positive width and height; bad rows: {bad[:10]}")
    elif np.any(arr[:, 2:] < 0):
        raise ValueError(f"{name} has negative width or height (expected (x, y, w, h))")
    if k is not None and arr.shape[0] != k:
        raise ValueError(f"{name} has {arr.shape[0]} boxes but the descriptors have {k} rows")
    return arr


def check_image(
    image: Any, name: str = "image", allow_gray: bool = False, min_size: int = 1
) -> np.ndarray:
    """Return ``image`` if it is ``(H, W, 3)`` uint8 RGB (or ``(H, W)`` uint8 with ``allow_gray``).

    Args:
        image: the image.
        name: the argument's name in the message.
        allow_gray: accept a 2-D grayscale image.
        min_size: smallest accepted height and width in pixels.
    """
    what = "(H, W, 3) uint8 RGB" + (" or (H, W) uint8 grayscale" if allow_gray else "")
    if not isinstance(image, np.ndarray):
        raise TypeError(f"{name} must be a numpy array {what}, got {type(image).__name__}")
    if image.dtype != np.uint8:
        raise ValueError(f"{name} must be {what}, got dtype {image.dtype}")
    if not ((image.ndim == 3 and image.shape[2] == 3) or (allow_gray and image.ndim == 2)):
        raise ValueError(f"{name} must have shape {what}, got {image.shape}")
    if image.shape[0] < min_size or image.shape[1] < min_size:
        raise ValueError(
            f"{name} is too small: shape {image.shape}, "
            f"need at least {min_size} x {min_size} pixels"
        )
    return image


def check_image_size(image_size: Any, name: str = "image_size") -> tuple[int, int]:
    """Return ``(H, W)`` as positive ints; a 3-tuple ``image.shape`` is accepted too."""
    if isinstance(image_size, np.ndarray) and image_size.ndim >= 2:
        raise ValueError(
            f"{name} must be (H, W), got an array of shape {image_size.shape}; pass image.shape[:2]"
        )
    try:
        seq = tuple(image_size)
    except TypeError:
        seq = ()
    if len(seq) not in (2, 3):
        raise ValueError(f"{name} must be a (H, W) pair, got {image_size!r}")
    h, w = seq[0], seq[1]
    try:
        hi, wi = int(h), int(w)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must hold integers (H, W), got {image_size!r}") from None
    if hi != h or wi != w or hi <= 0 or wi <= 0:
        raise ValueError(f"{name} must be positive integers (H, W), got {image_size!r}")
    return hi, wi


def check_int(x: Any, name: str = "n", minimum: int = 0) -> int:
    """Return ``x`` as an int ``>= minimum`` (a bool or a fractional number is refused)."""
    try:
        ok = not isinstance(x, bool) and int(x) == x and x >= minimum
    except (TypeError, ValueError, OverflowError):  # OverflowError: int(inf)
        ok = False
    if not ok:
        what = {0: "a non-negative integer", 1: "a positive integer"}.get(
            minimum, f"an integer >= {minimum}"
        )
        raise ValueError(f"{name} must be {what}, got {x!r}")
    return int(x)


def check_range(
    x: Any,
    name: str,
    low: float = -math.inf,
    high: float = math.inf,
    low_open: bool = False,
    high_open: bool = False,
) -> float:
    """Return ``x`` as a float in the interval ``[low, high]`` (``(`` / ``)`` where open)."""
    try:
        v = float(x)
    except (TypeError, ValueError, OverflowError):  # OverflowError: an int beyond float's range
        v = math.nan
    above = v > low if low_open else v >= low
    below = v < high if high_open else v <= high
    if not (above and below):  # NaN fails both
        lo, hi = "(" if low_open else "[", ")" if high_open else "]"
        raise ValueError(f"{name} must be in {lo}{low:g}, {high:g}{hi}, got {x!r}")
    return v


def check_choice(x: Any, name: str, choices: Iterable[Any]) -> Any:
    """Return ``x`` if it is one of ``choices``; the error lists the valid ones."""
    valid = tuple(choices)
    if x not in valid:
        raise ValueError(f"unknown {name} {x!r}; valid: {', '.join(map(str, valid))}")
    return x


def check_finite(x: Any, name: str = "x") -> np.ndarray:
    """Return ``x`` as an array if every entry is finite; else name the first bad row."""
    arr = np.asarray(x)
    finite = np.isfinite(arr)
    if not finite.all():
        row = int(np.argwhere(~finite)[0][0]) if arr.ndim else 0
        raise ValueError(f"{name} contains NaN or inf (first at row {row}); fix or drop that row")
    return arr


def check_options(given: Iterable[str], valid: Iterable[str], what: str) -> None:
    """Refuse an unknown option and one given twice.

    ``given`` lists each option name as the caller received it (a name from two sources, e.g. a
    keyword and a ``--opt`` pair, appears twice); ``what`` names the owner, e.g. ``"encoder"``.
    """
    names, valid = list(given), tuple(valid)
    unknown = sorted({n for n in names if n not in valid})
    if unknown:
        raise ValueError(
            f"unknown {what} option(s) {', '.join(map(repr, unknown))}; valid: {', '.join(valid)}"
        )
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise ValueError(
            f"{what} option(s) {', '.join(map(repr, twice))} given twice; give each once"
        )


def check_descriptors_kept(result: Any, caller: str) -> dict:
    """Return ``result.descriptors`` (a run's landmark descriptors), or say how to keep them."""
    descriptors = getattr(result, "descriptors", None)
    if descriptors is None or not hasattr(result, "boxes"):
        label = getattr(result, "label", None)
        of = f" of {label!r}" if label is not None else ""
        raise ValueError(
            f"{caller} needs the landmark descriptors{of}: run it with "
            "run_method(..., keep_descriptors=True)"
        )
    return descriptors


def is_int(v: Any) -> bool:
    """True for an integral number that is not a bool (a parsed-value predicate, no error)."""
    return isinstance(v, numbers.Integral) and not isinstance(v, bool)


def is_number(v: Any) -> bool:
    """True for a finite real number that is not a bool."""
    return isinstance(v, numbers.Real) and not isinstance(v, bool) and math.isfinite(v)


def check_device(device: Any) -> Any:
    """Return ``device`` as a ``torch.device`` that this machine has (CUDA only when torch sees a
    GPU)."""
    try:
        dev = torch.device(device)
    except (RuntimeError, TypeError):
        raise ValueError(f"device={device!r} is not a torch device; use 'cpu' or 'cuda'") from None
    if dev.type == "cuda" and not torch.cuda.is_available():
        raise ValueError(f"device={device!r} but torch sees no CUDA GPU; use device='cpu'")
    return dev


def check_file(path: Any, what: str) -> bool:
    """True if ``path`` is a regular file (links followed), False if nothing is there (the caller
    says "not found" with its fix); anything else there is refused, named (a folder, a dangling
    symlink, a FIFO, a device ...), never skipped."""
    path = Path(path)
    if path.is_file():
        return True
    if not os.path.lexists(path):
        return False
    try:
        mode = path.stat().st_mode
    except OSError:  # a link to nothing, or a loop
        target = os.readlink(path) if path.is_symlink() else "?"
        kind = f"a symlink that leads to no file ({target})"
    else:
        kind = next((name for test, name in _FILE_KINDS if test(mode)), "something else")
    raise ValueError(
        f"{what} {path} is {kind}, not a regular file; point it at the file itself, or remove it."
    )


_FILE_KINDS = (
    (stat.S_ISDIR, "a folder"),
    (stat.S_ISFIFO, "a FIFO (named pipe)"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)


def is_result(obj: Any) -> bool:
    """``obj`` is a result (``run_method``, ``peer_result``): it has a label, a matrix and a
    ground truth."""
    return all(hasattr(obj, a) for a in ("label", "similarity", "ground_truth"))


def check_results(results: Any, caller: str, unique_labels: bool = False) -> list:
    """``results`` as a non-empty list of results (what ``run_method`` and ``peer_result``
    return: ``.label``, ``.similarity``, ``.ground_truth``), refused naming the fix when it is one
    result, not a sequence, empty, or holds something else; ``unique_labels``: refuse a label
    given twice. ``caller``: the function the message names, e.g. ``"compare"``."""
    if is_result(results):
        raise TypeError(
            f"{caller}(): results is one result ({getattr(results, 'label', '?')!r}), not a list "
            f"of them: pass {caller}([result]) for one, or {caller}([a, b, ...]) for several"
        )
    if isinstance(results, (str, bytes, dict)) or not hasattr(results, "__iter__"):
        raise TypeError(
            f"{caller}(): results must be a list of results (run_method or peer_result), "
            f"got {type(results).__name__}"
        )
    out = list(results)
    if not out:
        raise ValueError(f"{caller}() needs at least one result (run_method or peer_result)")
    bad = [i for i, r in enumerate(out) if not is_result(r)]
    if bad:
        raise TypeError(
            f"{caller}(): results[{bad[0]}] is a {type(out[bad[0]]).__name__}, not a result: "
            "pass what run_method or peer_result return"
        )
    labels = [r.label for r in out]
    dup = sorted({x for x in labels if labels.count(x) > 1})
    if unique_labels and dup:
        raise ValueError(
            f"{caller}(): labels must be unique, repeated: {dup}; pass label=... to "
            "run_method to tell the runs apart"
        )
    return out


#: Bytes the bootstrap keeps per resample: 4 metrics (float64) as values, their concatenation
#: and the percentile's copy (:mod:`~vpr_core.evaluation.bootstrap`; queries go in chunks).
BOOTSTRAP_BYTES_PER_RESAMPLE = 4 * 8 * 3


def check_bootstrap_memory(n: int, name: str = "n_bootstrap") -> None:
    """Refuse ``n`` resamples whose metrics would not fit in half the available memory
    (estimated before any work; numpy failed after minutes). ``name``: the option in the
    message (the CLI's ``--n-bootstrap``)."""
    need = n * BOOTSTRAP_BYTES_PER_RESAMPLE
    avail = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    if need > avail / 2:
        most = int(avail / 2 / BOOTSTRAP_BYTES_PER_RESAMPLE)
        raise ValueError(
            f"{name} {n}: the resampled metrics need about {need / 1e9:.1f} GB of memory "
            f"({BOOTSTRAP_BYTES_PER_RESAMPLE} bytes per resample), more than half of the "
            f"{avail / 1e9:.1f} GB available; use at most {most:,} (1000, the default, gives "
            "95% intervals to about +-0.01)"
        )


def check_per_match(values: np.ndarray, n_matches: int, name: str) -> np.ndarray:
    """Return ``values`` (parsed, one per match, e.g. labels or scores) if it has one entry per
    match of the ``n_matches``; else name both lengths."""
    if len(values) != n_matches:
        raise ValueError(f"{name} ({len(values)}) must have one entry per match ({n_matches})")
    return values
