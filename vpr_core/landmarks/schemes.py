"""Landmark schemes as values: one frozen dataclass per scheme, checked once when it is made; any
frozen dataclass with ``boxes(self, image) -> (K, 4)`` is a scheme (docs/DEFINITIONS.md)."""

from __future__ import annotations

import dataclasses
import math
import numbers
from typing import Any, Protocol, cast, runtime_checkable

import numpy as np

from ..paper import (
    DENSE_PER_SCALE,
    DENSE_SCALES,
    MIN_SCALE_INDEX,
    N_CANDIDATES,
    N_LANDMARKS,
    N_SCALES,
    NMS_IOU,
    SCALE_PRIORITY_ORDER,
)
from ..utils import code_version
from .dense import dense_sampling
from .edge_boxes import edge_boxes
from .selection import reduce_overlap, select_min_scale, select_scale_priority

__all__ = [
    "CandidateScheme",
    "Dense",
    "EdgeBoxesTop",
    "LandmarkScheme",
    "MinScale",
    "ReduceOverlap",
    "ScalePriority",
    "SizeScheme",
    "WholeImage",
    "check_scheme",
    "option_text",
    "scheme_identity",
    "scheme_version",
]


@runtime_checkable
class LandmarkScheme(Protocol):
    """What a landmark scheme is: ``boxes(image (H, W, 3) uint8) -> (K, 4) (x, y, w, h)``."""

    def boxes(self, image: np.ndarray) -> np.ndarray: ...


