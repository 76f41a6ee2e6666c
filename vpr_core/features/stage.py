"""Feature stage: landmark descriptors of every image, in per-image stores
``features/<encoder slug>/<image key>.npz`` of ``(boxes, descriptors)`` keyed on the encoder's
config (weights by content); new boxes are computed and appended, known ones read (resume)."""

from __future__ import annotations

import time
from functools import lru_cache
from typing import Any, cast

import numpy as np
import torch
from torch import nn

from ..backbones import weights_sha256
from ..cache import SIDES, atomic_savez, load_npz, n_images
from ..executor import checked_encoding
from ..utils import cache_dir, code_version, config_slug, progress
from .encoder import Encoder, LandmarkEncoder, as_encoder

__all__ = ["encoder_slug", "extract_features", "get_encoder"]


def get_encoder(
    encoder: Encoder | str | nn.Module | None = None, **options: Any
) -> LandmarkEncoder:
    """A :class:`~vpr_core.features.LandmarkEncoder` for an :class:`~vpr_core.features.Encoder`
    (or a backbone with the other fields as ``**options``), shared between calls with the same
    value while the weights file's sha256 (read on every call) is the same; a module backbone
    gets a fresh encoder (its identity is measured when it is built)."""
    spec = as_encoder(encoder, **options)
    if isinstance(spec.backbone, nn.Module):
        return LandmarkEncoder(spec)
    return _cached_encoder(spec, weights_sha256(spec.parsed_backbone, spec.weights))


@lru_cache(maxsize=4)
def _cached_encoder(spec: Encoder, sha256: str) -> LandmarkEncoder:
    return LandmarkEncoder(spec)


get_encoder.cache_clear = _cached_encoder.cache_clear  # type: ignore[attr-defined]


def encoder_slug(encoder: LandmarkEncoder) -> str:
    """Cache folder of an encoder: its config (weights by ``weights_sha256``, never by path)."""
    cfg = dict(encoder.config)
    cfg.pop("device", None)  # the device does not change the cached descriptors' meaning
    cfg["code"] = code_version("features")
    return config_slug(str(cfg.get("backbone", "encoder")), cfg)


def _box_keys(boxes: np.ndarray) -> list[bytes]:
    """One hashable key per box row: the bytes of the row rounded to 1e-3 pixel (float64).

    Vectorised (one round over the array, rows viewed as 32-byte records): the stores grow to
    thousands of rows per image and are keyed on every lookup.
    """
    rounded = np.ascontiguousarray(np.round(np.asarray(boxes, dtype=np.float64).reshape(-1, 4), 3))
    return cast(
        list[bytes], rounded.view(np.dtype((np.void, rounded.itemsize * 4))).ravel().tolist()
    )


def _store_path(encoder, dataset, side: str, i: int):
    return cache_dir("features", encoder_slug(encoder)) / f"{dataset.image_key(side, i)}.npz"


def _store_identity(path) -> str:
    """What a per-image store holds: the encoder slug (its folder) and the image key (its name)."""
    return f"features {path.parent.name} {path.stem}"


def _read_store(path, dim: int, overwrite: bool = False):
    """``(boxes (S, 4), desc (S, dim), cost (S,))`` of a per-image store (empty if absent);
    ``desc`` memory-mapped: a run reads only the rows of its own boxes."""

    def check(a: dict) -> str | None:
        b, d, c = a["boxes"], a["desc"], a["cost"]
        if b.ndim != 2 or b.shape[1] != 4:
            return f"boxes of shape {b.shape}, expected (S, 4)"
        if d.ndim != 2 or (dim and d.shape[1] != dim):
            return f"descriptors of shape {d.shape}, expected (S, {dim or 'D'})"
        if not len(b) == len(d) == len(c):
            return f"{len(b)} boxes, {len(d)} descriptors and {len(c)} costs"
        return None

    stored = (
        None
        if overwrite
        else load_npz(
            path,
            ("boxes", "desc", "cost"),
            identity=_store_identity(path),
            check=check,
            mapped=("desc",),
        )
    )
    if stored is None:
        return np.zeros((0, 4)), np.zeros((0, dim), np.float32), np.zeros((0,))
    return stored["boxes"].reshape(-1, 4), stored["desc"], stored["cost"]


