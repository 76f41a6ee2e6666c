"""Named method presets: each paper method is data, merged over defaults (hloc habit).

A method config is a plain dict with two parts:

- ``landmarks``: how landmarks are produced per image. ``scheme`` is one of
  ``edge_boxes`` (top ``n`` Edge Box proposals), ``selection_scheme1`` (Algorithm 1),
  ``selection_scheme2`` (Algorithm 2), ``overlap_scheme1`` (Algorithm 3), ``dense`` or
  ``whole_image`` (one box covering the image). All Edge Box schemes select from the same
  ``n_candidates`` (1,000) proposals per image.
- ``matching``: ``soft_nms_iou`` (Algorithm 4 threshold, ``None`` = off) and ``sigma``.

Presets (paper section in brackets):

=====================  ============================================================
``classical``          top 100 Edge Boxes, Eq. (1) (Sec. 2.1, Sunderhauf et al. 2015)
``selection_scheme1``  Alg. 1: first 100 of 1,000 candidates with scale index >= 4
``selection_scheme2``  Alg. 2: scale priority 5, 6, 7, 8, 9, 4
``overlap_scheme1``    Alg. 3: greedy NMS over 1,000 candidates, ``iou_threshold``
``overlap_scheme2``    classical + Alg. 4 soft-NMS on the match scores, ``soft_nms_iou``
``dense``              4 scales x 25 landmarks on a grid (Sec. 4)
``global``             not in the paper: one whole-image descriptor from the same backbone,
                       so a reader sees what landmarks add. Eq. (1) with one box per image
                       is ``1 - d * s``; for equal image sizes ``s = exp(0) = 1`` and the
                       similarity is the cosine of the two whole-image descriptors. For
                       different sizes the shape penalty of Eq. (2) applies as for landmarks.
=====================  ============================================================

Each method accepts only its own options (:data:`METHOD_OPTIONS`); anything else is refused
with the list of valid ones, so an option never silently does nothing.
"""

from __future__ import annotations

import copy
import numbers
from typing import Any

from .paper import (
    DENSE_PER_SCALE,
    DENSE_SCALES,
    MIN_SCALE_INDEX,
    N_CANDIDATES,
    N_LANDMARKS,
    NMS_IOU,
    SCALE_PRIORITY_ORDER,
    SOFT_NMS_IOU,
    SOFT_NMS_SIGMA,
)

__all__ = [
    "DEFAULT_CONFIG",
    "EDGE_BOX_SCHEMES",
    "METHODS",
    "METHOD_OPTIONS",
    "available_methods",
    "get_method",
    "landmark_config",
    "method_label",
    "run_key",
]

EDGE_BOX_SCHEMES = ("edge_boxes", "selection_scheme1", "selection_scheme2", "overlap_scheme1")

DEFAULT_CONFIG: dict[str, Any] = {
    "landmarks": {"scheme": "edge_boxes", "n": N_LANDMARKS, "n_candidates": N_CANDIDATES},
    "matching": {"soft_nms_iou": None, "sigma": SOFT_NMS_SIGMA},
}

METHODS: dict[str, dict[str, Any]] = {
    "classical": {"landmarks": {"scheme": "edge_boxes", "n": N_LANDMARKS}},
    "selection_scheme1": {
        "landmarks": {"scheme": "selection_scheme1", "n": N_LANDMARKS, "min_index": MIN_SCALE_INDEX}
    },
    "selection_scheme2": {
        "landmarks": {
            "scheme": "selection_scheme2",
            "n": N_LANDMARKS,
            "order": SCALE_PRIORITY_ORDER,
        }
    },
    "overlap_scheme1": {
        "landmarks": {"scheme": "overlap_scheme1", "n": N_LANDMARKS, "iou_threshold": NMS_IOU}
    },
    "overlap_scheme2": {
        "landmarks": {"scheme": "edge_boxes", "n": N_LANDMARKS},
        "matching": {"soft_nms_iou": SOFT_NMS_IOU, "sigma": SOFT_NMS_SIGMA},
    },
    "dense": {
        "landmarks": {"scheme": "dense", "scales": DENSE_SCALES, "per_scale": DENSE_PER_SCALE}
    },
    "global": {"landmarks": {"scheme": "whole_image"}},
}