class CandidateScheme:
    """Base of the schemes that choose among an image's ``n_candidates`` Edge Box proposals.

    The pipeline computes (and caches) the proposals once per image and calls :meth:`select`,
    so every such scheme shares them; a subclass defines ``n_candidates`` and ``select``.
    """

    n_candidates: int

    def select(self, candidates: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
        """The landmarks kept from ``candidates (M, 4)`` (proposal order) of an ``(H, W)`` image."""
        raise NotImplementedError

    def boxes(self, image: np.ndarray) -> np.ndarray:
        """The landmarks of one image: its Edge Box proposals, then :meth:`select`."""
        candidates = edge_boxes(image, max_boxes=self.n_candidates).boxes
        return self.select(candidates, image.shape[:2])


class SizeScheme:
    """Base of the schemes whose boxes depend on the image size only (the pixels are not read)."""

    def for_size(self, image_size: tuple[int, int]) -> np.ndarray:
        """The landmarks of an ``(H, W)`` image."""
        raise NotImplementedError

    def boxes(self, image: np.ndarray) -> np.ndarray:
        """The landmarks of one image (:meth:`for_size` of its size)."""
        return self.for_size(image.shape[:2])


# ---------------------------------------------------------------------------------------------
# parameter checks: each scheme parses its options once, in __post_init__
# ---------------------------------------------------------------------------------------------


def _is_int(v: Any) -> bool:
    return isinstance(v, numbers.Integral) and not isinstance(v, bool)


def _is_number(v: Any) -> bool:
    return isinstance(v, numbers.Real) and not isinstance(v, bool) and math.isfinite(v)


def _is_sequence(v: Any) -> bool:
    return isinstance(v, (list, tuple)) and len(v) > 0


def _bad(obj: object, key: str, expected: str) -> ValueError:
    value = getattr(obj, key)
    return ValueError(
        f"{type(obj).__name__}: option {key}={value!r} is not valid; expected {expected}"
    )


def _set(obj: object, key: str, value: Any) -> None:
    object.__setattr__(obj, key, value)  # frozen dataclass: store the parsed value


def _count(obj: object, key: str) -> None:
    value = getattr(obj, key)
    if not (_is_int(value) and value >= 1):
        raise _bad(obj, key, "a positive integer (at least 1)")
    _set(obj, key, int(value))


def _fraction(obj: object, key: str) -> None:
    value = getattr(obj, key)
    if not (_is_number(value) and 0 <= value <= 1):
        raise _bad(obj, key, "a number in [0, 1]")
    _set(obj, key, float(value))


# ---------------------------------------------------------------------------------------------
# the paper's schemes
# ---------------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class EdgeBoxesTop(CandidateScheme):
    """The first ``n`` of ``n_candidates`` Edge Box proposals (Sec. 2.1, the classical method)."""

    n: int = N_LANDMARKS
    n_candidates: int = N_CANDIDATES

    def __post_init__(self) -> None:
        _count(self, "n")
        _count(self, "n_candidates")

    def select(self, candidates: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
        """The first ``n`` candidates."""
        return np.array(candidates[: self.n], dtype=np.float64)


@dataclasses.dataclass(frozen=True)
class MinScale(CandidateScheme):
    """Algorithm 1 (selection Scheme 1): the first ``n`` candidates of scale >= ``min_index``."""

    n: int = N_LANDMARKS
    min_index: int = MIN_SCALE_INDEX
    n_candidates: int = N_CANDIDATES

    def __post_init__(self) -> None:
        _count(self, "n")
        _count(self, "n_candidates")
        if not (_is_int(self.min_index) and 1 <= self.min_index <= N_SCALES):
            raise _bad(self, "min_index", f"a Table-1 scale index 1..{N_SCALES}, e.g. 4")
        _set(self, "min_index", int(self.min_index))

    def select(self, candidates: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
        """Algorithm 1 on ``candidates``."""
        return cast(
            np.ndarray, select_min_scale(candidates, image_size, n=self.n, min_index=self.min_index)
        )


@dataclasses.dataclass(frozen=True)
class ScalePriority(CandidateScheme):
    """Algorithm 2 (selection Scheme 2): candidates taken scale by scale in ``order``."""

    n: int = N_LANDMARKS
    order: tuple[int, ...] = SCALE_PRIORITY_ORDER
    n_candidates: int = N_CANDIDATES

    def __post_init__(self) -> None:
        _count(self, "n")
        _count(self, "n_candidates")
        order = self.order
        if (
            not _is_sequence(order)
            or not all(_is_int(v) and 1 <= v <= N_SCALES for v in order)
            or len(set(order)) != len(order)
        ):
            raise _bad(
                self,
                "order",
                "a non-empty sequence of distinct Table-1 scale indices 1..9, "
                "e.g. (5, 6, 7, 8, 9, 4)",
            )
        _set(self, "order", tuple(int(v) for v in order))

    def select(self, candidates: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
        """Algorithm 2 on ``candidates``."""
        return cast(
            np.ndarray, select_scale_priority(candidates, image_size, n=self.n, order=self.order)
        )


@dataclasses.dataclass(frozen=True)
class ReduceOverlap(CandidateScheme):
    """Algorithm 3 (overlap reduction Scheme 1): greedy IoU filtering of the candidates."""

    n: int = N_LANDMARKS
    iou_threshold: float = NMS_IOU
    n_candidates: int = N_CANDIDATES

    def __post_init__(self) -> None:
        _count(self, "n")
        _count(self, "n_candidates")
        _fraction(self, "iou_threshold")

    def select(self, candidates: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
        """Algorithm 3 on ``candidates``."""
        return cast(
            np.ndarray, reduce_overlap(candidates, n=self.n, iou_threshold=self.iou_threshold)
        )

    def note(self) -> str:
        """Its legend text: the IoU threshold."""
        return f"IoU {self.iou_threshold:g}"


@dataclasses.dataclass(frozen=True)
class Dense(SizeScheme):
    """Sec. 4: ``per_scale`` boxes on a grid at each normalised scale (area ratio) of ``scales``.

    ``per_scale`` is a perfect square, or one per scale (Table 3).
    """

    scales: tuple[float, ...] = DENSE_SCALES
    per_scale: int | tuple[int, ...] = DENSE_PER_SCALE

    def __post_init__(self) -> None:
        scales = self.scales
        if isinstance(scales, (str, bytes)) or not isinstance(scales, (list, tuple)):
            raise _bad(
                self, "scales", "a sequence of normalised scales in (0, 1], e.g. (0.16, 0.25)"
            )
        if not scales or not all(_is_number(s) and 0 < s <= 1 for s in scales):
            raise _bad(self, "scales", "a non-empty sequence of numbers in (0, 1]")
        _set(self, "scales", tuple(float(s) for s in scales))
        counts: Any = self.per_scale
        if _is_int(counts) and counts > 0:
            _set(self, "per_scale", int(counts))
        elif _is_sequence(counts) and all(_is_int(v) and v > 0 for v in counts):
            if len(counts) != len(scales):
                raise _bad(self, "per_scale", f"one count per scale ({len(scales)}) or one int")
            _set(self, "per_scale", tuple(int(v) for v in counts))
        else:
            raise _bad(self, "per_scale", "a positive integer (a square, e.g. 25) or one per scale")
        each = counts if isinstance(counts, (list, tuple)) else (counts,)
        if any(math.isqrt(int(c)) ** 2 != c for c in each):
            raise _bad(self, "per_scale", "perfect squares (a g x g grid: 9, 16, 25, 36, 49)")

    def for_size(self, image_size: tuple[int, int]) -> np.ndarray:
        """The dense grid of an ``(H, W)`` image (:func:`~vpr_core.landmarks.dense_sampling`)."""
        return dense_sampling(image_size, scales=self.scales, per_scale=self.per_scale)

    def note(self) -> str:
        """Its legend text: ``"0.25/0.49 x 49"``, empty at the paper's setting."""
        if self == Dense():
            return ""
        return f"{option_text(self.scales)} x {option_text(self.per_scale)}"


@dataclasses.dataclass(frozen=True)
class WholeImage(SizeScheme):
    """One box covering the image (not in the paper: a whole-image descriptor)."""

    def for_size(self, image_size: tuple[int, int]) -> np.ndarray:
        """``[[0, 0, W, H]]``."""
        h, w = image_size
        return np.array([[0.0, 0.0, float(w), float(h)]])


# ---------------------------------------------------------------------------------------------
# identity of any scheme (the paper's or a user's): caches and run keys derive from it
# ---------------------------------------------------------------------------------------------


def option_text(value: Any) -> str:
    """An option's value as a slug fragment: ``0.25/0.49``, ``49``."""
    if isinstance(value, tuple):
        return "/".join(option_text(v) for v in value)
    return f"{value:g}" if isinstance(value, float) else str(value)


def check_scheme(scheme: Any) -> Any:
    """Return ``scheme`` if it is a frozen dataclass with a ``boxes(image)`` method.

    Raises:
        TypeError: anything else (the message says what a scheme is), a field that is not a
            plain value, a ``version`` that is not a non-empty string.
    """
    params = getattr(type(scheme), "__dataclass_params__", None)
    if (
        isinstance(scheme, type)
        or params is None
        or not params.frozen
        or not callable(getattr(scheme, "boxes", None))
    ):
        raise TypeError(
            f"a landmark scheme must be a frozen dataclass (@dataclass(frozen=True)) with a "
            f"method boxes(self, image) -> (K, 4) array; got {scheme!r}"
        )
    for f in dataclasses.fields(scheme):
        if not _plain(getattr(scheme, f.name)):
            raise TypeError(
                f"{type(scheme).__name__}: field {f.name} holds a "
                f"{type(getattr(scheme, f.name)).__name__}; a scheme's fields must be plain "
                "values (numbers, strings, None, tuples of them: they name the run and key its "
                "caches), e.g. a tuple instead of an array"
            )
    version = getattr(scheme, "version", None)
    if version is not None and not (isinstance(version, str) and version):
        raise TypeError(
            f"{type(scheme).__name__}.version must be a non-empty string, got {version!r}"
        )
    return scheme


def _plain(value: Any) -> bool:
    if isinstance(value, tuple):
        return all(map(_plain, value))
    return value is None or isinstance(value, (str, bool, numbers.Number))


def scheme_version(scheme: Any) -> str | None:
    """The version a scheme's stored boxes are keyed by, or None: not stored.

    The package's schemes: the landmark code's version
    (:func:`~vpr_core.utils.code_version`). A user's scheme class: its declared ``version``
    (a class attribute ``version: ClassVar[str] = "1"``, the user's promise that the same
    version and fields give the same boxes); without one its boxes are recomputed on every run
    (they are cheap; features stay cached by box content), since code the package does not own
    may read globals or helpers that changed.
    """
    cls = type(check_scheme(scheme))
    if cls.__module__.startswith("vpr_core."):
        return code_version("landmarks")
    version = getattr(scheme, "version", None)
    return None if version is None else f"user {version}"


def scheme_identity(scheme: Any) -> dict[str, Any]:
    """What a scheme's stored boxes are keyed by: class, field values and version.

    Returns:
        ``{"scheme": "<module>.<qualified name>", "params": dataclasses.asdict(scheme),
        "version": scheme_version(scheme)}`` (JSON-able; ``version`` None: not stored).
    """
    cls = type(check_scheme(scheme))
    return {
        "scheme": f"{cls.__module__}.{cls.__qualname__}",
        "params": dataclasses.asdict(scheme),
        "version": scheme_version(scheme),
    }
