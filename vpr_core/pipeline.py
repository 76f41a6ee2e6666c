"""Pipeline stages: landmarks -> features -> similarity matrix -> metrics, all cached on disk.

One stage, one function (hloc habit). Notebooks and the CLI call :func:`run_method`, which
chains :func:`extract_landmarks`, :func:`extract_features` and the matching/evaluation steps.

Caches (under :func:`vpr_core.utils.cache_root`):

- ``landmarks/edge_boxes-<hash>/<image key>.npz``: the 1,000 Edge Box candidates of one image
  with their scores, the edge-map source and the seconds it took. Every Edge Box scheme
  (classical, Algorithms 1-3) selects from these, so candidates are computed once per image.
- ``features/<encoder slug>/<image key>.npz``: a per-image store of ``(boxes, descriptors)``
  for one encoder config (backbone, input size, dim, seed, weights). Boxes are looked up row by
  row, so a new landmark config computes only the boxes it has not seen (resume), and the same
  config a second time reads everything from disk.
- ``results/<dataset>-<hash>/<method slug>.npz``: similarity matrices.
"""

from __future__ import annotations

import os
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from . import landmarks as lm
from .methods import EDGE_BOX_SCHEMES, get_method, landmark_config
from .utils import cache_dir, config_slug, logger, progress, short_hash

SIDES = ("query", "reference")


# --------------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------------
def _atomic_savez(path: Path, **arrays: Any) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(suffix=".npz", dir=path.parent)
    os.close(fd)
    try:
        np.savez(tmp, **arrays)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)


def dataset_fingerprint(dataset) -> str:
    """Short hash of a dataset's image contents and ground truth (cache key of results)."""
    keys = [dataset.image_key(s, i) for s in SIDES for i in range(_n(dataset, s))]
    gt = np.asarray(dataset.ground_truth, dtype=bool)
    return short_hash([dataset.name, keys, short_hash(gt.tobytes().hex()), list(gt.shape)])


def _n(dataset, side: str) -> int:
    return len(dataset.query_paths if side == "query" else dataset.reference_paths)


# --------------------------------------------------------------------------------------------
# landmarks
# --------------------------------------------------------------------------------------------
def edge_box_candidates(dataset, side: str, i: int, n_candidates: int = 1000,
                        overwrite: bool = False) -> tuple[np.ndarray, float]:
    """The ``n_candidates`` Edge Box proposals of one image, cached.

    Returns:
        ``(boxes (K, 4), seconds)``: proposals in proposal order (descending score) and the
        seconds the extraction took when it was computed.
    """
    params = {"n_candidates": int(n_candidates), "sed": os.environ.get("VPR_SED_MODEL", "")}
    folder = cache_dir("landmarks", config_slug("edge_boxes", params))
    path = folder / f"{dataset.image_key(side, i)}.npz"
    if path.exists() and not overwrite:
        with np.load(path) as z:
            return z["boxes"].astype(np.float64), float(z["seconds"])
    image = dataset.load_image(side, i)
    t0 = time.perf_counter()
    res = lm.edge_boxes(image, max_boxes=n_candidates)
    seconds = time.perf_counter() - t0
    _atomic_savez(path, boxes=np.asarray(res.boxes, dtype=np.float64),
                  scores=np.asarray(res.scores, dtype=np.float64),
                  edge_source=np.array(res.edge_source), seconds=np.array(seconds))
    return np.asarray(res.boxes, dtype=np.float64), seconds


