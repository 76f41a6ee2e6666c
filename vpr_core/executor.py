"""Work done outside the process, verified before anything keeps it: an ``executor=`` value
(:class:`vpr_core.run.Executor`) and every matrix, pair vector, descriptor list and timing it
returns (shape, dtype, finite, width, a seeded sample recomputed in-process)."""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable, Sequence
from typing import Any, NoReturn

import numpy as np

from .matching import Matching, similarity_pairs

#: What an executor is given to score: query descriptors, boxes, reference descriptors, boxes.
Sides = tuple[Sequence, Sequence, Sequence, Sequence]

__all__ = [
    "EXECUTOR_METHODS",
    "RTOL",
    "SPOT_CHECK",
    "check_executor",
    "checked_encoding",
    "checked_matrix",
    "checked_pairs",
]

#: What ``run_method(..., executor=)`` calls on the value (:class:`vpr_core.run.Executor`).
EXECUTOR_METHODS = ("encode", "similarity_matrix", "similarity_pairs")
#: Pairs (and per side: images x boxes) recomputed in-process per executor call: a few, so
#: the check costs a few percent of the work sent out (``two_sided`` also computes its
#: reference statistics here once per database, as an in-process run does).
SPOT_CHECK = {"pairs": 8, "images": 2, "boxes": 4}
#: Largest difference between the executor's values and the in-process ones, relative to the
#: largest in-process value: Eq. (1) sums in float64 (the block engine agrees with the one-pair
#: reference to ~1e-6), descriptors are float32 network outputs (other kernels, other devices).
RTOL = {"matrix": 1e-5, "descriptors": 1e-4}
_FIX = (
    "it must return what its in-process counterpart returns (vpr_core.run.Executor); fix the "
    "executor, or pass executor=None to run in-process; what it returned was not cached"
)


def _name(executor: Any) -> str:
    text = repr(executor)
    return f"executor={text[:77] + '...' if len(text) > 80 else text}"


def _refuse(executor: Any, what: str) -> NoReturn:
    raise ValueError(f"{_name(executor)}: {what}; {_FIX}.")


def check_executor(executor: Any) -> Any:
    """``executor`` when it has callable :data:`EXECUTOR_METHODS`, else one sentence naming it
    and the fix (before any work is done)."""
    missing = [m for m in EXECUTOR_METHODS if not callable(getattr(executor, m, None))]
    if missing:
        raise ValueError(
            f"{_name(executor)} is a {type(executor).__name__} without callable "
            f"{', '.join(missing)}: an executor has the methods {', '.join(EXECUTOR_METHODS)} "
            "(vpr_core.run.Executor; e.g. vpr_study.DaskExecutor(address)); pass one, or "
            "executor=None to run in-process"
        )
    return executor


def _array(executor: Any, value: Any, what: str, shape: tuple[int, ...]) -> np.ndarray:
    """``value`` as a float64 array of ``shape``: a numpy array of real floats, finite."""
    if not isinstance(value, np.ndarray):
        _refuse(executor, f"{what} is a {type(value).__name__}, not a numpy array")
    if value.shape != shape:
        _refuse(executor, f"{what} has shape {value.shape}, expected {shape}")
    if not np.issubdtype(value.dtype, np.floating):
        _refuse(executor, f"{what} has dtype {value.dtype}, expected real floats")
    if not np.isfinite(value).all():
        _refuse(executor, f"{what} holds NaN or inf (the in-process values are finite)")
    return value


def _spot_check(
    executor: Any, what: str, got: np.ndarray, want: np.ndarray, rtol: float, where: list[str]
) -> None:
    """Refuse ``got`` unless it equals the in-process ``want`` to ``rtol`` of ``want``'s scale."""
    scale = max(float(np.abs(want).max(initial=0.0)), 1e-12)
    err = np.abs(got.astype(np.float64) - want.astype(np.float64))
    if err.size and float(err.max()) > rtol * scale:
        k = int(np.argmax(err.max(axis=tuple(range(1, err.ndim))) if err.ndim > 1 else err))
        _refuse(
            executor,
            f"{what} differs from the same values recomputed in-process at {where[k]} "
            f"(by {float(err.max()):.3g}, more than {rtol:g} of {scale:.3g}: another dataset, "
            "order, sign or computation)",
        )


def _sample(n: int, size: int, seed: int = 0) -> np.ndarray:
    """Up to ``size`` sorted distinct indices of ``range(n)`` (seeded)."""
    if n <= size:
        return np.arange(n)
    return np.sort(np.random.default_rng(seed).choice(n, size, replace=False))


