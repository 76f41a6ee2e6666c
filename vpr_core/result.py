"""What a run produces: :class:`MethodResult`, and :func:`result_from_matrix`, the one door from a
similarity matrix to a result (a run's, a peer's, a normalised one's)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .cache import dataset_fingerprint
from .datasets.ground_truth import ground_truth_coverage, ground_truth_text
from .evaluation.bootstrap import format_interval, metrics_and_intervals
from .evaluation.chance import chance, chance_precision, saturation_notice
from .evaluation.curves import pr_curve
from .evaluation.spec import Evaluation
from .matching.normalise import normalise_matrix
from .matching.whiten import score_sign_notice
from .methods import Method, run_key
from .notices import notice

__all__ = [
    "INTERVAL_COLUMNS",
    "MethodResult",
    "constant_notice",
    "normalise_result",
    "result_from_matrix",
]


#: Interval columns of :meth:`MethodResult.row` (95% bootstrap over queries).
INTERVAL_COLUMNS = [
    "AUC lo",
    "AUC hi",
    "R@100P lo",
    "R@100P hi",
    "R@1 lo",
    "R@1 hi",
    "R@5 lo",
    "R@5 hi",
]


@dataclass
class MethodResult:
    """Everything one method produced on one dataset.

    Attributes:
        method: the method's name; ``label``: a display label (``"overlap_scheme1 (IoU 0.4)"``).
        config: the :class:`~vpr_core.methods.Method` (a peer: ``{"name", "source"}``);
            ``encoder``: the encoder config.
        similarity: ``(Nq, Nr)`` Eq. (1) similarities (NaN = not ranked: off the shortlist, or an
            image without landmarks).
        ground_truth: ``(Nq, Nr)`` bool.
        boxes: ``{"query": [(K_i, 4)], "reference": [...]}``.
        metrics: AUC (ratio protocol), R@100P, R@1, R@5.
        intervals: ``{"auc", "r@100p", "r@1", "r@5": (value, low, high)}``, 95% bootstrap over
            queries (:func:`~vpr_core.evaluation.bootstrap_metrics`, ``N_BOOTSTRAP`` resamples,
            seed 0).
        timings: seconds per image for landmarks and features (recorded compute costs), seconds
            per image pair for matching (measured when the matrix was computed) and the number
            of image pairs scored by Eq. (1).
        shortlist: None (exhaustive) or the k of shortlist + re-rank.
        queries_with_gt: ``(queries with ground truth, all queries)``.
        tolerance, root: the dataset's ground-truth tolerance, recorded when it was loaded, and
            its folder (tables and titles print them beside every number; ``compare`` names
            both tolerances of runs scored against different ground truths).
        dataset_title: the dataset as titles print it (:attr:`PlaceDataset.title
            <vpr_core.datasets.PlaceDataset.title>`: the name and a subset such as "every 50th
            place").
        ground_truth_from_file: the correct pairs were read from a file (titles then say
            "ground truth from file: ..." instead of "tolerance N").
        protocol: the PR protocol of ``metrics`` and ``intervals``.
        warnings: the warnings that change what the numbers mean (also raised with
            ``warnings.warn`` when they happened).
        dataset_fingerprint: hash of the dataset's image contents and ground truth
            (:func:`~vpr_core.cache.dataset_fingerprint`).
        weights_sha256: sha256 of the backbone weights' contents ("" when it has none).
        edge_model: the edge map of Edge Box schemes (``"gradient"`` or ``"sha256:..."``,
            :func:`~vpr_core.landmarks.edge_boxes.edge_model_id`), ``"none"`` for other schemes.
        soft_only: the dataset's soft-only pairs (:attr:`PlaceDataset.soft_only
            <vpr_core.datasets.PlaceDataset.soft_only>`: neither right nor wrong, so left out of
            the chance levels), None without soft ground truth.
    """

    method: str
    label: str
    dataset: str
    config: Method | dict
    encoder: dict
    similarity: np.ndarray = field(repr=False)
    ground_truth: np.ndarray = field(repr=False)
    boxes: dict = field(repr=False)
    metrics: dict = field(repr=False)
    timings: dict = field(repr=False)
    descriptors: dict | None = field(default=None, repr=False)
    intervals: dict = field(default_factory=dict, repr=False)
    shortlist: int | None = None
    queries_with_gt: tuple[int, int] = (0, 0)
    tolerance: Any = None
    root: str | None = None
    ground_truth_from_file: bool = False
    dataset_title: str = ""
    protocol: str = "ratio"
    warnings: list = field(default_factory=list)
    dataset_fingerprint: str = ""
    weights_sha256: str = ""
    edge_model: str = "none"
    soft_only: np.ndarray | None = field(default=None, repr=False)

    @property
    def run(self) -> str:
        """The configuration's identity (:func:`~vpr_core.methods.run_key`), e.g.
        ``"overlap_scheme1(iou_threshold=0.4)"``; peers: ``"peer:<name>"``."""
        return run_key(self.config) if isinstance(self.config, Method) else self.method

    def __repr__(self) -> str:
        """Method, dataset, metrics with intervals and the matrix shape (never the arrays)."""
        iv = ", ".join(f"{k} {format_interval(*v)}" for k, v in self.intervals.items())
        nq, nr = np.shape(self.similarity)
        return (
            f"MethodResult({self.label!r} on {self.dataset!r}, "
            f"{self.truth_text}, "
            f"{self.protocol}: {iv or 'no intervals'}; {self.queries_with_gt[0]} of "
            f"{self.queries_with_gt[1]} queries with ground truth, similarity {nq}x{nr}"
            + (f"; {len(self.warnings)} warning(s)" if self.warnings else "")
            + ")"
        )

    def row(self) -> dict:
        """One table row: label, run key, metrics with their 95% intervals, coverage, costs."""
        t, iv, m = self.timings, self.intervals, self.metrics
        row: dict = {"method": self.label, "run": self.run}
        for key, name in (("auc", "AUC"), ("r@100p", "R@100P"), ("r@1", "R@1"), ("r@5", "R@5")):
            value = m[key] if key in m else m[key.replace("@", "_at_")]
            lo, hi = (iv[key][1], iv[key][2]) if key in iv else (np.nan, np.nan)
            row[name], row[f"{name} lo"], row[f"{name} hi"] = float(value), float(lo), float(hi)
        row.update(
            {
                "queries": int(self.queries_with_gt[0]),
                "landmarks/img": float(t["landmarks_per_image"]),
                "landmarks s/img": float(t["landmarks_s_per_image"]),
                "features s/img": float(t["features_s_per_image"]),
                "matching s/pair": float(t["matching_s_per_pair"]),
                "pairs scored": float(t.get("pairs", np.nan)),
            }
        )
        return row

    def curve(self):
        """PR curve of this result under its own protocol (another: :func:`pr_curve` of its
        ``similarity`` and ``ground_truth``)."""
        return pr_curve(self.similarity, self.ground_truth, self.protocol, warn=False)

    @staticmethod
    def fields_of(dataset: Any) -> dict[str, Any]:
        """The :class:`MethodResult` fields a :class:`~vpr_core.datasets.PlaceDataset` gives: its
        name, ground truth (tolerance applied), soft-only pairs, tolerance, folder, title and
        fingerprint."""
        return {
            "dataset": dataset.name,
            "ground_truth": np.asarray(dataset.ground_truth, dtype=bool),
            "soft_only": dataset.soft_only,
            "tolerance": dataset.tolerance,
            "root": None if dataset.root is None else str(dataset.root),
            "ground_truth_from_file": bool(dataset.meta.get("ground_truth_file")),
            "dataset_title": dataset.title,
            "dataset_fingerprint": dataset_fingerprint(dataset),
        }

    @property
    def truth_text(self) -> str:
        """How its ground truth was made, as tables and titles print it (``"tolerance 2"``, or
        the file's correct references per query)."""
        return ground_truth_text(self.ground_truth, self.tolerance, self.ground_truth_from_file)

    def chance(self) -> dict[str, float]:
        """What a random ranking of its ground truth scores (:func:`~vpr_core.chance`, its
        protocol, R@1), and ``"precision"``: the flat PR curve of chance
        (:func:`~vpr_core.evaluation.chance.chance_precision`)."""
        out = chance(self.ground_truth, self.protocol, ks=(1,), soft=self.soft_only)
        return {
            **out,
            "precision": chance_precision(self.ground_truth, self.protocol, self.soft_only),
        }


def constant_notice(sim: np.ndarray) -> str | None:
    """The notice that a matrix ranks arbitrarily: it holds one value (NaN aside), or each query's
    row holds one value of its own; its metrics are then chance levels, whatever they read (e.g.
    zero descriptors, or constant ones weighted by ``contrast``, or a user's peer matrix);
    returns it (None: it ranks)."""
    if sim.size < 2 or np.isnan(sim).all():
        return None
    low, high = np.nanmin(sim), np.nanmax(sim)
    if low == high:
        return notice(
            f"the similarity matrix is constant (every value {float(low)!r}): its ranking is "
            "arbitrary, so its metrics are chance levels; check the backbone (its descriptors "
            "may all be equal or zero: compare encode() of two different images) and the "
            "matching options (weighting='contrast' scores identical descriptors 0), or a "
            "peer's matrix file"
        )
    ranked = np.isfinite(sim)
    rows = ranked.sum(axis=1) >= 2
    if rows.any():
        lo = np.where(ranked, sim, np.inf).min(axis=1)[rows]
        hi = np.where(ranked, sim, -np.inf).max(axis=1)[rows]
        if (lo == hi).all():
            return notice(
                f"each query's row of the similarity matrix is constant ({int(rows.sum())} "
                "rows, each one value of its own): no query ranks its references, so the "
                "metrics are chance levels; check the matrix (a peer's file: a per-query score "
                "repeated across the references?) or the method"
            )
    return None


def _normalise_of(config: Method | dict) -> str | None:
    """The whole-matrix step a result's configuration names (None: none)."""
    if isinstance(config, Method):
        return config.matching.normalise
    return config.get("normalise")


def _whiten_of(config: Method | dict) -> int | None:
    """The descriptor whitening a result's configuration names (None: none)."""
    if isinstance(config, Method):
        return config.matching.whiten
    return config.get("whiten")


def _unranked_empty(sim: np.ndarray, boxes: dict) -> np.ndarray:
    """NaN for every pair involving an image without landmarks (``boxes`` of both sides; a
    peer's are empty lists: nothing to exclude)."""
    nq, nr = sim.shape
    if len(boxes.get("query", [])) != nq or len(boxes.get("reference", [])) != nr:
        return sim
    empty_q = [i for i, b in enumerate(boxes["query"]) if len(b) == 0]
    empty_r = [i for i, b in enumerate(boxes["reference"]) if len(b) == 0]
    if not (empty_q or empty_r):
        return sim
    sim = sim.copy()
    sim[empty_q, :] = np.nan
    sim[:, empty_r] = np.nan
    return sim


def result_from_matrix(
    similarity: np.ndarray,
    result: MethodResult,
    evaluation: Evaluation,
    database: np.ndarray | None = None,
) -> MethodResult:
    """The one door from a similarity matrix to a result: ``result`` (what made the matrix: its
    method, configuration, encoder, boxes, and :meth:`MethodResult.fields_of` its dataset) with
    ``similarity`` scored.

    In order: the whole-matrix step its configuration names (``normalise``, by
    :func:`~vpr_core.matching.normalise.normalise_matrix`; ``database``: the ``(Nr, Nr)``
    references against each other where the step needs them), images without landmarks
    unranked (NaN), soft-only pairs neither right nor wrong, the constant-matrix, whitened
    score-sign and saturation notices (added to ``warnings``), then metrics and intervals
    under ``evaluation``.

    Args:
        similarity: ``(Nq, Nr)`` as the method produced it (NaN: not ranked).
        result: a :class:`MethodResult` whose identity and dataset fields are set; its
            matrix, metrics and intervals are replaced.
        evaluation: the protocol and bootstrap resamples.
        database: see above.
    """
    sim = normalise_matrix(similarity, _normalise_of(result.config), database=database)
    sim = _unranked_empty(np.asarray(sim, dtype=np.float64), result.boxes)
    if result.soft_only is not None and not np.isnan(sim).all():
        sim = np.array(sim, dtype=np.float64)  # VPR_Tutorial's rule: soft-only pairs at the min
        sim[result.soft_only] = np.nanmin(sim)
    gt = np.asarray(result.ground_truth, dtype=bool)
    notices = [constant_notice(sim)]
    if _whiten_of(result.config) is not None:  # (not in the paper) centred cosines: scores <= 0
        notices.append(score_sign_notice(sim, gt, evaluation.protocol))
    metrics, intervals = metrics_and_intervals(sim, gt, evaluation)
    notices.append(
        saturation_notice(
            gt, intervals, evaluation, soft=result.soft_only, tolerance=result.tolerance
        )
    )
    return dataclasses.replace(
        result,
        similarity=sim,
        metrics=metrics,
        intervals=intervals,
        protocol=evaluation.protocol,
        queries_with_gt=ground_truth_coverage(gt),
        warnings=list(dict.fromkeys([*result.warnings, *(n for n in notices if n)])),
    )


def normalise_result(
    result: MethodResult,
    how: str,
    database: np.ndarray | None = None,
    evaluation: Evaluation | None = None,
    label: str | None = None,
) -> MethodResult:
    """(Not in the paper.) A result with its matrix normalised (any method's or a peer's;
    docs/DEFINITIONS.md), through :func:`result_from_matrix` on the same ground truth.

    Args:
        result: a :class:`MethodResult` (``run_method`` or :func:`vpr_study.peer_result`), not
            normalised yet.
        how: a name of :data:`~vpr_core.matching.normalise.NORMALISATIONS`; ``"query_batch"``
            needs the batch of queries (``compare`` marks it).
        database: ``(Nr, Nr)`` the references scored against each other by the same technique
            (``"database"`` only; for a peer from descriptors: ``peer_from_descriptors(db, db)``).
        evaluation: protocol and resamples (default: the result's protocol, ``N_BOOTSTRAP``
            resamples where it has intervals, else none).
        label: default ``"<label> (normalised: <how>)"``.
    """
    done = _normalise_of(result.config)
    if done is not None:
        raise ValueError(
            f"{result.label!r} is already normalised ({done!r}): normalise the result it was "
            "made from"
        )
    if isinstance(result.config, Method):
        matching = dataclasses.replace(result.config.matching, normalise=how)
        config: Method | dict = dataclasses.replace(result.config, matching=matching)
    else:
        config = {**dict(result.config), "normalise": how}
    n_boot = len(result.intervals) and Evaluation().n_bootstrap
    evaluation = evaluation or Evaluation(protocol=result.protocol, n_bootstrap=n_boot)
    named = dataclasses.replace(
        result, label=label or f"{result.label} (normalised: {how})", config=config
    )
    return result_from_matrix(result.similarity, named, evaluation, database=database)