def landmarks_for_image(conf: dict[str, Any], dataset, side: str, i: int
                        ) -> tuple[np.ndarray, float]:
    """Landmarks of one image for a method's landmark config.

    Returns:
        ``(boxes (K, 4), seconds)`` where seconds is the landmark-extraction cost of this image
        (Edge Box time for proposal schemes, the grid computation for ``dense``).
    """
    lconf = conf.get("landmarks", conf)
    scheme = lconf["scheme"]
    size = dataset.image_size(side, i)
    if scheme == "dense":
        t0 = time.perf_counter()
        boxes = lm.dense_sampling(size, scales=lconf["scales"], per_scale=lconf["per_scale"])
        return np.asarray(boxes, dtype=np.float64), time.perf_counter() - t0
    if scheme not in EDGE_BOX_SCHEMES:
        raise ValueError(f"Unknown landmark scheme {scheme!r}; valid: "
                         f"{', '.join(EDGE_BOX_SCHEMES + ('dense',))}.")
    cands, seconds = edge_box_candidates(dataset, side, i, lconf.get("n_candidates", 1000))
    options = {k: lconf[k] for k in ("n", "min_index", "order", "iou_threshold") if k in lconf}
    t0 = time.perf_counter()
    boxes = lm.select_from_candidates(cands, size, scheme, **options)
    seconds += time.perf_counter() - t0
    return np.asarray(boxes, dtype=np.float64).reshape(-1, 4), seconds


def extract_landmarks(conf: dict[str, Any], dataset) -> dict[str, Any]:
    """Landmarks of every image of a dataset.

    Returns:
        ``{"query": [ (K_i, 4) ... ], "reference": [...], "seconds": {"query": [...], ...}}``.
    """
    out: dict[str, Any] = {"seconds": {}}
    for side in SIDES:
        boxes, secs = [], []
        for i in progress(range(_n(dataset, side)), desc=f"landmarks {side}"):
            b, s = landmarks_for_image(conf, dataset, side, i)
            boxes.append(b)
            secs.append(s)
        out[side] = boxes
        out["seconds"][side] = secs
    return out


# --------------------------------------------------------------------------------------------
# features
# --------------------------------------------------------------------------------------------
def get_encoder(backbone: str = "efficientnet_lite0", dim: int = 1024, seed: int = 0,
                weights: str | None = None):
    """A shared :class:`~vpr_core.features.LandmarkEncoder` (model loading is the slow part).

    The same arguments return the same object, however they are passed.
    """
    return _cached_encoder(str(backbone), int(dim), int(seed), weights)


@lru_cache(maxsize=4)
def _cached_encoder(backbone: str, dim: int, seed: int, weights: str | None):
    from .features import LandmarkEncoder

    kwargs = {"backbone": backbone, "dim": dim, "seed": seed}
    if weights is not None:
        kwargs["weights"] = weights
    return LandmarkEncoder(**kwargs)


get_encoder.cache_clear = _cached_encoder.cache_clear  # type: ignore[attr-defined]


def _encoder_slug(encoder) -> str:
    cfg = dict(encoder.config)
    return config_slug(str(cfg.get("backbone", "encoder")), cfg)


def _box_keys(boxes: np.ndarray) -> list[bytes]:
    return [np.round(b, 3).astype(np.float64).tobytes() for b in np.asarray(boxes, dtype=float)]


def features_for_image(encoder, dataset, side: str, i: int, boxes: np.ndarray,
                       overwrite: bool = False) -> tuple[np.ndarray, float]:
    """Descriptors of ``boxes`` in one image, from the per-image store; computes what is missing.

    Returns:
        ``(desc (K, dim) float32, seconds)``: seconds is the recorded compute cost of these K
        descriptors (measured when they were computed, so cached runs report real costs).
    """
    folder = cache_dir("features", _encoder_slug(encoder))
    path = folder / f"{dataset.image_key(side, i)}.npz"
    boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    s_boxes = np.zeros((0, 4))
    s_desc = np.zeros((0, encoder.dim if encoder.dim else 0), np.float32)
    s_cost = np.zeros((0,))
    if path.exists() and not overwrite:
        with np.load(path) as z:
            s_boxes, s_desc, s_cost = z["boxes"], z["desc"], z["cost"]
    index = {k: j for j, k in enumerate(_box_keys(s_boxes))}
    keys = _box_keys(boxes)
    missing = [j for j, k in enumerate(keys) if k not in index]
    if missing:
        missing_unique = list(dict.fromkeys(keys[j] for j in missing))
        first = {k: j for j, k in reversed(list(enumerate(keys)))}
        new_boxes = boxes[[first[k] for k in missing_unique]]
        image = dataset.load_image(side, i)
        t0 = time.perf_counter()
        new_desc = encoder.encode(image, new_boxes)
        cost = (time.perf_counter() - t0) / max(len(new_boxes), 1)
        s_boxes = np.concatenate([s_boxes.reshape(-1, 4), new_boxes])
        s_desc = np.concatenate([s_desc.reshape(-1, new_desc.shape[1]), new_desc]).astype(
            np.float32)
        s_cost = np.concatenate([s_cost, np.full(len(new_boxes), cost)])
        _atomic_savez(path, boxes=s_boxes, desc=s_desc, cost=s_cost)
        index = {k: j for j, k in enumerate(_box_keys(s_boxes))}
    rows = [index[k] for k in keys]
    return s_desc[rows].astype(np.float32), float(s_cost[rows].sum())


