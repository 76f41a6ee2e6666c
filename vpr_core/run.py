"""One method on one dataset: landmarks -> features -> Eq. (1) matrix -> metrics; the matrix is
cached in ``results/<dataset>-<fingerprint>/``. An image without landmarks is excluded from
ranking (its pairs are NaN), never scored as zeros."""

from __future__ import annotations

import dataclasses
import functools
import time
import warnings
from collections.abc import Callable, Sequence
from typing import Any, ParamSpec, Protocol

import numpy as np

from .cache import SIDES, atomic_savez, images_fingerprint, load_npz, n_images
from .checks import check_int
from .evaluation.spec import Evaluation, refuse_tolerance
from .executor import check_executor, checked_matrix, checked_pairs
from .features import Encoder, as_encoder
from .features.stage import extract_features, get_encoder
from .landmarks.edge_boxes import edge_model_id
from .landmarks.schemes import CandidateScheme, LandmarkScheme
from .landmarks.stage import extract_landmarks
from .matching.normalise import NORMALISATIONS
from .matching.shortlist import (
    rerank,
    shortlist_pairs,
    split_whole_image,
    with_whole_image_boxes,
)
from .matching.similarity import similarity_matrix, similarity_pairs
from .matching.weighting import WEIGHTINGS
from .matching.whiten import DESCRIPTOR_STEPS
from .methods import Matching, Method, as_method, default_label
from .notices import VPRWarning, notice
from .result import MethodResult, result_from_matrix
from .utils import array_sha256, cache_dir, code_version, config_slug, logger

P = ParamSpec("P")

__all__ = ["Executor", "run_method"]


class Executor(Protocol):
    """Where the two heavy stages run when not in-process (``run_method(..., executor=)``): the
    Dask executor of :mod:`vpr_study.cluster` is one. Each method returns what its in-process
    counterpart returns, exactly; the caller owns the value (opens and closes it)."""

    def encode(
        self, dataset: Any, side: str, encoder_kwargs: dict, indices: list[int], boxes: list
    ) -> tuple[list, list]:
        """Descriptors ``[(K_i, D)]`` and seconds of images ``indices`` of ``side``."""
        ...

    def similarity_matrix(
        self,
        query_desc: Sequence,
        query_boxes: Sequence,
        reference_desc: Sequence,
        reference_boxes: Sequence,
        matching: Matching,
    ) -> np.ndarray:
        """``(Nq, Nr)`` Eq. (1), as :func:`~vpr_core.matching.similarity_matrix` (with
        ``whiten``, the descriptors come whitened and ``matching`` has no ``whiten``)."""
        ...

    def similarity_pairs(
        self,
        query_desc: Sequence,
        query_boxes: Sequence,
        reference_desc: Sequence,
        reference_boxes: Sequence,
        pairs: np.ndarray,
        matching: Matching,
    ) -> np.ndarray:
        """``(P,)`` Eq. (1) of listed pairs, as :func:`~vpr_core.matching.similarity_pairs`."""
        ...


def _empty_notice(boxes: dict, dataset) -> None:
    """The notice naming every image without landmarks (:func:`~vpr_core.result.result_from_matrix`
    leaves their pairs unranked, NaN, never scored as zeros)."""
    empty = {s: [i for i, b in enumerate(boxes[s]) if len(b) == 0] for s in SIDES}
    names = [
        f"{s} {i} ({(dataset.query_paths if s == 'query' else dataset.reference_paths)[i]})"
        for s in SIDES
        for i in empty[s]
    ]
    if names:
        notice(
            f"no landmarks in {len(names)} image(s), excluded from ranking (their pairs count "
            f"as not retrieved): {'; '.join(names[:10])}{' ...' if len(names) > 10 else ''}"
        )


def _check_shortlist(shortlist: Any, n_ref: int) -> int | None:
    """``shortlist`` (None: exhaustive, or k references re-ranked per query) as an int, or None
    where k covers every reference."""
    if shortlist is None:
        return None
    shortlist = check_int(shortlist, "shortlist", 1)
    if shortlist == 1:
        logger.warning(
            "shortlist=1 leaves no second-best reference: the ratio protocol then "
            "sets S2 := S1 (ratio 1); use k >= 2"
        )
    return shortlist if shortlist < n_ref else None  # k >= Nr is exhaustive


