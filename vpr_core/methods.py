"""Named method presets: each paper method is data, merged over defaults (hloc habit).

A method config is a plain dict with two parts:

- ``landmarks``: how landmarks are produced per image. ``scheme`` is one of
  ``edge_boxes`` (top ``n`` Edge Box proposals), ``selection_scheme1`` (Algorithm 1),
  ``selection_scheme2`` (Algorithm 2), ``overlap_scheme1`` (Algorithm 3) or ``dense``.
  All Edge Box schemes select from the same ``n_candidates`` (1,000) proposals per image.
- ``matching``: ``soft_nms_iou`` (Algorithm 4 threshold, ``None`` = off) and ``sigma``.

Presets (paper section in brackets):

=====================  ============================================================
``classical``          top 100 Edge Boxes, Eq. (1) (Sec. 2.1, Sunderhauf et al. 2015)
``selection_scheme1``  Alg. 1: first 100 of 1,000 candidates with scale index >= 4
``selection_scheme2``  Alg. 2: scale priority (5, 6, 7, 8, 9, 4)
``overlap_scheme1``    Alg. 3: greedy NMS over 1,000 candidates, ``iou_threshold``
``overlap_scheme2``    classical + Alg. 4 soft-NMS on the match scores, ``soft_nms_iou``
``dense``              4 scales (0.16, 0.25, 0.36, 0.49) x 25 landmarks (Sec. 4)
=====================  ============================================================
"""

from __future__ import annotations

import copy
from typing import Any

EDGE_BOX_SCHEMES = ("edge_boxes", "selection_scheme1", "selection_scheme2", "overlap_scheme1")

DEFAULT_CONFIG: dict[str, Any] = {
    "landmarks": {"scheme": "edge_boxes", "n": 100, "n_candidates": 1000},
    "matching": {"soft_nms_iou": None, "sigma": 0.5},
}

METHODS: dict[str, dict[str, Any]] = {
    "classical": {"landmarks": {"scheme": "edge_boxes", "n": 100}},
    "selection_scheme1": {"landmarks": {"scheme": "selection_scheme1", "n": 100, "min_index": 4}},
    "selection_scheme2": {
        "landmarks": {"scheme": "selection_scheme2", "n": 100, "order": (5, 6, 7, 8, 9, 4)}
    },
    "overlap_scheme1": {"landmarks": {"scheme": "overlap_scheme1", "n": 100, "iou_threshold": 0.5}},
    "overlap_scheme2": {
        "landmarks": {"scheme": "edge_boxes", "n": 100},
        "matching": {"soft_nms_iou": 0.5, "sigma": 0.5},
    },
    "dense": {
        "landmarks": {"scheme": "dense", "scales": (0.16, 0.25, 0.36, 0.49), "per_scale": 25}
    },
}

# Which sub-config an override key belongs to.
_MATCHING_KEYS = {"soft_nms_iou", "sigma"}
_LANDMARK_KEYS = {"n", "n_candidates", "min_index", "order", "iou_threshold", "scales", "per_scale",
                  "scheme"}


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
    if isinstance(value, list):
        return tuple(_normalise(v) for v in value)
    if isinstance(value, tuple):
        return tuple(_normalise(v) for v in value)
    return value


def get_method(name: str, **overrides: Any) -> dict[str, Any]:
    """Config dict of a named method, with flat ``overrides`` routed to the right part.

    Args:
        name: one of :func:`available_methods`.
        **overrides: e.g. ``iou_threshold=0.4`` (``overlap_scheme1``), ``soft_nms_iou=0.3``,
            ``scales=(0.25, 0.49), per_scale=49`` (``dense``).

    Returns:
        ``{"name": ..., "landmarks": {...}, "matching": {...}}``.

    Raises:
        ValueError: unknown method or override key (the message lists the valid ones).
    """
    if name not in METHODS:
        raise ValueError(
            f"Unknown method {name!r}. Valid methods: {', '.join(available_methods())}."
        )
    conf = _merge(DEFAULT_CONFIG, METHODS[name])
    for key, value in overrides.items():
        if value is None and key != "soft_nms_iou":
            continue
        if key in _MATCHING_KEYS:
            conf["matching"][key] = _normalise(value)
        elif key in _LANDMARK_KEYS:
            conf["landmarks"][key] = _normalise(value)
        else:
            valid = sorted(_MATCHING_KEYS | _LANDMARK_KEYS)
            raise ValueError(f"Unknown option {key!r} for method {name!r}. Valid: {valid}.")
    conf["landmarks"] = {k: _normalise(v) for k, v in conf["landmarks"].items()}
    scheme = conf["landmarks"]["scheme"]
    if scheme == "dense":
        for k in ("n", "n_candidates"):
            conf["landmarks"].pop(k, None)
    conf["name"] = name
    return conf


def landmark_config(conf: dict[str, Any]) -> dict[str, Any]:
    """The part of a method config that decides the landmarks (cache key of the boxes)."""
    return dict(conf["landmarks"])