def extract_features(boxes: dict[str, Any], dataset, encoder) -> dict[str, Any]:
    """Descriptors for every image's landmarks (cached per image and encoder config).

    Args:
        boxes: output of :func:`extract_landmarks`.
        dataset: a :class:`~vpr_core.datasets.PlaceDataset`.
        encoder: a :class:`~vpr_core.features.LandmarkEncoder`.

    Returns:
        ``{"query": [(K_i, D) float32 ...], "reference": [...], "seconds": {side: [...]}}``.
    """
    out: dict[str, Any] = {"seconds": {}}
    for side in SIDES:
        descs, secs = [], []
        for i in progress(range(_n(dataset, side)), desc=f"features {side}"):
            d, s = features_for_image(encoder, dataset, side, i, boxes[side][i])
            descs.append(d)
            secs.append(s)
        out[side] = descs
        out["seconds"][side] = secs
    return out


# --------------------------------------------------------------------------------------------
# methods
# --------------------------------------------------------------------------------------------
@dataclass
class MethodResult:
    """Everything one method produced on one dataset.

    Attributes:
        method: preset name; ``label``: a display label (e.g. ``"overlap_scheme1 t=0.4"``).
        config: the full method config; ``encoder``: the encoder config.
        similarity: ``(Nq, Nr)`` Eq. (1) similarities.
        ground_truth: ``(Nq, Nr)`` bool.
        boxes: ``{"query": [(K_i, 4)], "reference": [...]}``.
        metrics: AUC (ratio protocol), R@100P, R@1, R@5.
        timings: seconds per image for landmarks and features (recorded compute costs) and
            seconds per image pair for matching (measured in this run).
    """

    method: str
    label: str
    dataset: str
    config: dict
    encoder: dict
    similarity: np.ndarray
    ground_truth: np.ndarray
    boxes: dict
    metrics: dict
    timings: dict
    descriptors: dict | None = field(default=None, repr=False)

    def row(self) -> dict:
        """One table row: label, metrics (ratio-protocol AUC, R@100P, R@1, R@5) and costs."""
        t = self.timings
        return {"method": self.label, "AUC(ratio)": float(self.metrics["auc"]),
                "R@100P": float(self.metrics["r_at_100p"]), "R@1": float(self.metrics["r_at_1"]),
                "R@5": float(self.metrics["r_at_5"]),
                "landmarks/img": float(t["landmarks_per_image"]),
                "landmarks s/img": float(t["landmarks_s_per_image"]),
                "features s/img": float(t["features_s_per_image"]),
                "matching s/pair": float(t["matching_s_per_pair"])}

    def curve(self, protocol: str = "ratio"):
        """PR curve of this result under ``protocol``."""
        from .evaluation import pr_curve

        return pr_curve(self.similarity, self.ground_truth, protocol=protocol)


