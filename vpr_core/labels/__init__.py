"""Section 3.1's match labels: exact, geometric or from a CSV (docs/DEFINITIONS.md). This face
is the API; the labellers are the package-private ``_exact``, ``_geometric`` and ``_file``."""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..checks import check_boxes, check_choice, check_descriptors_kept, check_options
from ..datasets.ground_truth import ground_truth_references
from ..matching import match_landmarks
from ._exact import LabelRule, LabelUnavailableError, as_label_rule, check_matches, label_pair_exact
from ._file import append_labels, label_pair_file
from ._geometric import (
    GEOMETRIC_OPTIONS,
    estimate_pair_geometry,
    label_matches_geometric,
    label_pair_geometric,
)

__all__ = [
    "LabelRule",
    "LabelUnavailableError",
    "append_labels",
    "estimate_pair_geometry",
    "label_matches",
    "label_matches_geometric",
    "pair_matches",
]

#: Names :func:`label_matches` accepts.
LABEL_METHODS = ("auto", "exact", "geometric", "file")

#: The options each labeller takes beside ``rule`` and the file method's ``labels``.
_OPTIONS = {"exact": ("image_size_r",), "file": ("on_unmatched",), "geometric": GEOMETRIC_OPTIONS}


def resolve_label_method(dataset: Any, method: str, labels: Any) -> str:
    """The labeller ``method`` stands for (``auto``: exact, else file, else geometric)."""
    if check_choice(method, "label method", LABEL_METHODS) != "auto":
        return method
    if getattr(dataset, "homographies", None) is not None:
        return "exact"
    if labels is not None:
        return "file"
    return "geometric"


def label_matches(
    dataset: Any,
    q: int,
    r: int,
    boxes_q: np.ndarray,
    boxes_r: np.ndarray,
    matches: np.ndarray,
    method: str = "auto",
    **options: Any,
) -> np.ndarray:
    """``(P,)`` bool: each landmark match ``(P, 2)`` of pair (q, r) correct or not
    (docs/DEFINITIONS.md), by one of :data:`LABEL_METHODS`.

    ``**options``: ``rule=`` (a :class:`LabelRule`, or its fields as keywords:
    ``iou_threshold``, ...); ``geometric``: ``images``, ``geometry``, ``geometry_cache`` and
    ``verification=`` (a :class:`Verification`, or its fields as keywords); ``file``:
    ``labels`` (the CSV: a path or DataFrame; under ``auto`` it picks ``file`` where the
    geometry is unknown) and ``on_unmatched``; ``exact``: ``image_size_r``.
    LabelUnavailableError: no information.
    """
    bq, br = check_boxes(boxes_q, "boxes_q"), check_boxes(boxes_r, "boxes_r")
    m = check_matches(matches, len(bq), len(br))
    method = resolve_label_method(dataset, method, options.get("labels"))
    rule = as_label_rule(options, method)
    return label_matches_parsed(dataset, q, r, bq, br, m, method, rule, **options)


def label_matches_parsed(
    dataset: Any,
    q: int,
    r: int,
    bq: np.ndarray,
    br: np.ndarray,
    m: np.ndarray,
    method: str,
    rule: LabelRule,
    **options: Any,
) -> np.ndarray:
    """:func:`label_matches` of boxes, matches, a resolved ``method`` and a :class:`LabelRule` a
    caller already parsed; the labeller's option names are checked here."""
    labels = options.pop("labels", None)  # the file method's CSV
    check_options(options, _OPTIONS[method], f"{method} label")
    if method == "exact":
        return label_pair_exact(dataset, q, r, bq, br, m, rule, **options)
    if method == "file":
        return label_pair_file(labels, q, r, bq, br, m, **options)
    return label_pair_geometric(dataset, q, r, bq, br, m, rule, **options)


@dataclass(frozen=True)
class PairMatches:
    """The ``(P, 2)`` reciprocal landmark matches of one image pair of a run, their ``(P,)``
    labels (None when the pair cannot be verified: ``note`` says why) and Eq. (1) of the pair."""

    query: int
    reference: int
    ground_truth: bool
    matches: np.ndarray
    labels: np.ndarray | None
    similarity: float
    note: str = ""

    def summary(self) -> str:
        """e.g. ``"query 0 vs reference 0 (ground truth); 40/61 matches correct; S = 0.41"``."""
        counts = (
            f"{int(self.labels.sum())}/{len(self.labels)} matches correct"
            if self.labels is not None
            else f"{len(self.matches)} matches, unlabelled"
        )
        kind = "ground truth" if self.ground_truth else "irrelevant"
        return (
            f"query {self.query} vs reference {self.reference} ({kind}); {counts}; "
            f"S = {self.similarity:.3f}"
        )


def pair_matches(
    dataset: Any, result: Any, query: int = 0, reference: int | None = None
) -> PairMatches:
    """Match and label the landmarks of one pair of a run with ``keep_descriptors=True`` (the
    data of Fig. 1-3 and 8); ``reference`` None: the query's ground-truth reference."""
    descriptors = check_descriptors_kept(result, "pair_matches")
    gt = np.asarray(dataset.ground_truth, dtype=bool)
    q = int(query)
    if reference is None:
        refs = ground_truth_references(gt, q)
        if not refs:
            raise ValueError(f"query {q} has no ground-truth reference; pick another query")
        reference = refs[0]
    r = int(reference)
    bq, br = result.boxes["query"][q], result.boxes["reference"][r]
    m = match_landmarks(descriptors["query"][q], bq, descriptors["reference"][r], br)
    note = ""
    if gt[q, r]:
        try:
            labels = label_matches(dataset, q, r, bq, br, m.matches)
        except LabelUnavailableError as exc:
            labels, note = None, str(exc)
            logging.getLogger("vpr_core").warning("pair (%d, %d) cannot be labelled: %s", q, r, exc)
    else:
        labels = np.zeros(len(m.matches), dtype=bool)
    return PairMatches(
        q, r, bool(gt[q, r]), np.asarray(m.matches), labels, float(m.similarity), note
    )
