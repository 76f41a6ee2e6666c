"""Methods as values: ``Method(name, landmarks scheme, Matching)``, the paper's presets as a table,
and the run keys, labels and cache keys derived from a method's value (docs/DEFINITIONS.md)."""

from __future__ import annotations

import dataclasses
from typing import Any

from .checks import check_choice, check_options
from .landmarks.schemes import (
    Dense,
    EdgeBoxesTop,
    MinScale,
    ReduceOverlap,
    ScalePriority,
    WholeImage,
    check_scheme,
    option_text,
)
from .matching import Matching
from .matching.spec import as_matching
from .paper import SOFT_NMS_IOU, SOFT_NMS_SIGMA

__all__ = [
    "METHODS",
    "Matching",
    "Method",
    "as_method",
    "available_methods",
    "get_method",
    "method_label",
    "run_key",
]


@dataclasses.dataclass(frozen=True)
class Method:
    """A method: a name, a landmark scheme (any frozen dataclass with ``boxes(image)``) and the
    :class:`Matching` settings."""

    name: str
    landmarks: Any  # a LandmarkScheme that is a frozen dataclass (checked below)
    matching: Matching = Matching()

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"Method: name must be a non-empty string, got {self.name!r}")
        check_scheme(self.landmarks)
        # Matching's one rule (None: the paper's Eq. (1)); no soft-NMS given beside it
        object.__setattr__(self, "matching", as_matching(None, SOFT_NMS_SIGMA, self.matching))


#: The paper's methods (Sec. 2.1, Algorithms 1-4, Sec. 4) and ``global`` (not in the paper: one
#: whole-image descriptor from the same backbone, so a reader sees what landmarks add).
METHODS: dict[str, Method] = {
    m.name: m
    for m in (
        Method("classical", EdgeBoxesTop()),
        Method("selection_scheme1", MinScale()),
        Method("selection_scheme2", ScalePriority()),
        Method("overlap_scheme1", ReduceOverlap()),
        Method("overlap_scheme2", EdgeBoxesTop(), Matching(soft_nms_iou=SOFT_NMS_IOU)),
        Method("dense", Dense()),
        Method("global", WholeImage()),
    )
}


def _fields(obj: Any) -> tuple[str, ...]:
    return tuple(f.name for f in dataclasses.fields(obj))


def available_methods() -> list[str]:
    """Names of the method presets."""
    return sorted(METHODS)


def _method_options(method: Method) -> tuple[str, ...]:
    """The options a method takes as keywords: its scheme's fields, then its matching options."""
    return _fields(method.landmarks) + method.matching.options()


def get_method(name: str, **overrides: Any) -> Method:
    """A preset with its own options changed, e.g. ``get_method("dense", per_scale=49)``.

    Args:
        name: one of :func:`available_methods`.
        **overrides: the method's options (:func:`_method_options`); ``None`` means "not set"
            (except ``soft_nms_iou``, where it turns Algorithm 4 off).

    Raises:
        ValueError: unknown method, an option the method does not take (the message lists the
            valid ones) or an option value of the wrong type or range.
    """
    preset = METHODS[check_choice(name, "method", available_methods())]
    check_options(overrides, _method_options(preset), f"method {name!r}")
    given = {k: v for k, v in overrides.items() if v is not None or k == "soft_nms_iou"}
    scheme = {k: v for k, v in given.items() if k in _fields(preset.landmarks)}
    matching = {k: v for k, v in given.items() if k not in scheme}
    try:
        return dataclasses.replace(
            preset,
            landmarks=dataclasses.replace(preset.landmarks, **scheme),
            matching=dataclasses.replace(preset.matching, **matching),
        )
    except ValueError as exc:
        raise ValueError(f"method {name!r}: {exc}") from None


def as_method(method: Any, **overrides: Any) -> Method:
    """A preset name (with its options), a :class:`Method` or a bare scheme, as a Method.

    A bare scheme is named after the preset with that scheme class and plain matching
    (``Dense(...)`` -> ``dense``), else after its class (``MyGrid(...)`` -> ``MyGrid``).

    Raises:
        ValueError: options given with a Method or a scheme (set them on the value instead).
        TypeError: not a name, a Method or a frozen dataclass with ``boxes(image)``.
    """
    if isinstance(method, str):
        return get_method(method, **overrides)
    if overrides and set(overrides) <= {"spatial", "weighting", "normalise", "whiten"}:  # matching
        base = as_method(method)  # of every method, schemes included
        return dataclasses.replace(base, matching=dataclasses.replace(base.matching, **overrides))
    if overrides:
        raise ValueError(
            f"options {sorted(overrides)} apply to a preset name only; set them on the value "
            f"instead, e.g. dataclasses.replace(scheme, {next(iter(overrides))}=...)"
        )
    if isinstance(method, Method):
        return method
    check_scheme(method)
    name = next(
        (
            m.name
            for m in METHODS.values()
            if type(m.landmarks) is type(method) and m.matching == Matching()
        ),
        type(method).__name__,
    )
    return Method(name, method)


def _default(field: dataclasses.Field) -> Any:
    if field.default is not dataclasses.MISSING:
        return field.default
    if field.default_factory is not dataclasses.MISSING:
        return field.default_factory()
    return dataclasses.MISSING


def _options(method: Method) -> dict[str, Any]:
    """The options that differ from the preset of the same name (from the class defaults when
    there is none), flat and sorted: what the run key and the label show."""
    preset = METHODS.get(method.name)
    out = {}
    for part in (method.landmarks, method.matching):
        base = None if preset is None else getattr(preset, _part_name(part))
        same_type = base is not None and type(base) is type(part)
        for f in dataclasses.fields(part):
            value = getattr(part, f.name)
            default = getattr(base, f.name) if same_type else _default(f)
            if value != default:
                out[f.name] = value
    return dict(sorted(out.items()))


def _part_name(part: Any) -> str:
    return "matching" if isinstance(part, Matching) else "landmarks"


def run_key(method: Method) -> str:
    """The identity of a run's configuration: the name and every option that differs from the
    preset, e.g. ``"overlap_scheme1(iou_threshold=0.4)"``, ``"dense(per_scale=49,
    scales=0.25/0.49)"``; just ``"classical"`` at the defaults. Findings match on it."""
    inner = ", ".join(f"{k}={option_text(v)}" for k, v in _options(method).items())
    return f"{method.name}({inner})" if inner else method.name


def method_label(method: Method) -> str:
    """The legend of a method: its name, then what its scheme and matching say of themselves
    (their ``note()``; else the options that differ, as in :func:`run_key`), e.g.
    ``"overlap_scheme1 (IoU 0.4)"``, ``"dense (0.25/0.49 x 49)"``, ``"MyGrid (g=3)"``."""
    opts = _options(method)
    notes = []
    for part in (method.landmarks, method.matching):
        note = getattr(part, "note", None)
        if callable(note):
            notes.append(note())
        else:
            notes.append(
                ", ".join(f"{k}={option_text(opts[k])}" for k in _fields(part) if k in opts)
            )
    text = "; ".join(n for n in notes if n)
    return f"{method.name} ({text})" if text else method.name