def _features(boxes: dict, dataset, encoder, shortlist: int | None, executor):
    """Landmark descriptors (and whole-image descriptors when a shortlist needs them)."""
    if shortlist is None:
        return extract_features(boxes, dataset, encoder, executor=executor), None
    feats = extract_features(
        with_whole_image_boxes(boxes, dataset), dataset, encoder, executor=executor
    )
    return split_whole_image(feats)


def _match(
    boxes: dict[str, Any],
    feats: dict[str, Any],
    matching: Matching | None = None,
    shortlist: int | None = None,
    global_desc: dict[str, np.ndarray] | None = None,
    executor: Executor | None = None,
) -> tuple[np.ndarray, dict[str, float]]:
    """Eq. (1) similarities: exhaustive in-process (the paper's path: one
    :func:`~vpr_core.matching.similarity_matrix` call), or on each query's shortlist, or on an
    :class:`Executor`.

    Args:
        boxes: ``{"query": [(K_i, 4)], "reference": [...]}`` landmarks.
        feats: ``{"query": [(K_i, D)], "reference": [...]}`` descriptors.
        matching: the :class:`~vpr_core.methods.Matching` settings (Algorithm 4, geometry and
            weighting options); None: Eq. (1) as the paper.
        shortlist: None (exhaustive) or k: Eq. (1) only on each query's top-k references by
            the cosine of ``global_desc``.
        global_desc: ``{"query": (Nq, D'), "reference": (Nr, D')}`` whole-image descriptors
            (needed with ``shortlist``).
        executor: an :class:`Executor`, or None (in-process).

    Returns:
        ``(similarity (Nq, Nr) float64, info)``: NaN off the shortlist; ``info`` has
        ``pairs`` (image pairs scored by Eq. (1)), ``shortlist_s`` (global ranking seconds) and
        ``matching_s`` (Eq. (1) seconds).
    """
    matching = matching or Matching()
    args = (feats["query"], boxes["query"], feats["reference"], boxes["reference"])
    nq, nr = len(feats["query"]), len(feats["reference"])
    t0 = time.perf_counter()
    if shortlist is None:
        if executor is None:  # the paper's path
            sim = similarity_matrix(*args, matching=matching)
        else:
            sim = executor.similarity_matrix(*args, matching)
        seconds = time.perf_counter() - t0
        if executor is not None:  # checked before the cache keeps it: a sample recomputed here
            sim = checked_matrix(executor, sim, args, matching)
        return sim, {"pairs": float(nq * nr), "shortlist_s": 0.0, "matching_s": seconds}
    if global_desc is None:
        raise ValueError("shortlist=k needs the whole-image descriptors (global_desc)")

    pairs, _ = shortlist_pairs(global_desc["query"], global_desc["reference"], shortlist)
    t1 = time.perf_counter()
    if executor is None:
        sim = rerank(similarity_pairs(*args, pairs, matching), pairs, nq, nr)
        t2 = time.perf_counter()
    else:  # an executor's values, checked before the cache keeps them
        vals = executor.similarity_pairs(*args, pairs, matching)
        t2 = time.perf_counter()
        sim = rerank(checked_pairs(executor, vals, args, pairs, matching), pairs, nq, nr)
    logger.info(
        "shortlist k=%d: Eq. (1) on %d of %d pairs (%.1f s ranking, %.1f s matching)",
        shortlist,
        len(pairs),
        nq * nr,
        t1 - t0,
        t2 - t1,
    )
    return sim, {"pairs": float(len(pairs)), "shortlist_s": t1 - t0, "matching_s": t2 - t1}


def _cached_matrix(
    folder, name: str, key: dict, shape: tuple[int, int], compute: Callable
) -> tuple[np.ndarray, float, float, bool]:
    """``(similarity, seconds per pair, pairs, read from the cache)`` of the matrix ``key``
    names: read from ``folder`` or computed by ``compute()`` and stored."""
    path = folder / f"{config_slug(name, key)}.npz"
    identity = f"results {path.parent.name} {path.stem}"

    def check(a: dict) -> str | None:
        got = a["similarity"].shape
        return (
            None
            if got == shape
            else f"a similarity matrix of shape {got}, expected {shape} for this dataset"
        )

    cached = load_npz(
        path, ("similarity", "seconds_per_pair", "pairs"), identity=identity, check=check
    )
    if cached is not None:
        return (
            cached["similarity"],
            float(cached["seconds_per_pair"]),
            float(cached["pairs"]),
            True,
        )
    sim, match_s, n_pairs = compute()
    atomic_savez(
        path,
        identity=identity,
        similarity=sim,
        seconds_per_pair=np.array(match_s),
        pairs=np.array(n_pairs),
    )
    return sim, float(match_s), float(n_pairs), False