_EDGE = ("n", "n_candidates")
#: The options each method accepts (flat keyword overrides of :func:`get_method`).
METHOD_OPTIONS: dict[str, tuple[str, ...]] = {
    "classical": _EDGE,
    "selection_scheme1": _EDGE + ("min_index",),
    "selection_scheme2": _EDGE + ("order",),
    "overlap_scheme1": _EDGE + ("iou_threshold",),
    "overlap_scheme2": _EDGE + ("soft_nms_iou", "sigma"),
    "dense": ("scales", "per_scale"),
    "global": (),
}

# Which sub-config an option belongs to.
_MATCHING_KEYS = {"soft_nms_iou", "sigma"}
# Landmark keys a scheme does not use (dropped from its config so cache keys stay minimal).
_NOT_FOR = {"dense": ("n", "n_candidates"), "whole_image": ("n", "n_candidates")}


def available_methods() -> list[str]:
    """Names of the method presets."""
    return sorted(METHODS)


def _merge(base: dict, extra: dict) -> dict:
    out = copy.deepcopy(base)
    for k, v in extra.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = _merge(out[k], v)
        else:
            out[k] = v
    return out


def _normalise(value: Any) -> Any:
    """Lists -> tuples (hashable, stable slugs)."""
    if isinstance(value, (list, tuple)):
        return tuple(_normalise(v) for v in value)
    return value


def _is_number(v: Any) -> bool:
    return isinstance(v, numbers.Real) and not isinstance(v, bool)


def _is_int(v: Any) -> bool:
    return isinstance(v, numbers.Integral) and not isinstance(v, bool)


def _validate(name: str, key: str, value: Any) -> Any:
    """Check one option's type and range before it reaches a label, a slug or an algorithm."""

    def bad(expected: str) -> ValueError:
        return ValueError(
            f"method {name!r}: option {key}={value!r} is not valid; expected {expected}"
        )

    if key == "scales":
        if isinstance(value, (str, bytes)) or not isinstance(value, (list, tuple)):
            raise bad("a sequence of normalised scales in (0, 1], e.g. scales=(0.16, 0.25)")
        if not value or not all(_is_number(s) and 0 < s <= 1 for s in value):
            raise bad("a non-empty sequence of numbers in (0, 1]")
        return tuple(float(s) for s in value)
    if key == "per_scale":
        if _is_int(value) and value > 0:
            return int(value)
        if isinstance(value, (list, tuple)) and value and all(_is_int(v) and v > 0 for v in value):
            return tuple(int(v) for v in value)
        raise bad("a positive integer (a square, e.g. 25) or one per scale")
    if key in ("n", "n_candidates", "min_index"):
        if not (_is_int(value) and value >= 1):
            raise bad("a positive integer (at least 1)")
        return int(value)
    if key == "order":
        if (
            isinstance(value, (str, bytes))
            or not isinstance(value, (list, tuple))
            or not all(_is_int(v) and 1 <= v <= 9 for v in value)
            or not value
        ):
            raise bad("a non-empty sequence of Table-1 scale indices 1..9, e.g. (5, 6, 7, 8, 9, 4)")
        return tuple(int(v) for v in value)
    if key in ("iou_threshold", "soft_nms_iou"):
        if value is None and key == "soft_nms_iou":
            return None
        if not (_is_number(value) and 0 <= value <= 1):
            raise bad("a number in [0, 1]")
        return float(value)
    if key == "sigma":
        if not (_is_number(value) and value > 0):
            raise bad("a positive number")
        return float(value)
    return _normalise(value)  # pragma: no cover - every option above is typed


