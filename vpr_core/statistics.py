"""Section 3.1: CMR, CLS and ASL of landmark matches per Table-1 scale (Fig. 4).
Definitions in docs/DEFINITIONS.md ("Scale statistics"); arrays are indexed by scale 1..9."""

from __future__ import annotations

import logging
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from os import PathLike
from typing import Any

import numpy as np
import pandas as pd

from .checks import check_boxes, check_descriptors_kept, check_image_size, check_per_match
from .datasets.ground_truth import (
    ground_truth_references,
    ground_truth_text,
    sample_irrelevant_references,
)
from .evaluation.bootstrap import N_BOOTSTRAP
from .labels import (
    LabelUnavailableError,
    as_label_rule,
    label_matches,
    label_matches_parsed,
    resolve_label_method,
)
from .labels._exact import dataset_image_size
from .labels._file import read_label_file
from .landmarks.scales import scale_index_parsed
from .matching import match_landmarks
from .methods import Matching
from .paper import N_SCALES, SCALE_RANGE_LABELS
from .utils import progress

__all__ = [
    "cmr_difference",
    "MatchRecord",
    "ScaleStats",
    "label_matches",
    "scale_statistics",
    "scale_statistics_from_matches",
]

logger = logging.getLogger("vpr_core")


@dataclass
class MatchRecord:
    """Matches of one image pair: the ``(P,)`` Table-1 scale (1..9) of each match's query-side
    landmark, its pair score ``1 - d*s``, its label (None: unlabelled, the pair does not enter
    CMR), and optionally the ``(P, 2)`` (query box, reference box) indices."""

    scales: np.ndarray
    scores: np.ndarray
    labels: np.ndarray | None
    is_gt_pair: bool
    q: int = -1
    r: int = -1
    matches: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.scales = np.asarray(self.scales, dtype=np.int64).reshape(-1)
        self.scores = np.asarray(self.scores, dtype=np.float64).reshape(-1)
        check_per_match(self.scores, len(self.scales), "scores")
        if len(self.scales) and ((self.scales < 1) | (self.scales > N_SCALES)).any():
            raise ValueError("scales must be Table-1 indices 1..9")
        if self.labels is not None:
            self.labels = np.asarray(self.labels, dtype=bool).reshape(-1)
            check_per_match(self.labels, len(self.scales), "labels")


def _nan10() -> np.ndarray:
    return np.full(N_SCALES + 1, np.nan)


def _zeros10() -> np.ndarray:
    return np.zeros(N_SCALES + 1, dtype=np.int64)