def _missing_boxes(s_boxes: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """The distinct rows of ``boxes`` not in the store, in first-occurrence order."""
    index = set(_box_keys(s_boxes))
    keys = _box_keys(boxes)
    first = {k: j for j, k in reversed(list(enumerate(keys)))}
    missing = [k for k in dict.fromkeys(keys) if k not in index]
    return boxes[[first[k] for k in missing]].reshape(-1, 4)


def _add_to_store(path, store, new_boxes: np.ndarray, new_desc: np.ndarray, seconds: float):
    """Append freshly computed rows to a store and write it atomically; returns the store."""
    s_boxes, s_desc, s_cost = store
    cost = seconds / max(len(new_boxes), 1)
    s_boxes = np.concatenate([s_boxes.reshape(-1, 4), new_boxes])
    s_desc = np.concatenate([s_desc.reshape(-1, new_desc.shape[1]), new_desc]).astype(np.float32)
    s_cost = np.concatenate([s_cost, np.full(len(new_boxes), cost)])
    atomic_savez(path, identity=_store_identity(path), boxes=s_boxes, desc=s_desc, cost=s_cost)
    return s_boxes, s_desc, s_cost


def _rows(store, boxes: np.ndarray) -> tuple[np.ndarray, float]:
    s_boxes, s_desc, s_cost = store
    index = {k: j for j, k in enumerate(_box_keys(s_boxes))}
    rows = np.array([index[k] for k in _box_keys(boxes)], dtype=np.int64)
    return np.array(s_desc[rows], dtype=np.float32), float(s_cost[rows].sum())


def _features_for_image(
    encoder, dataset, side: str, i: int, boxes: np.ndarray, overwrite: bool = False
) -> tuple[np.ndarray, float]:
    """Descriptors of ``boxes`` in one image, from the per-image store; computes what is missing.

    Returns:
        ``(desc (K, dim) float32, seconds)``: seconds is the recorded compute cost of these K
        descriptors (measured when they were computed, so cached runs report real costs).
    """
    path = _store_path(encoder, dataset, side, i)
    boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    store = _read_store(path, encoder.dim or 0, overwrite)
    new_boxes = _missing_boxes(store[0], boxes)
    if len(new_boxes):
        image = dataset.load_image(side, i)
        t0 = time.perf_counter()
        new_desc = encoder.encode(image, new_boxes)
        store = _add_to_store(path, store, new_boxes, new_desc, time.perf_counter() - t0)
    return _rows(store, boxes)


def _extract_side_crop_batched(boxes: list, dataset, side: str, encoder) -> tuple[list, list]:
    """One side's ``crop``-mode descriptors, the missing crops of consecutive images sharing
    batches (only the last batch is padded; same bits as :func:`_features_for_image`, tested).
    A box's recorded cost is its image's crop time plus its share of the batches it ran in."""
    n = n_images(dataset, side)
    bs = int(encoder.batch_size)
    results: list[Any] = [None] * n
    pending: dict[int, dict[str, Any]] = {}  # images whose new crops are not all encoded yet
    queue: list[tuple[int, torch.Tensor]] = []  # (image, crops) waiting for a full batch

    def run(final: bool) -> None:
        total = sum(len(c) for _, c in queue)
        take = total if final else (total // bs) * bs
        if take == 0:
            return
        owners, parts, left, got = [], [], [], 0
        for i, c in queue:
            k = min(len(c), take - got)
            if k:
                owners.append((i, k))
                parts.append(c[:k])
            if k < len(c):
                left.append((i, c[k:]))
            got += k
        queue[:] = left
        t0 = time.perf_counter()
        desc = encoder.encode_crops(torch.cat(parts))
        per_row = (time.perf_counter() - t0) / len(desc)
        start = 0
        for i, k in owners:
            job = pending[i]
            job["desc"].append(desc[start : start + k])
            job["seconds"] += per_row * k
            job["left"] -= k
            start += k
            if job["left"] == 0:
                store = _add_to_store(
                    job["path"],
                    job["store"],
                    job["new"],
                    np.concatenate(job["desc"]),
                    job["seconds"],
                )
                results[i] = _rows(store, job["boxes"])
                del pending[i]

    for i in progress(range(n), desc=f"features {side}"):
        path = _store_path(encoder, dataset, side, i)
        all_boxes = np.asarray(boxes[i], dtype=np.float64).reshape(-1, 4)
        store = _read_store(path, encoder.dim or 0)
        new_boxes = _missing_boxes(store[0], all_boxes)
        if not len(new_boxes):
            results[i] = _rows(store, all_boxes)
            continue
        image = dataset.load_image(side, i)
        t0 = time.perf_counter()
        crops = encoder.crops(image, new_boxes)
        pending[i] = {
            "path": path,
            "store": store,
            "new": new_boxes,
            "boxes": all_boxes,
            "desc": [],
            "left": len(new_boxes),
            "seconds": time.perf_counter() - t0,
        }
        queue.append((i, crops))
        run(final=False)
    run(final=True)
    return [r[0] for r in results], [r[1] for r in results]


def _extract_side_executor(executor, boxes: list, dataset, side: str, encoder) -> tuple:
    """One side's descriptors: this process reads/writes the stores, the executor computes
    what is missing (``executor.encode``; :class:`vpr_core.run.Executor`)."""
    n = n_images(dataset, side)
    all_boxes = [np.asarray(boxes[i], dtype=np.float64).reshape(-1, 4) for i in range(n)]
    paths_ = [_store_path(encoder, dataset, side, i) for i in range(n)]
    stores = [_read_store(p, encoder.dim or 0) for p in paths_]
    missing = [_missing_boxes(stores[i][0], all_boxes[i]) for i in range(n)]
    todo = [i for i in range(n) if len(missing[i])]
    if todo:
        new = [missing[i] for i in todo]
        returned = executor.encode(dataset, side, dict(encoder.kwargs), todo, new)
        descs, secs = checked_encoding(  # before a store keeps them: a sample encoded here
            executor, returned, side, todo, new, encoder.dim,
            lambda i, b: encoder.encode(dataset.load_image(side, i), b),
        )  # fmt: skip
        for i, nb, d, s in zip(todo, new, descs, secs, strict=True):
            stores[i] = _add_to_store(paths_[i], stores[i], nb, d, s)
    out = [_rows(stores[i], all_boxes[i]) for i in range(n)]
    return [d for d, _ in out], [s for _, s in out]


def extract_features(boxes: dict[str, Any], dataset, encoder, executor=None) -> dict[str, Any]:
    """Descriptors for every image's landmarks (cached per image and encoder config).

    Args:
        boxes: output of :func:`~vpr_core.landmarks.stage.extract_landmarks`.
        dataset: a :class:`~vpr_core.datasets.PlaceDataset`.
        encoder: a :class:`~vpr_core.features.LandmarkEncoder` from :func:`get_encoder`.
        executor: a :class:`vpr_core.run.Executor`: images whose descriptors are not cached
            are encoded by it (it returns arrays; only this process touches the cache). None:
            in-process.

    Returns:
        ``{"query": [(K_i, D) float32 ...], "reference": [...], "seconds": {side: [...]}}``.
    """
    out: dict[str, Any] = {"seconds": {}}
    for side in SIDES:
        if executor is not None:
            descs, secs = _extract_side_executor(executor, boxes[side], dataset, side, encoder)
        elif encoder.pooling == "crop":
            descs, secs = _extract_side_crop_batched(boxes[side], dataset, side, encoder)
        else:
            descs, secs = [], []
            for i in progress(range(n_images(dataset, side)), desc=f"features {side}"):
                d, s = _features_for_image(encoder, dataset, side, i, boxes[side][i])
                descs.append(d)
                secs.append(s)
        out[side] = descs
        out["seconds"][side] = secs
    return out