def _plain_matching(matching: Matching) -> Matching:
    """What the matcher (and an executor) gets: the run's :class:`Matching` without its
    whole-matrix step (``normalise``, applied to the result) and its descriptor steps
    (:data:`~vpr_core.matching.whiten.DESCRIPTOR_STEPS`, applied to the descriptors before)."""
    off: dict[str, Any] = {field: None for field in DESCRIPTOR_STEPS}
    return dataclasses.replace(matching, normalise=None, **off)


def _database_matrix(
    conf: Method, folder, key: dict, boxes: dict, feats: dict, k: int | None, glob, executor
) -> np.ndarray | None:
    """(Not in the paper.) The ``(Nr, Nr)`` references scored against each other by the same
    matching and shortlist (cached like Eq. (1)), for a normalisation that needs the database;
    None for any other."""
    how = conf.matching.normalise
    if how is None or not NORMALISATIONS[how].needs_database:
        return None
    ref = {s: boxes["reference"] for s in SIDES}
    ref_feats = {s: feats["reference"] for s in SIDES}
    ref_glob = None if glob is None else {s: glob["reference"] for s in SIDES}
    nr = len(feats["reference"])
    kk = None if k is None or k >= nr else k
    plain = _plain_matching(conf.matching)

    def compute() -> tuple[np.ndarray, float, float]:
        db, info = _match(ref, ref_feats, plain, kk, ref_glob, executor)
        return (
            db,
            (info["matching_s"] + info["shortlist_s"]) / max(info["pairs"], 1),
            info["pairs"],
        )

    db_key = {**key, "database_self": True}
    return _cached_matrix(folder, f"{conf.name}-database", db_key, (nr, nr), compute)[0]


def _from_cache(wall: float, recorded: float) -> bool:
    """Whether a stage that took ``wall`` seconds in this call, and whose cached entries record
    ``recorded`` seconds of computation, was read from the cache (under half the time)."""
    return recorded > 0 and wall < 0.5 * recorded


def _records_warnings(run: Callable[P, MethodResult]) -> Callable[P, MethodResult]:
    """Hand every warning of ``run`` on to the caller's filters and record the
    :class:`~vpr_core.notices.VPRWarning` ones on the result (``.warnings``)."""

    @functools.wraps(run)
    def wrapper(*args: P.args, **kwargs: P.kwargs) -> MethodResult:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", VPRWarning)
            result = run(*args, **kwargs)
        for w in caught:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        result.warnings = list(
            dict.fromkeys(str(w.message) for w in caught if issubclass(w.category, VPRWarning))
        )
        return result

    return wrapper


def _values(
    method: Any, encoder: Encoder | None, evaluation: Evaluation | None, overrides: dict
) -> tuple[Method, Encoder, Evaluation]:
    """``run_method``'s arguments parsed once into its three values: the keyword overrides
    that are :class:`~vpr_core.features.Encoder` or :class:`~vpr_core.evaluation.Evaluation`
    fields change those values (given or default); the rest are the method's options. A
    ``tolerance`` is refused naming the fix (it is the dataset's)."""
    refuse_tolerance(overrides, "run_method")
    parts: dict[type, dict[str, Any]] = {Encoder: {}, Evaluation: {}}
    for cls, found in parts.items():
        names = {f.name for f in dataclasses.fields(cls)}
        found.update({k: overrides.pop(k) for k in list(overrides) if k in names})
    return (
        as_method(method, **overrides),
        as_encoder(encoder, **parts[Encoder]),  # one Encoder made (and checked)
        dataclasses.replace(evaluation or Evaluation(), **parts[Evaluation]),
    )