@dataclass
class ScaleStats:
    """Fig. 4 statistics; every array has length 10, indexed by scale (0 unused, NaN / 0).

    ``cmr``, ``cls_*`` and ``asl_*`` are defined in docs/DEFINITIONS.md; ``n_matches``,
    ``n_labelled`` and ``n_correct`` count ground-truth-pair matches per scale,
    ``n_matches_irrelevant`` those of query-irrelevant pairs. ``records`` keeps the per-pair
    :class:`MatchRecord` s (:meth:`matches_frame`).
    """

    n_matches: np.ndarray = field(default_factory=_zeros10)
    n_labelled: np.ndarray = field(default_factory=_zeros10)
    n_correct: np.ndarray = field(default_factory=_zeros10)
    cmr: np.ndarray = field(default_factory=_nan10)
    cls_gt: np.ndarray = field(default_factory=_nan10)
    cls_irrelevant: np.ndarray = field(default_factory=_nan10)
    asl_gt: np.ndarray = field(default_factory=_nan10)
    asl_irrelevant: np.ndarray = field(default_factory=_nan10)
    n_matches_irrelevant: np.ndarray = field(default_factory=_zeros10)
    n_gt_pairs: int = 0
    n_irrelevant_pairs: int = 0
    n_unlabelled_pairs: int = 0
    meta: dict = field(default_factory=dict)
    records: list = field(default_factory=list, repr=False)

    @property
    def scales(self) -> np.ndarray:
        """``(9,)`` the scale indices 1..9."""
        return np.arange(1, N_SCALES + 1)

    def cmr_intervals(self, n: int | None = None, seed: int = 0) -> np.ndarray:
        """``(10, 2)`` 95% bootstrap interval of each scale's CMR, resampling query images
        (``n`` default ``N_BOOTSTRAP``); NaN where the scale has no labelled match."""
        n = N_BOOTSTRAP if n is None else int(n)
        out = np.full((N_SCALES + 1, 2), np.nan)
        recs = [r for r in self.records if r.is_gt_pair and r.labels is not None]
        if not recs or n < 1:
            return out
        queries = sorted({r.q for r in recs})
        qi = {q: k for k, q in enumerate(queries)}
        correct = np.zeros((len(queries), N_SCALES + 1))
        total = np.zeros((len(queries), N_SCALES + 1))
        for r in recs:
            sc = np.asarray(r.scales, dtype=np.int64)
            np.add.at(correct[qi[r.q]], sc, np.asarray(r.labels, dtype=float))
            np.add.at(total[qi[r.q]], sc, 1.0)
        rng = np.random.default_rng(seed)
        draws = rng.integers(0, len(queries), size=(n, len(queries)))
        w = np.zeros((n, len(queries)))
        np.add.at(w, (np.repeat(np.arange(n), len(queries)), draws.ravel()), 1.0)
        with np.errstate(invalid="ignore", divide="ignore"):
            rates = (w @ correct) / (w @ total)  # (n, 10); NaN where a resample has no match
        for k in range(1, N_SCALES + 1):
            if total[:, k].sum() > 0:
                out[k] = np.nanpercentile(rates[:, k], [2.5, 97.5])
        return out

    def to_frame(self) -> Any:
        """DataFrame, one row per scale 1..9: ``range``, every array, ``cmr lo`` / ``cmr hi``."""
        s = slice(1, N_SCALES + 1)
        iv = self.cmr_intervals()
        df = pd.DataFrame(
            {
                "scale": self.scales,
                "range": list(SCALE_RANGE_LABELS),
                "n_matches": self.n_matches[s],
                "n_labelled": self.n_labelled[s],
                "n_correct": self.n_correct[s],
                "cmr": self.cmr[s],
                "cmr lo": iv[s, 0],
                "cmr hi": iv[s, 1],
                "cls_gt": self.cls_gt[s],
                "cls_irrelevant": self.cls_irrelevant[s],
                "asl_gt": self.asl_gt[s],
                "asl_irrelevant": self.asl_irrelevant[s],
                "n_matches_irrelevant": self.n_matches_irrelevant[s],
            }
        )
        return df.set_index("scale")

    def matches_frame(self) -> Any:
        """DataFrame, one row per match: ``query``, ``reference``, ``pair`` (gt / irrelevant),
        box indices (-1 when unknown), ``scale``, ``score`` and ``correct`` (1 / 0 / empty)."""
        rows = []
        for rec in self.records:
            m = (
                np.asarray(rec.matches, dtype=np.int64).reshape(-1, 2)
                if rec.matches is not None
                else np.full((len(rec.scales), 2), -1, dtype=np.int64)
            )
            for k in range(len(rec.scales)):
                rows.append(
                    {
                        "query": rec.q,
                        "reference": rec.r,
                        "pair": "gt" if rec.is_gt_pair else "irrelevant",
                        "query_box_index": int(m[k, 0]),
                        "reference_box_index": int(m[k, 1]),
                        "scale": int(rec.scales[k]),
                        "score": float(rec.scores[k]),
                        "correct": (None if rec.labels is None else int(rec.labels[k])),
                    }
                )
        columns = "query reference pair query_box_index reference_box_index scale score correct"
        return pd.DataFrame(rows, columns=columns.split())