def checked_matrix(executor: Any, sim: Any, sides: Sides, matching: Matching) -> np.ndarray:
    """An executor's ``(Nq, Nr)`` Eq. (1) matrix of ``sides`` (query descriptors and boxes,
    reference descriptors and boxes, as it was given them) under ``matching``, checked: a finite
    real-float numpy array of that shape, whose entries at a seeded sample of
    :data:`SPOT_CHECK` pairs equal the in-process values (a weighting's statistics over every
    reference, as in a matrix). Returns float64."""
    shape = (len(sides[0]), len(sides[2]))
    sim = _array(executor, sim, "its similarity matrix", shape)
    flat = _sample(shape[0] * shape[1], SPOT_CHECK["pairs"])
    pairs = np.stack(np.unravel_index(flat, shape), axis=1).astype(np.int64)
    if len(pairs):
        every = np.arange(shape[1])
        want = similarity_pairs(*sides, pairs, matching, sample=every)
        where = [f"pair (query {q}, reference {r})" for q, r in pairs]
        got = sim[pairs[:, 0], pairs[:, 1]]
        _spot_check(executor, "its similarity matrix", got, want, RTOL["matrix"], where)
    return sim.astype(np.float64, copy=False)


def checked_pairs(
    executor: Any, vals: Any, sides: Sides, pairs: np.ndarray, matching: Matching
) -> np.ndarray:
    """An executor's ``(P,)`` Eq. (1) values of ``pairs`` ``(P, 2)``, checked as
    :func:`checked_matrix` (a weighting's statistics over its default sample, as in-process)."""
    vals = _array(executor, vals, "its similarity of listed pairs", (len(pairs),))
    rows = _sample(len(pairs), SPOT_CHECK["pairs"])
    if len(rows):
        want = similarity_pairs(*sides, pairs[rows], matching)
        where = [f"pair (query {pairs[i, 0]}, reference {pairs[i, 1]})" for i in rows]
        _spot_check(
            executor, "its similarity of listed pairs", vals[rows], want, RTOL["matrix"], where
        )
    return vals.astype(np.float64, copy=False)


def _seconds(executor: Any, secs: Any, indices: Sequence[int], side: str) -> list[float]:
    """``secs`` as one finite non-negative float per image of ``indices`` (they enter the
    stores' cost column, then the cost tables)."""
    if isinstance(secs, (str, bytes)) or not isinstance(secs, Sequence | np.ndarray):
        _refuse(executor, f"encode's seconds for {side} are a {type(secs).__name__}, not a list")
    if len(secs) != len(indices):
        _refuse(executor, f"encode gave {len(secs)} timings for {len(indices)} {side} images")
    out = []
    for i, s in zip(indices, secs, strict=True):
        real = isinstance(s, numbers.Real) and not isinstance(s, bool)
        if not (real and math.isfinite(float(s)) and float(s) >= 0):
            _refuse(
                executor,
                f"encode's seconds for {side} image {i} are {s!r}, not a finite number >= 0 "
                "(a negative or missing timing never enters a cost table)",
            )
        out.append(float(s))
    return out


def checked_encoding(
    executor: Any,
    returned: Any,
    side: str,
    indices: Sequence[int],
    boxes: Sequence[np.ndarray],
    dim: int,
    recompute: Callable[[int, np.ndarray], np.ndarray],
) -> tuple[list[np.ndarray], list[float]]:
    """What an executor's ``encode`` returned for images ``indices`` of ``side`` and their
    ``boxes`` ``[(K_i, 4)]``, checked: ``(descriptors, seconds)``, one ``(K_i, dim)`` finite
    real-float numpy array and one finite number >= 0 per image, and the descriptors of a
    seeded sample of :data:`SPOT_CHECK` images x boxes equal to ``recompute(image, boxes)``
    (the in-process encoder). Returns float32 descriptors and float seconds."""
    if not isinstance(returned, tuple | list) or len(returned) != 2:
        _refuse(
            executor, f"encode returned a {type(returned).__name__}, not (descriptors, seconds)"
        )
    descs, secs = returned
    if isinstance(descs, (str, bytes, np.ndarray)) or not isinstance(descs, Sequence):
        _refuse(executor, f"encode's descriptors are a {type(descs).__name__}, not a list")
    if len(descs) != len(indices):
        _refuse(
            executor, f"encode gave descriptors of {len(descs)} {side} images, asked {len(indices)}"
        )
    out = [
        _array(executor, d, f"the descriptors of {side} image {i}", (len(b), dim)).astype(
            np.float32, copy=False
        )
        for i, d, b in zip(indices, descs, boxes, strict=True)
    ]
    seconds = _seconds(executor, secs, indices, side)
    for k in _sample(len(indices), SPOT_CHECK["images"]):
        rows = _sample(len(boxes[k]), SPOT_CHECK["boxes"], seed=int(indices[k]))
        if len(rows):
            want = recompute(int(indices[k]), np.asarray(boxes[k])[rows])
            where = [f"{side} image {indices[k]}, box {r}" for r in rows]
            what = f"the descriptors of {side} image {indices[k]}"
            _spot_check(executor, what, out[k][rows], want, RTOL["descriptors"], where)
    return out, seconds