@_records_warnings
def run_method(
    method: str | Method | LandmarkScheme,
    dataset,
    *,
    encoder: Encoder | None = None,
    evaluation: Evaluation | None = None,
    shortlist: int | None = None,
    executor: Executor | None = None,
    label: str | None = None,
    keep_descriptors: bool = False,
    **overrides: Any,
) -> MethodResult:
    """Run a method on a dataset: landmarks -> features -> Eq. (1) matrix -> metrics, cached.

    A run is three values, parsed and checked here before any work: the
    :class:`~vpr_core.methods.Method`, the :class:`~vpr_core.features.Encoder` and the
    :class:`~vpr_core.evaluation.Evaluation`; the stages receive them.

    Args:
        method: a preset name (``classical``, ``dense``, ``global``, ...), a
            :class:`~vpr_core.methods.Method`, or a bare landmark scheme (any frozen dataclass
            with ``boxes(image)``; see :func:`~vpr_core.methods.as_method`).
        dataset: a :class:`~vpr_core.datasets.PlaceDataset`.
        encoder: the landmark encoder (default ``Encoder()``: ``efficientnet_lite0``, ``crop``
            pooling, the paper's projection); ``backbone=``, ``weights=``, ``pooling=``,
            ``input_size=``, ``device=``, ``dim=``, ``seed=`` given as keywords change it.
        evaluation: the PR protocol and bootstrap resamples (default ``Evaluation()``: the
            paper's ``ratio`` protocol, ``N_BOOTSTRAP`` resamples); ``protocol=`` and
            ``n_bootstrap=`` given as keywords change it. R@K is protocol-free. The ground truth
            is the dataset's as loaded (its ``tolerance``): the Eq. (1) matrix cache is keyed by
            the images, landmarks, descriptors and ``Matching``, not by the ground truth, so a
            tolerance sweep (the dataset loaded again, or ``ds.with_tolerance(N)``) reuses every
            matrix; ``tolerance=`` here is refused naming that fix.
        shortlist: None (exhaustive, the paper's) or k: each query's top-k references by the
            cosine of whole-image descriptors (same backbone and pooling) are re-ranked by
            Eq. (1); all other pairs are NaN ("not ranked"; the ratio protocol's S2 is the
            second best inside the shortlist). k >= the number of references is exhaustive.
        executor: where extraction and matching run: an :class:`Executor` value (e.g.
            :class:`vpr_study.cluster.DaskExecutor` on a Dask cluster; the caller opens and
            closes it), or None: in-process, always. The numbers are the same either way:
            what it returns is checked, a sample recomputed here, before any cache keeps it
            (:mod:`vpr_core.executor`).
        label: display label; default from the config (:func:`~vpr_core.methods.default_label`:
            the method, its options, and a backbone module's class).
        keep_descriptors: also return the descriptors (needed by the scale statistics); with
            ``whiten=k`` the whitened ones, those Eq. (1) saw.
        **overrides: the encoder and evaluation fields above, and the method's own options:
            its scheme's (e.g. ``iou_threshold=0.4``, ``scales=``, ``per_scale=``) and its
            :class:`~vpr_core.Matching`'s, on every method: ``soft_nms_iou=`` (Algorithm 4),
            and, not in the paper (off by default; docs/DEFINITIONS.md): ``spatial=
            "consistency"``, ``weighting=`` a name of :data:`~vpr_core.WEIGHTINGS`
            (``"contrast"``, ``"idf"``, ``"two_sided"``), ``normalise=`` a name of
            :data:`~vpr_core.NORMALISATIONS` (``"query_batch"``: needs the batch of queries;
            ``"database"``), ``whiten=k`` (the landmark descriptors of both sides whitened on
            the reference database before Eq. (1), once, here; the shortlist's whole-image
            descriptors are not; :data:`~vpr_core.WHITEN_K` is the recipe's). An option the
            method does not take is an error naming the valid ones.

    Returns:
        A :class:`MethodResult`; ``.warnings`` lists every warning of the run that changes what
        its numbers mean (each also raised as a :class:`~vpr_core.notices.VPRWarning`).
    """
    conf, spec, evaluation = _values(method, encoder, evaluation, overrides)
    executor = None if executor is None else check_executor(executor)
    nq, nr = n_images(dataset, "query"), n_images(dataset, "reference")
    k = _check_shortlist(shortlist, nr)
    landmark_encoder = get_encoder(spec)
    images = images_fingerprint(dataset)  # the matrix cache's folder: not the ground truth
    weights_sha256 = str(landmark_encoder.config.get("weights_sha256", ""))
    edge_model = edge_model_id() if isinstance(conf.landmarks, CandidateScheme) else "none"
    t_stage = time.perf_counter()
    boxes = extract_landmarks(conf.landmarks, dataset)
    wall_lm = time.perf_counter() - t_stage
    feats, glob = _features(boxes, dataset, landmark_encoder, k, executor)
    wall_ft = time.perf_counter() - t_stage - wall_lm
    for field, step in DESCRIPTOR_STEPS.items():  # (not in the paper) e.g. whiten=k
        if (value := getattr(conf.matching, field)) is not None:
            q_d, r_d, _ = step(feats["query"], feats["reference"], value)
            feats = {**feats, "query": q_d, "reference": r_d}
    # keyed by what goes in: the images (folder), the boxes and descriptors (content), the
    # Matching value; not the ground truth, so another tolerance reuses the matrix
    inputs = [
        a for side in SIDES for pair in zip(boxes[side], feats[side], strict=True) for a in pair
    ]
    if glob is not None:
        inputs += [glob[side] for side in SIDES]
    # the normalisation (not in the paper) is a step after the matrix: the Eq. (1) matrix is
    # cached without it, so every normalisation of a method reuses it; a descriptor step (not in
    # the paper, e.g. the whitening) was applied above, so the matcher (and an executor) get a
    # Matching without it and the key names it only when it is set (a key without it is as
    # before it existed)
    plain = _plain_matching(conf.matching)
    key = {
        "inputs": array_sha256(inputs),
        "matching": {
            f: v for f, v in dataclasses.asdict(plain).items() if f not in DESCRIPTOR_STEPS
        },
        "shortlist": k,
        "code": code_version("matching"),
    }
    if plain.weighting is not None and (own := WEIGHTINGS[plain.weighting].identity()):
        key["weighting code"] = own  # a weighting defined outside the package, by its code
    for field in DESCRIPTOR_STEPS:  # (not in the paper) a step on the descriptors, when set
        if getattr(conf.matching, field) is not None:
            key[field] = getattr(conf.matching, field)
    folder = cache_dir("results", f"{dataset.name}-{images}")

    def compute() -> tuple[np.ndarray, float, float]:
        sim, info = _match(boxes, feats, plain, shortlist=k, global_desc=glob, executor=executor)
        return (
            sim,
            (info["matching_s"] + info["shortlist_s"]) / max(info["pairs"], 1),
            info["pairs"],
        )

    sim, match_s, n_pairs, cached = _cached_matrix(folder, conf.name, key, (nq, nr), compute)
    database = _database_matrix(conf, folder, key, boxes, feats, k, glob, executor)
    n_img = nq + nr
    timings = {
        "landmarks_s_per_image": float(sum(map(sum, boxes["seconds"].values())) / n_img),
        "features_s_per_image": float(sum(map(sum, feats["seconds"].values())) / n_img),
        "matching_s_per_pair": match_s,
        "landmarks_per_image": float(np.mean([len(b) for s in SIDES for b in boxes[s]])),
        "pairs": n_pairs,
    }
    earlier = [
        stage
        for stage, wall, key in (
            ("landmarks", wall_lm, "landmarks_s_per_image"),
            ("features", wall_ft, "features_s_per_image"),
        )
        if _from_cache(wall, timings[key] * n_img)
    ]
    _empty_notice(boxes, dataset)
    made = MethodResult(
        method=conf.name,
        label=label or default_label(conf, landmark_encoder.config),
        config=conf,
        encoder=dict(landmark_encoder.config),
        similarity=sim,
        boxes={s: boxes[s] for s in SIDES},
        metrics={},
        timings=timings,
        descriptors={s: feats[s] for s in SIDES} if keep_descriptors else None,
        shortlist=k,
        weights_sha256=weights_sha256,
        edge_model=edge_model,
        **MethodResult.fields_of(dataset),
    )
    result = result_from_matrix(sim, made, evaluation, database=database)
    logger.info(
        "%s on %s: %d images, %.0f landmarks/img; landmarks %.2f s/img, features %.3f "
        "s/img%s, Eq. (1) on %d pairs%s; AUC(%s) %.3f, R@1 %.3f",
        result.label,
        dataset.name,
        n_img,
        timings["landmarks_per_image"],
        timings["landmarks_s_per_image"],
        timings["features_s_per_image"],
        f" ({' and '.join(earlier)} cached: the seconds of the earlier run that computed them)"
        if earlier
        else "",
        int(n_pairs),
        " (read from the cache)" if cached else "",
        evaluation.protocol,
        result.metrics["auc"],
        result.metrics["r@1"],
    )
    return result
