"""Section 3.1's match labels: is a landmark match correct (do both boxes show the same region)?

=================  ==========================================================================
module             labeller
=================  ==========================================================================
``exact``          ``synthetic``: the generator's homography (:func:`label_matches_exact`)
``geometric``      real images: SIFT + RANSAC verification (:func:`estimate_pair_geometry`,
                   :func:`label_matches_geometric`)
``file``           a CSV of manual labels (:func:`read_label_file`, :func:`label_matches_file`)
``manual``         the ipywidgets helper that writes that CSV (:func:`label_widget`)
=================  ==========================================================================

:func:`label_matches` picks one by name (``auto``: ``exact`` where the geometry is known).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..datasets.ground_truth import ground_truth_references
from .exact import (
    LabelUnavailableError,
    check_matches,
    dataset_image_size,
    is_ground_truth,
    label_matches_exact,
    map_boxes,
)
from .file import LABEL_COLUMNS, label_matches_file, read_label_file
from .geometric import (
    PairGeometry,
    estimate_pair_geometry,
    label_matches_geometric,
    label_pair_geometric,
)
from .manual import append_labels, label_widget, pair_label_widget

__all__ = [
    "LABEL_COLUMNS",
    "LABEL_METHODS",
    "LabelUnavailableError",
    "PairGeometry",
    "PairMatches",
    "append_labels",
    "check_matches",
    "dataset_image_size",
    "estimate_pair_geometry",
    "is_ground_truth",
    "label_matches",
    "label_matches_exact",
    "label_matches_file",
    "label_matches_geometric",
    "label_widget",
    "map_boxes",
    "pair_label_widget",
    "pair_matches",
    "read_label_file",
    "resolve_label_method",
]

#: Names :func:`label_matches` accepts.
LABEL_METHODS = ("auto", "exact", "geometric", "file")


def resolve_label_method(dataset: Any, method: str, labels: Any) -> str:
    """The labeller ``method`` stands for: ``auto`` -> ``exact`` when the dataset has
    homographies, else ``file`` when ``labels`` is given, else ``geometric``.

    Raises:
        ValueError: unknown method (the message lists :data:`LABEL_METHODS`).
    """
    if method not in LABEL_METHODS:
        raise ValueError(f"unknown label method {method!r}; valid: {', '.join(LABEL_METHODS)}")
    if method != "auto":
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
    iou_threshold: float = 0.5,
    labels: Any = None,
    **options: Any,
) -> np.ndarray:
    """Label the landmark matches of query ``q`` vs reference ``r`` as correct / incorrect.

    A match is *correct* when its two boxes show the same physical region of the place.

    Methods:

    * ``exact`` (``synthetic``; needs ``dataset.homographies``): the 4 corners of the query box
      are mapped into reference ``r`` with ``dataset.homographies[q]``; the axis-aligned bounding
      box of the mapped corners, clipped to the reference image, is compared with the matched
      reference box: correct iff ``IoU >= iou_threshold``. For a pair that is *not* ground truth
      (different places) every match is incorrect by definition. The generator knows the geometry
      of the pair (q, q) only: a ground-truth pair with ``r != q`` (tolerance > 0) raises
      :class:`LabelUnavailableError` (label it with ``geometric`` instead).
    * ``geometric`` (real images): SIFT + ratio test (0.8) + RANSAC (see
      :func:`estimate_pair_geometry`) between the two images, then per match

      - when the pair is explained by one homography: the ``exact`` rule with the estimated
        homography (mapped box IoU >= ``iou_threshold``);
      - otherwise (fundamental matrix only) the *point rule*: with ``n_q`` the RANSAC inliers
        whose query point lies in the query box, ``n_r`` those whose reference point lies in the
        reference box and ``n_qr`` those inside both, the match is correct iff
        ``n_qr >= min_points`` (2) and the point-set IoU ``n_qr / (n_q + n_r - n_qr) >=
        point_iou`` (0.4) — the inlier analogue of the box IoU.

      A non-ground-truth pair is all incorrect (no image matching is run). A pair without a
      usable geometry raises :class:`LabelUnavailableError`. Images are loaded from the dataset
      unless ``images=(img_q, img_r)`` is given; ``geometry=`` passes a precomputed
      :class:`PairGeometry`; ``geometry_cache=`` (a dict) caches geometries per (q, r).
    * ``file``: rows of the CSV ``labels`` (columns
      ``query,reference,query_box_index,reference_box_index,correct``) for this (q, r), looked up
      per match; see :func:`label_matches_file` for the error / warning rules.
    * ``auto``: ``exact`` when ``dataset.homographies is not None``, else ``file`` when
      ``labels`` is given, else ``geometric``.

    Args:
        dataset: a ``PlaceDataset`` (uses ``ground_truth``, ``homographies``, ``load_image``,
            ``image_size``).
        q: query index.
        r: reference index.
        boxes_q: ``(Kq, 4)`` ``(x, y, w, h)`` query landmark boxes.
        boxes_r: ``(Kr, 4)`` reference landmark boxes.
        matches: ``(P, 2)`` int (query box index, reference box index) pairs.
        method: ``"auto"``, ``"exact"``, ``"geometric"`` or ``"file"``.
        iou_threshold: box-IoU threshold of the ``exact`` / homography rules.
        labels: CSV path or DataFrame for ``file``.
        **options: ``geometric``: ``images``, ``geometry``, ``geometry_cache``, ``model``,
            ``min_points``, ``point_iou`` and :func:`estimate_pair_geometry` keywords
            (``ratio``, ``min_inliers``, ...). ``file``: ``on_unmatched``. ``exact``:
            ``image_size_r``.

    Returns:
        ``(P,)`` bool, True = correct match.

    Raises:
        ValueError: unknown method (lists the valid ones), bad shapes, bad label files.
        LabelUnavailableError: the labeller has no information for this pair.
    """
    method = resolve_label_method(dataset, method, labels)
    if method == "exact":
        unknown = set(options) - {"image_size_r"}
        if unknown:
            raise TypeError(f"unexpected options for method='exact': {sorted(unknown)}")
        return label_matches_exact(
            dataset, q, r, boxes_q, boxes_r, matches, iou_threshold, **options
        )
    if method == "file":
        unknown = set(options) - {"on_unmatched"}
        if unknown:
            raise TypeError(f"unexpected options for method='file': {sorted(unknown)}")
        return label_matches_file(labels, q, r, boxes_q, boxes_r, matches, **options)
    return label_pair_geometric(dataset, q, r, boxes_q, boxes_r, matches, iou_threshold, **options)


@dataclass(frozen=True)
class PairMatches:
    """The landmark matches of one image pair of a run, labelled where the pair allows.

    Attributes:
        query, reference: the image indices.
        ground_truth: whether the pair shows the same place.
        matches: ``(P, 2)`` reciprocal matches (query box, reference box).
        labels: ``bool (P,)`` (an irrelevant pair's matches are all wrong), or None when the
            pair cannot be verified (``note`` says why).
        similarity: Eq. (1) of the pair.
        note: why the labels are missing ("" otherwise).
    """

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
    """Match and label the landmarks of one pair of a run (the data of Fig. 1-3 and 8).

    Args:
        dataset: the run's dataset.
        result: a :class:`~vpr_core.pipeline.MethodResult` run with ``keep_descriptors=True``.
        query: query index.
        reference: reference index; None: the query's ground-truth reference (Fig. 1).
            Another index shows an irrelevant pair, where every match is wrong (Fig. 2).

    Raises:
        ValueError: the result has no descriptors, or the query has no ground-truth reference.
    """
    from ..matching import match_landmarks

    if result.descriptors is None:
        raise ValueError(
            f"pair_matches needs the descriptors of {result.label!r}: run it with "
            "run_method(..., keep_descriptors=True)"
        )
    gt = np.asarray(dataset.ground_truth, dtype=bool)
    q = int(query)
    if reference is None:
        refs = ground_truth_references(gt, q)
        if not refs:
            raise ValueError(f"query {q} has no ground-truth reference; pick another query")
        reference = refs[0]
    r = int(reference)
    bq, br = result.boxes["query"][q], result.boxes["reference"][r]
    m = match_landmarks(result.descriptors["query"][q], bq, result.descriptors["reference"][r], br)
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