def _cls_asl(scales: np.ndarray, scores: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    n = np.bincount(scales, minlength=N_SCALES + 1)[: N_SCALES + 1].astype(np.int64)
    mass = np.bincount(scales, weights=scores, minlength=N_SCALES + 1)[: N_SCALES + 1]
    # CLS shares the *positive* similarity mass: a pair score 1 - d*s below 0 (d*s > 1, common
    # with weakly similar descriptors and the shape factor s <= e) lowers Eq. (1) rather than
    # contributing to it, and signed sums near zero would give shares far outside [0, 1].
    pos = np.bincount(scales, weights=np.clip(scores, 0.0, None), minlength=N_SCALES + 1)[
        : N_SCALES + 1
    ]
    n[0] = 0
    mass[0] = pos[0] = 0.0
    total = pos[1:].sum()
    cls = _nan10()
    if len(scores) and total > 0:
        cls[1:] = pos[1:] / total
    asl = _nan10()
    nz = n > 0
    asl[nz] = mass[nz] / n[nz]
    return n, cls, asl


def scale_statistics_from_matches(
    records: Iterable[MatchRecord], meta: dict | None = None
) -> ScaleStats:
    """CMR / CLS / ASL per Table-1 scale from per-pair match records (any method, any matcher)."""
    records = list(records)
    gt_sc, gt_s, irr_sc, irr_s, lab_sc, lab_v = [], [], [], [], [], []
    n_gt = n_irr = n_unl = 0
    for rec in records:
        if not isinstance(rec, MatchRecord):
            rec = MatchRecord(*rec)
        if rec.is_gt_pair:
            n_gt += 1
            gt_sc.append(rec.scales)
            gt_s.append(rec.scores)
            if rec.labels is None:
                n_unl += 1
            else:
                lab_sc.append(rec.scales)
                lab_v.append(rec.labels)
        else:
            n_irr += 1
            irr_sc.append(rec.scales)
            irr_s.append(rec.scores)

    def cat(xs: list, dtype: Any) -> np.ndarray:
        return np.concatenate(xs).astype(dtype) if xs else np.zeros(0, dtype=dtype)

    st = ScaleStats(meta=dict(meta or {}), records=list(records))
    st.n_gt_pairs, st.n_irrelevant_pairs, st.n_unlabelled_pairs = n_gt, n_irr, n_unl
    st.n_matches, st.cls_gt, st.asl_gt = _cls_asl(cat(gt_sc, np.int64), cat(gt_s, np.float64))
    st.n_matches_irrelevant, st.cls_irrelevant, st.asl_irrelevant = _cls_asl(
        cat(irr_sc, np.int64), cat(irr_s, np.float64)
    )
    lsc, lv = cat(lab_sc, np.int64), cat(lab_v, bool)
    st.n_labelled = np.bincount(lsc, minlength=N_SCALES + 1)[: N_SCALES + 1].astype(np.int64)
    st.n_correct = np.bincount(lsc[lv], minlength=N_SCALES + 1)[: N_SCALES + 1].astype(np.int64)
    st.n_labelled[0] = st.n_correct[0] = 0
    cmr = _nan10()
    nz = st.n_labelled > 0
    cmr[nz] = st.n_correct[nz] / st.n_labelled[nz]
    st.cmr = cmr
    return st


def _query_records(
    dataset: Any,
    q: int,
    size_q: tuple[int, int],
    query: tuple[np.ndarray, np.ndarray],
    references: tuple[Sequence[np.ndarray], Sequence[np.ndarray]],
    pairs: list[tuple[int, bool]],
    matching: Matching,
    label_options: dict,
) -> list[MatchRecord]:
    """The :class:`MatchRecord` of query ``q`` (parsed boxes, descriptors) against each
    ``(r, is_gt)`` of ``pairs``; a ground-truth pair the labeller cannot label stays unlabelled."""
    bq, desc_q = query
    boxes_r, desc_r = references
    sc_q = scale_index_parsed(bq, size_q)
    records = []
    for r, is_gt in pairs:
        br = boxes_r[r]
        res = match_landmarks(desc_q, bq, desc_r[r], br, matching)
        mt = np.asarray(res.matches, dtype=np.int64).reshape(-1, 2)
        lab = None
        if is_gt:
            try:
                lab = label_matches_parsed(dataset, q, r, bq, br, mt, **label_options)
            except LabelUnavailableError as e:
                logger.warning("scale_statistics: pair (%d, %d) unlabelled: %s", q, r, e)
        records.append(
            MatchRecord(sc_q[mt[:, 0]], np.asarray(res.scores), lab, is_gt, q, r, matches=mt)
        )
    return records


def scale_statistics(
    dataset: Any,
    run: Any,
    *,
    label_method: str = "auto",
    n_irrelevant: int = 5,
    seed: int = 0,
    image_sizes: Sequence[tuple[int, int]] | None = None,
    queries: Sequence[int] | None = None,
    gt_pairs: str = "center",
    **label_options: Any,
) -> ScaleStats:
    """Fig. 4 scale statistics of any landmark method (docs/DEFINITIONS.md, "Scale statistics").

    ``run``: a :class:`~vpr_core.MethodResult` with its descriptors
    (``run_method(..., keep_descriptors=True)``), or any object with ``boxes`` and
    ``descriptors`` as ``{"query": [(K_i, 4)], "reference": [...]}`` / ``(K_i, D)``. Each query
    with ground truth is matched (:func:`vpr_core.matching.match_landmarks`, with the run's
    :class:`~vpr_core.matching.Matching` when it has one) with its ground-truth reference(s)
    (``gt_pairs``: :func:`ground_truth_references`), labelled by :func:`label_matches`
    (``label_method`` and ``**label_options``: ``iou_threshold``, ``labels``, ...), and with
    ``n_irrelevant`` query-irrelevant references sampled with ``seed``. Queries without ground
    truth are skipped; ``image_sizes`` per query ``(H, W)`` (default: asked from the dataset).
    """
    descriptors = check_descriptors_kept(run, "scale_statistics")
    boxes_q, boxes_r = run.boxes["query"], run.boxes["reference"]
    desc_q, desc_r = descriptors["query"], descriptors["reference"]
    config = getattr(run, "config", None)
    matching = getattr(config, "matching", None) or Matching()
    gt = np.asarray(dataset.ground_truth, dtype=bool)
    nq, nr = gt.shape
    sides = (("query", nq, boxes_q, desc_q), ("reference", nr, boxes_r, desc_r))
    for side, n, boxes, desc in sides:
        if len(boxes) != n or len(desc) != n:
            x = side[0]
            raise ValueError(
                f"boxes_{x}/desc_{x} need one entry per {side} ({n}), got {len(boxes)}/{len(desc)}"
            )
    if "method" in label_options:
        raise TypeError("scale_statistics takes the labeller as label_method=..., not method=...")
    boxes_q = [check_boxes(b, f"boxes_q[{i}]") for i, b in enumerate(boxes_q)]
    boxes_r = [check_boxes(b, f"boxes_r[{j}]") for j, b in enumerate(boxes_r)]
    labels = label_options.pop("labels", None)
    method = resolve_label_method(dataset, label_method, labels)
    rule = as_label_rule(label_options, method)
    if method == "file" and labels is not None and isinstance(labels, (str, PathLike)):
        labels = read_label_file(labels)
    if method == "geometric":
        label_options.setdefault("geometry_cache", {})
    qs = list(range(nq)) if queries is None else sorted(int(x) for x in queries)
    qs = [q for q in qs if gt[q].any()]
    irr = sample_irrelevant_references(gt, n_irrelevant, seed, qs)
    label_options = {
        "method": method,
        "rule": rule,
        "labels": labels,
        **label_options,
    }

    records: list[MatchRecord] = []
    for q in progress(qs, desc="scale statistics", unit="query"):
        size_q = (
            check_image_size(image_sizes[q], f"image_sizes[{q}]")
            if image_sizes is not None
            else dataset_image_size(dataset, "query", q)
        )
        pairs = [(r, True) for r in ground_truth_references(gt, q, gt_pairs)]
        pairs += [(r, False) for r in irr[q]]
        query = (boxes_q[q], desc_q[q])
        records += _query_records(
            dataset, q, size_q, query, (boxes_r, desc_r), pairs, matching, label_options
        )
    meta = {
        "dataset": getattr(dataset, "title", getattr(dataset, "name", None)),
        "label_method": method,
        "n_irrelevant": n_irrelevant,
        "seed": seed,
        "gt_pairs": gt_pairs,
        "soft_nms_iou": matching.soft_nms_iou,
        "iou_threshold": rule.iou_threshold,
        "tolerance": getattr(dataset, "tolerance", None),
        "ground_truth": ground_truth_text(
            gt,
            getattr(dataset, "tolerance", None),
            bool(getattr(dataset, "meta", {}).get("ground_truth_file")),
        ),
        "queries_with_gt": [int(gt.any(axis=1).sum()), int(gt.shape[0])],
    }
    return scale_statistics_from_matches(records, meta=meta)


def cmr_difference(
    matches: pd.DataFrame, n: int = N_BOOTSTRAP, seed: int = 0
) -> tuple[float, float, float]:
    """``(difference, low, high)``: CMR(Scales 5-7) - CMR(Scales 1-3) of the labelled
    ground-truth matches of a ``ScaleStats.matches_frame``, with its 95% interval bootstrapped
    over query images (all matches of a drawn query count)."""
    m = matches[(matches["pair"] == "gt") & matches["correct"].notna()]
    groups = {"small": m["scale"].between(1, 3), "large": m["scale"].between(5, 7)}
    if not all(g.any() for g in groups.values()):
        raise ValueError("cmr_difference needs labelled ground-truth matches at Scales 1-3 and 5-7")
    queries = np.unique(m["query"].to_numpy())
    qi = np.searchsorted(queries, m["query"].to_numpy())
    sums = {}
    for name, mask in groups.items():
        mask = mask.to_numpy()
        sums[name] = (
            np.bincount(qi[mask], weights=m["correct"].to_numpy()[mask], minlength=len(queries)),
            np.bincount(qi[mask], minlength=len(queries)).astype(float),
        )

    def diff(w: np.ndarray) -> np.ndarray:
        rates = {k: (w @ c) / np.maximum(w @ t, 1e-12) for k, (c, t) in sums.items()}
        return rates["large"] - rates["small"]

    point = float(diff(np.ones((1, len(queries))))[0])
    rng = np.random.default_rng(seed)
    draws = rng.integers(0, len(queries), size=(n, len(queries)))
    w = np.zeros((n, len(queries)))
    np.add.at(w, (np.repeat(np.arange(n), len(queries)), draws.ravel()), 1.0)
    lo, hi = np.percentile(diff(w), [2.5, 97.5])
    return point, float(lo), float(hi)
