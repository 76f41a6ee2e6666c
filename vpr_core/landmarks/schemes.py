"""Landmark schemes as values: one frozen dataclass per scheme, checked once when it is made; any
frozen dataclass with ``boxes(self, image) -> (K, 4)`` is a scheme (docs/DEFINITIONS.md)."""

from __future__ import annotations

import dataclasses
import math
import numbers
from typing import Any, Protocol, runtime_checkable

import numpy as np

from ..boxes import box_iou_parsed
from ..checks import check_int, is_int, is_number
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
from .edge_boxes import edge_boxes
from .scales import scale_index_parsed

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
]


@runtime_checkable
class LandmarkScheme(Protocol):
    """What a landmark scheme is: ``boxes(image (H, W, 3) uint8) -> (K, 4) (x, y, w, h)``."""

    def boxes(self, image: np.ndarray) -> np.ndarray: ...


class CandidateScheme:
    """Base of the schemes that choose among an image's ``n_candidates`` Edge Box proposals.

    The pipeline computes (and caches) the proposals once per image and calls :meth:`select`,
    so every such scheme shares them; a subclass defines ``n_candidates`` and :meth:`indices`
    (or :meth:`select`).
    """

    n_candidates: int

    def indices(self, candidates: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
        """``(N,)`` int64 indices of the kept ``candidates`` (float64 ``(M, 4)``, proposal order)
        of an ``(H, W)`` image; both come parsed (the pipeline's, or a public function's)."""
        raise NotImplementedError

    def select(self, candidates: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
        """The landmarks kept from ``candidates (M, 4)`` (proposal order) of an ``(H, W)`` image."""
        return candidates[self.indices(candidates, image_size)]

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


def _is_sequence(v: Any) -> bool:
    return isinstance(v, (list, tuple)) and len(v) > 0


def _bad(obj: object, key: str, expected: str) -> ValueError:
    """The one wording of a scheme option's refusal: names the class, the option and the fix."""
    return ValueError(f"{type(obj).__name__}.{key} must be {expected}, got {getattr(obj, key)!r}")


def _set(obj: object, key: str, value: Any) -> None:
    object.__setattr__(obj, key, value)  # frozen dataclass: store the parsed value


def _count(obj: object, key: str) -> None:
    _set(obj, key, check_int(getattr(obj, key), f"{type(obj).__name__}.{key}", 1))


def _is_scale_index(v: Any) -> bool:
    return is_int(v) and 1 <= v <= N_SCALES


def _fraction(obj: object, key: str) -> None:
    value = getattr(obj, key)
    if not (is_number(value) and 0 <= value <= 1):
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

    def indices(self, candidates: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
        """The first ``n`` candidates."""
        return np.arange(min(self.n, len(candidates)), dtype=np.int64)


@dataclasses.dataclass(frozen=True)
class MinScale(CandidateScheme):
    """Algorithm 1 (selection Scheme 1): the first ``n`` candidates of scale >= ``min_index``."""

    n: int = N_LANDMARKS
    min_index: int = MIN_SCALE_INDEX
    n_candidates: int = N_CANDIDATES

    def __post_init__(self) -> None:
        _count(self, "n")
        _count(self, "n_candidates")
        if not _is_scale_index(self.min_index):
            raise _bad(self, "min_index", f"a Table-1 scale index 1..{N_SCALES} (e.g. 4)")
        _set(self, "min_index", int(self.min_index))

    def indices(self, candidates: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
        """Algorithm 1: the first ``n`` candidates whose Table-1 scale index is >= ``min_index``."""
        scale = scale_index_parsed(candidates, image_size)
        return np.flatnonzero(scale >= self.min_index)[: self.n].astype(np.int64)


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
            or not all(map(_is_scale_index, order))
            or len(set(order)) != len(order)
        ):
            raise _bad(
                self,
                "order",
                "a non-empty sequence of distinct Table-1 scale indices 1..9 "
                "(e.g. (5, 6, 7, 8, 9, 4))",
            )
        _set(self, "order", tuple(int(v) for v in order))

    def indices(self, candidates: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
        """Algorithm 2: all candidates of scale ``order[0]``, then all of ``order[1]``, ...,
        until ``n`` are kept; scales absent from ``order`` never are."""
        scale = scale_index_parsed(candidates, image_size)
        picked: list[np.ndarray] = []
        total = 0
        for s in self.order:
            if total >= self.n:
                break
            cand = np.flatnonzero(scale == s)[: self.n - total]
            picked.append(cand)
            total += cand.size
        return np.concatenate(picked).astype(np.int64)


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

    def indices(
        self, candidates: np.ndarray, image_size: tuple[int, int] | None = None
    ) -> np.ndarray:
        """Algorithm 3: the first candidate is kept, then each one whose IoU with every kept box
        is ``<= iou_threshold``, until ``n`` are kept. Each kept box's IoU with the later
        candidates is folded into a running maximum: a candidate's test is one compare."""
        b, t = candidates, self.iou_threshold
        kept: list[int] = []
        max_iou = np.zeros(b.shape[0], dtype=np.float64)  # max IoU with the boxes kept so far
        for i in range(b.shape[0]):
            if len(kept) >= self.n:
                break
            if i == 0 or max_iou[i] <= t:
                kept.append(i)
                np.maximum(
                    max_iou[i + 1 :],
                    box_iou_parsed(b[i : i + 1], b[i + 1 :])[0],
                    out=max_iou[i + 1 :],
                )
        return np.asarray(kept, dtype=np.int64)

    def note(self) -> str:
        """Its legend text: the IoU threshold."""
        return f"IoU {self.iou_threshold:g}"


@dataclasses.dataclass(frozen=True)
class Dense(SizeScheme):
    """Sec. 4: ``per_scale`` boxes on a grid at each normalised scale (area ratio) of ``scales``
    (docs/DEFINITIONS.md).

    ``per_scale`` is a perfect square, or one per scale (Table 3).
    """

    scales: tuple[float, ...] = DENSE_SCALES
    per_scale: int | tuple[int, ...] = DENSE_PER_SCALE

    def __post_init__(self) -> None:
        scales = self.scales
        if not (
            isinstance(scales, (list, tuple))
            and scales
            and all(is_number(s) and 0 < s <= 1 for s in scales)
        ):
            raise _bad(
                self,
                "scales",
                "a non-empty sequence of normalised scales (area ratios) in (0, 1], "
                "e.g. (0.16, 0.25)",
            )
        _set(self, "scales", tuple(float(s) for s in scales))
        counts: Any = self.per_scale
        many = isinstance(counts, (list, tuple))
        each = [check_int(c, "Dense.per_scale", 1) for c in (counts if many else (counts,))]
        if many and len(each) != len(scales):
            raise _bad(self, "per_scale", f"one count per scale ({len(scales)}) or one int")
        if any(math.isqrt(c) ** 2 != c for c in each):
            raise _bad(self, "per_scale", "perfect squares (a g x g grid: 9, 16, 25, 36, 49)")
        _set(self, "per_scale", tuple(each) if many else each[0])

    def for_size(self, image_size: tuple[int, int]) -> np.ndarray:
        """The dense grid of an ``(H, W)`` image: ``(sum(per_scale), 4)`` boxes, scale by
        scale, row by row, by increasing ``x`` (:func:`~vpr_core.landmarks.dense_sampling`)."""
        H, W = image_size
        counts = self.per_scale
        each = counts if isinstance(counts, tuple) else (counts,) * len(self.scales)
        blocks = [
            _grid_boxes(a, math.isqrt(c), H, W) for a, c in zip(self.scales, each, strict=True)
        ]
        return np.concatenate(blocks, axis=0)

    def note(self) -> str:
        """Its legend text: ``"0.25/0.49 x 49"``, empty at the paper's setting."""
        if self == Dense():
            return ""
        return f"{option_text(self.scales)} x {option_text(self.per_scale)}"


def _grid_boxes(area_ratio: float, g: int, H: int, W: int) -> np.ndarray:
    """``(g*g, 4)`` boxes of one scale on a ``g x g`` grid, row by row."""
    s = math.sqrt(float(area_ratio))
    w, h = s * W, s * H
    if g == 1:
        xs = np.array([(W - w) / 2.0])
        ys = np.array([(H - h) / 2.0])
    else:
        xs = np.arange(g) * ((W - w) / (g - 1))
        ys = np.arange(g) * ((H - h) / (g - 1))
    yy, xx = np.meshgrid(ys, xs, indexing="ij")  # row-major: y outer, x inner
    return np.stack([xx.ravel(), yy.ravel(), np.full(g * g, w), np.full(g * g, h)], axis=1)


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


def _scheme_version(scheme: Any) -> str | None:
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
        "version": ...}`` (JSON-able; ``version`` None: not stored).
    """
    cls = type(check_scheme(scheme))
    return {
        "scheme": f"{cls.__module__}.{cls.__qualname__}",
        "params": dataclasses.asdict(scheme),
        "version": _scheme_version(scheme),
    }
