"""Exact match labels from a known homography (``synthetic``), and what every labeller shares.
The rule is in docs/DEFINITIONS.md."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from ..boxes import paired_iou_parsed
from ..checks import check_choice, check_int, check_range, check_shape

__all__ = [
    "RULE_FIELDS",
    "LabelRule",
    "LabelUnavailableError",
    "as_label_rule",
    "check_matches",
    "dataset_image_size",
    "is_ground_truth",
    "label_pair_exact",
    "map_boxes",
    "value_or_fields",
]


class LabelUnavailableError(ValueError):
    """The labeller cannot label this pair; ``scale_statistics`` counts it as unlabelled."""


@dataclasses.dataclass(frozen=True)
class LabelRule:
    """When a landmark match is correct (docs/DEFINITIONS.md, "Match labels"): its query box
    mapped by the pair's homography overlaps the matched box with IoU >= ``iou_threshold``
    (``exact``, and ``geometric`` with a homography); without one (``geometric``, ``model``
    ``"auto"`` or ``"points"``) at least ``min_points`` inlier correspondences fall in both
    boxes with point-IoU >= ``point_iou``. Checked once, here."""

    iou_threshold: float = 0.5
    model: str = "auto"
    min_points: int = 2
    point_iou: float = 0.4

    def __post_init__(self) -> None:
        check_range(self.iou_threshold, "iou_threshold", 0.0, 1.0)
        check_choice(self.model, "model", ("auto", "homography", "points"))
        check_int(self.min_points, "min_points", 1)
        check_range(self.point_iou, "point_iou", 0.0, 1.0)


#: The :class:`LabelRule` fields a labeller reads (``geometric``: all of them).
RULE_FIELDS = {"exact": ("iou_threshold",), "file": ()}


def as_label_rule(options: dict[str, Any], method: str = "geometric") -> LabelRule:
    """Pop ``rule=`` (a :class:`LabelRule`) or the fields ``method`` reads from ``options`` (not
    both; a field it does not read stays, and is refused as an unexpected option)."""
    names = RULE_FIELDS.get(method, [f.name for f in dataclasses.fields(LabelRule)])
    value = options.pop("rule", None)
    given = {name: options.pop(name) for name in names if name in options}
    return value_or_fields(LabelRule, "rule", value, given)


def value_or_fields(cls: type, name: str, value: Any, fields: dict[str, Any]) -> Any:
    """Option ``name`` given as a ``cls`` value or as its ``fields`` (not both): the value, or a
    ``cls`` made of the fields (``LabelRule``, ``Verification``)."""
    if value is None:
        return cls(**fields)
    if fields:
        raise ValueError(f"give {name}={cls.__name__}(...) or its fields, not both")
    if not isinstance(value, cls):
        raise TypeError(f"{name} must be a {cls.__name__}(...), got {type(value).__name__}")
    return value


def check_matches(matches: Any, n_q: int, n_r: int) -> np.ndarray:
    """``matches`` as int64 ``(P, 2)`` (query, reference box index); empty gives ``(0, 2)``."""
    if np.size(matches) == 0:
        return np.zeros((0, 2), dtype=np.int64)
    m = check_shape(matches, "P 2", "matches").astype(np.int64)
    for col, side, n in ((0, "query", n_q), (1, "reference", n_r)):
        if (m[:, col] < 0).any() or (m[:, col] >= n).any():
            raise ValueError(f"matches reference {side} boxes outside 0..{n - 1}")
    return m


def dataset_image_size(dataset: Any, side: str, i: int) -> tuple[int, int]:
    """``(H, W)`` of image ``i`` of ``side`` (``dataset.image_size`` if it has one, else loaded)."""
    fn = getattr(dataset, "image_size", None)
    if callable(fn):
        hw = fn(side, i)
        return int(hw[0]), int(hw[1])
    img = dataset.load_image(side, i)
    return int(img.shape[0]), int(img.shape[1])


def is_ground_truth(dataset: Any, q: int, r: int) -> bool:
    """``dataset.ground_truth[q, r]``; IndexError naming the shape when (q, r) is outside it."""
    gt = np.asarray(dataset.ground_truth, dtype=bool)
    if not (0 <= q < gt.shape[0] and 0 <= r < gt.shape[1]):
        raise IndexError(f"pair (q={q}, r={r}) outside the ground truth of shape {gt.shape}")
    return bool(gt[q, r])


def map_boxes(
    b: np.ndarray, H: np.ndarray, image_size: tuple[int, int] | None = None
) -> np.ndarray:
    """Boxes ``(K, 4)`` through a ``(3, 3)`` homography (source pixel ``(x, y, 1)`` -> target):
    the bounding box of the 4 mapped corners, clipped to ``image_size`` ``(H, W)`` if given; a
    corner mapped to or behind the line at infinity gives a zero box."""
    if len(b) == 0:
        return b.copy()
    x, y, w, h = b.T
    cx = np.stack([x, x + w, x, x + w], axis=1)  # (K, 4)
    cy = np.stack([y, y, y + h, y + h], axis=1)
    pts = np.stack([cx, cy, np.ones_like(cx)], axis=-1) @ H.T  # (K, 4, 3)
    z = pts[..., 2]
    valid = (z > 1e-12).all(axis=1)
    zs = np.where(z > 1e-12, z, 1.0)
    mx, my = pts[..., 0] / zs, pts[..., 1] / zs
    x1, x2 = mx.min(axis=1), mx.max(axis=1)
    y1, y2 = my.min(axis=1), my.max(axis=1)
    if image_size is not None:
        Hh, Ww = float(image_size[0]), float(image_size[1])
        x1, x2 = np.clip(x1, 0, Ww), np.clip(x2, 0, Ww)
        y1, y2 = np.clip(y1, 0, Hh), np.clip(y2, 0, Hh)
    out = np.stack([x1, y1, x2 - x1, y2 - y1], axis=1)
    out[~valid, 2:] = 0.0
    out[~valid, :2] = 0.0
    return out


def label_pair_exact(
    dataset: Any,
    q: int,
    r: int,
    bq: np.ndarray,
    br: np.ndarray,
    m: np.ndarray,
    rule: LabelRule,
    image_size_r: tuple[int, int] | None = None,
) -> np.ndarray:
    """``method="exact"`` of :func:`vpr_core.labels.label_matches` on boxes, matches and a rule
    a caller already parsed (no checks).

    Raises:
        LabelUnavailableError: no homographies, or a ground-truth pair (q, r) with ``r != q``
            (the generator knows the geometry of (i, i) only).
    """
    Hs = getattr(dataset, "homographies", None)
    if Hs is None:
        raise LabelUnavailableError(
            f"exact labels need dataset.homographies; dataset {getattr(dataset, 'name', '?')!r} "
            "has none: use method='geometric' or method='file'"
        )
    if not is_ground_truth(dataset, q, r):
        return np.zeros(len(m), dtype=bool)  # not the same place: every match is wrong
    if r != q:
        raise LabelUnavailableError(
            f"pair (q={q}, r={r}) is ground truth only through the tolerance; the generator's "
            f"homography is known for (q, q) only. Label (q={q}, r={q}), or use "
            "method='geometric' for neighbouring references"
        )
    if len(m) == 0:
        return np.zeros(0, dtype=bool)
    size_r = (
        image_size_r if image_size_r is not None else dataset_image_size(dataset, "reference", r)
    )
    mapped = map_boxes(bq[m[:, 0]], np.asarray(Hs, dtype=np.float64)[q], size_r)
    return paired_iou_parsed(mapped, br[m[:, 1]]) >= rule.iou_threshold