def method_label(conf: dict[str, Any]) -> str:
    """Short human label of a method config (used in legends and tables)."""
    name = conf["name"]
    lconf, mconf = conf["landmarks"], conf["matching"]
    if name == "overlap_scheme1":
        return f"{name} (IoU {lconf['iou_threshold']:g})"
    if name == "overlap_scheme2":
        return f"{name} (IoU {mconf['soft_nms_iou']:g})"
    if name == "dense" and (tuple(lconf["scales"]) != (0.16, 0.25, 0.36, 0.49)
                            or lconf["per_scale"] != 25):
        ps = lconf["per_scale"]
        ps = "/".join(str(p) for p in ps) if isinstance(ps, tuple) else str(ps)
        return f"dense ({'/'.join(f'{s:g}' for s in lconf['scales'])} x {ps})"
    return name


def run_method(method: str | dict, dataset, backbone: str = "efficientnet_lite0",
               dim: int = 1024, seed: int = 0, weights: str | None = None,
               keep_descriptors: bool = False, label: str | None = None,
               **overrides: Any) -> MethodResult:
    """Run a named method (or a config from :func:`~vpr_core.methods.get_method`) on a dataset.

    Args:
        method: preset name (``classical``, ``dense``, ...) or a config dict.
        dataset: a :class:`~vpr_core.datasets.PlaceDataset`.
        backbone, dim, seed, weights: the landmark encoder.
        keep_descriptors: also return the descriptors (needed by the scale statistics).
        label: display label; default from the config.
        **overrides: flat config overrides, e.g. ``iou_threshold=0.4``.

    Returns:
        A :class:`MethodResult`.
    """
    from .evaluation import evaluate
    from .matching import similarity_matrix

    conf = get_method(method, **overrides) if isinstance(method, str) else dict(method)
    encoder = get_encoder(backbone, dim, seed, weights)
    boxes = extract_landmarks(conf, dataset)
    feats = extract_features(boxes, dataset, encoder)

    key = {"dataset": dataset_fingerprint(dataset), "landmarks": landmark_config(conf),
           "matching": conf["matching"], "encoder": dict(encoder.config)}
    folder = cache_dir("results", f"{dataset.name}-{key['dataset']}")
    path = folder / f"{config_slug(conf['name'], key)}.npz"
    nq, nr = _n(dataset, "query"), _n(dataset, "reference")
    t0 = time.perf_counter()
    if path.exists():
        with np.load(path) as z:
            sim, match_s = z["similarity"], float(z["seconds_per_pair"])
    else:
        sim = similarity_matrix(feats["query"], boxes["query"], feats["reference"],
                                boxes["reference"], soft_nms_iou=conf["matching"]["soft_nms_iou"],
                                sigma=conf["matching"]["sigma"])
        match_s = (time.perf_counter() - t0) / max(nq * nr, 1)
        _atomic_savez(path, similarity=sim, seconds_per_pair=np.array(match_s))
    sim = np.asarray(sim, dtype=np.float64)
    gt = np.asarray(dataset.ground_truth, dtype=bool)
    metrics = evaluate(sim, gt)
    n_img = nq + nr
    timings = {
        "landmarks_s_per_image": float(sum(map(sum, boxes["seconds"].values())) / n_img),
        "features_s_per_image": float(sum(map(sum, feats["seconds"].values())) / n_img),
        "matching_s_per_pair": match_s,
        "landmarks_per_image": float(np.mean([len(b) for s in SIDES for b in boxes[s]])),
    }
    return MethodResult(
        method=conf["name"], label=label or method_label(conf), dataset=dataset.name,
        config=conf, encoder=dict(encoder.config), similarity=sim, ground_truth=gt,
        boxes={s: boxes[s] for s in SIDES}, metrics=metrics, timings=timings,
        descriptors={s: feats[s] for s in SIDES} if keep_descriptors else None,
    )


def run_methods(methods: Sequence[str | dict], dataset, **kwargs: Any) -> list[MethodResult]:
    """:func:`run_method` for several methods with shared caches; logs one line per method."""
    results = []
    for m in methods:
        r = run_method(m, dataset, **kwargs)
        logger.info("%s on %s: %s", r.label, dataset.name,
                    ", ".join(f"{k}={v:.3f}" for k, v in r.metrics.items()))
        results.append(r)
    return results
