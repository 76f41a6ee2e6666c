"""Methods as values: ``Method(name, landmarks scheme, Matching)``, the paper's presets as a table,
and the run keys, labels and cache keys derived from a method's value (docs/DEFINITIONS.md)."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
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
    "STEP_FIELDS",
    "Matching",
    "Method",
    "as_method",
    "available_methods",
    "default_label",
    "get_method",
    "method_label",
    "run_identity",
    "run_key",
    "step_between",
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

    @property
    def key(self) -> str:
        """Its configuration's identity (:func:`run_key`), as tables and the findings name it."""
        return run_key(self)


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


#: (Not in the paper.) The :class:`Matching` fields that are steps on Eq. (1): what
#: :func:`step_between` credits a difference to (docs/DEFINITIONS.md).
STEP_FIELDS = ("whiten", "weighting", "normalise")


def run_identity(run: Any) -> dict[str, Any]:
    """What a ``run_method`` result's numbers come from, part by part (what :func:`step_between`
    compares): ``dataset`` (its fingerprint: images and ground truth), ``method`` and
    ``landmarks`` (the scheme), each field of its encoder's config (backbone, weights, pooling,
    input size, projection, ...), ``shortlist``, ``protocol`` and each :class:`Matching` field;
    ``label`` names it (not compared)."""
    config = getattr(run, "config", None)
    if not isinstance(config, Method):
        raise ValueError(
            f"{getattr(run, 'label', type(run).__name__)!r} is not a run_method result (a peer "
            "or another value): a step is credited only between two runs of one method"
        )
    parts: dict[str, Any] = {
        "label": getattr(run, "label", config.name),
        "dataset": getattr(run, "dataset_fingerprint", "") or getattr(run, "dataset", None),
        "method": config.name,
        "landmarks": config.landmarks,
    }
    parts.update(dict(getattr(run, "encoder", None) or {}))
    parts.update(shortlist=getattr(run, "shortlist", None), protocol=getattr(run, "protocol", None))
    parts.update(dataclasses.asdict(config.matching))
    return parts


def step_between(a: Any, b: Any, caller: str, step: str = "the step") -> dict[str, Any]:
    """(Not in the paper.) The step ``b`` adds to ``a``: ``{field: value in b}`` for each of
    :data:`STEP_FIELDS` that differs (``{"weighting": "two_sided"}``). The one check of every
    function that credits a difference to a step: everything else must be the same.

    Args:
        a, b: two ``run_method`` results (or their :func:`run_identity`, or a mapping of the
            parts a saved table records: the same keys).
        caller: the function the refusal names; step: what it credits (in the refusal).

    Raises:
        ValueError: ``a`` and ``b`` differ in anything but the step (the dataset, method,
            landmarks, encoder, shortlist, protocol, another matching field: each named, with
            both values), in no step, or ``b`` removes a step ``a`` has.
    """
    ia, ib = (x if isinstance(x, Mapping) else run_identity(x) for x in (a, b))
    la, lb = ia.get("label", "a"), ib.get("label", "b")
    keys = [k for k in dict.fromkeys([*ia, *ib]) if k != "label"]
    other = [k for k in keys if k not in STEP_FIELDS and ia.get(k) != ib.get(k)]
    if other:
        shown = "; ".join(f"{k} {_short(ia.get(k))} vs {_short(ib.get(k))}" for k in other[:4])
        raise ValueError(
            f"{caller}: {la!r} and {lb!r} differ in more than {step} ({', '.join(other)}): "
            f"{shown}. A step is credited only between two runs that differ by it alone: pass "
            "one method's run without and with one more step (whiten=, weighting= or "
            "normalise=), the same dataset, encoder, shortlist and options otherwise"
        )
    found = {k: ib.get(k) for k in STEP_FIELDS if ia.get(k) != ib.get(k)}
    if not found or any(v is None for v in found.values()):
        raise ValueError(
            f"{caller}: {lb!r} must be {la!r} with one more step (whiten=, weighting= or "
            f"normalise=), the rest the same; it {'removes one' if found else 'adds none'}"
        )
    return found


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def default_label(method: Method, encoder: dict) -> str:
    """A run's label when none is given: the method's (:func:`~vpr_core.methods.method_label`)
    and a user's backbone module by its class (``"dense (backbone: TinyNet)"``), so a run with
    one's own backbone reads apart from the method's in a table and a legend (a named backbone
    is a setting of the whole study: titles name it, a figure's legend where it differs)."""
    text = method_label(method)
    if "module" not in encoder:  # a named backbone
        return text
    said = f"backbone: {encoder['backbone']}"
    return f"{text[:-1]}; {said})" if text.endswith(")") else f"{text} ({said})"