def get_method(name: str, **overrides: Any) -> dict[str, Any]:
    """Config dict of a named method, with flat ``overrides`` routed to the right part.

    Args:
        name: one of :func:`available_methods`.
        **overrides: the method's own options (:data:`METHOD_OPTIONS`), e.g.
            ``iou_threshold=0.4`` (``overlap_scheme1``), ``soft_nms_iou=0.3``
            (``overlap_scheme2``), ``scales=(0.25, 0.49), per_scale=49`` (``dense``).
            ``None`` means "not set" and is skipped.

    Returns:
        ``{"name": ..., "landmarks": {...}, "matching": {...}}``.

    Raises:
        ValueError: unknown method, an option the method does not take (the message lists the
            valid ones) or an option value of the wrong type or range.
    """
    if name not in METHODS:
        raise ValueError(
            f"Unknown method {name!r}. Valid methods: {', '.join(available_methods())}."
        )
    conf = _merge(DEFAULT_CONFIG, METHODS[name])
    valid = METHOD_OPTIONS[name]
    for key, value in overrides.items():
        if key not in valid:
            raise ValueError(
                f"Unknown option {key!r} for method {name!r}: it would be ignored. Options of "
                f"{name!r}: {', '.join(valid) if valid else 'none'}."
            )
        if value is None and key != "soft_nms_iou":
            continue
        part = "matching" if key in _MATCHING_KEYS else "landmarks"
        conf[part][key] = _validate(name, key, value)
    conf["landmarks"] = {k: _normalise(v) for k, v in conf["landmarks"].items()}
    for k in _NOT_FOR.get(conf["landmarks"]["scheme"], ()):
        conf["landmarks"].pop(k, None)
    conf["name"] = name
    return conf


def landmark_config(conf: dict[str, Any]) -> dict[str, Any]:
    """The part of a method config that decides the landmarks (cache key of the boxes)."""
    return dict(conf["landmarks"])


def method_label(conf: dict[str, Any]) -> str:
    """Short human label of a method config (legends and tables), derived from the same options
    as :func:`run_key`: ``"overlap_scheme1 (IoU 0.4)"``, ``"dense (0.25/0.49 x 49)"``."""
    name, opts = conf["name"], _options(conf)
    if name == "overlap_scheme1":
        return f"{name} (IoU {conf['landmarks']['iou_threshold']:g})"
    if name == "overlap_scheme2":
        return f"{name} (IoU {conf['matching']['soft_nms_iou']:g})"
    if name == "dense" and opts:
        lconf = conf["landmarks"]
        return f"dense ({_text(tuple(lconf['scales']))} x {_text(lconf['per_scale'])})"
    return name


def _options(conf: dict[str, Any]) -> dict[str, Any]:
    """The options of a config that differ from its preset (flat, as :func:`get_method` takes)."""
    name = conf["name"]
    if name not in METHODS:
        return {}
    base = get_method(name)
    out = {}
    for part in ("landmarks", "matching"):
        for key, value in conf.get(part, {}).items():
            if key in METHOD_OPTIONS[name] and base[part].get(key) != value:
                out[key] = value
    return dict(sorted(out.items()))


def _text(value: Any) -> str:
    if isinstance(value, tuple):
        return "/".join(_text(v) for v in value)
    return f"{value:g}" if isinstance(value, float) else str(value)


def run_key(conf: dict[str, Any]) -> str:
    """The identity of a run's configuration: the preset name and every option that differs
    from the preset, e.g. ``"overlap_scheme1(iou_threshold=0.4)"`` or
    ``"dense(per_scale=49, scales=0.25/0.49)"``; just ``"classical"`` at the defaults.

    Tables carry it in their ``run`` column and the paper's claims are matched on it (never on
    a legend text); :func:`method_label` derives the legend from the same options.
    """
    opts = _options(conf)
    inner = ", ".join(f"{k}={_text(v)}" for k, v in opts.items())
    return f"{conf['name']}({inner})" if inner else conf["name"]
