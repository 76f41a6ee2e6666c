"""The distributed engine: feature extraction (image shards) and matching (query blocks) on Dask.

With a scheduler address (``scheduler=`` / ``--scheduler`` / ``$VPR_DASK_SCHEDULER``) the two
heavy stages run as ``dask.distributed`` tasks on an existing cluster; without one, everything
runs in-process and no cluster (nor Dask) is needed.

**Data path: workers return arrays to the client.** A task gets its inputs from the client
(image indices and boxes, descriptor blocks), computes, and returns numpy arrays; the client
assembles them in a fixed order and is the only process that reads or writes the cache. So a
cluster needs no shared filesystem for the cache. It needs:

* the same ``vpr_core`` version (and torch build) on every worker as on the client: the workers
  check that their encoder's config equals the client's and refuse otherwise;
* for feature extraction, the dataset's image files readable at the same paths on every worker
  (a shared or replicated data folder) and the backbone weights where the encoder looks for them;
* for matching, nothing on disk: descriptors travel with the tasks.

**Determinism.** The result equals the in-process computation exactly (``np.array_equal``):
every task runs the same public function (:func:`vpr_core.matching.similarity_matrix`,
:func:`~vpr_core.matching.similarity_pairs`, ``LandmarkEncoder.encode``) on its block, each image
pair's Eq. (1) value depends only on that pair's landmarks (verified bit for bit across block
shapes and torch thread counts by ``tests/test_distributed.py``), the encoder pads every batch
to a fixed shape, and the blocks are assembled by position, not by completion order.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np

from ..paper import SOFT_NMS_SIGMA
from ..utils import logger, progress

__all__ = [
    "SCHEDULER_ENV",
    "extract_features_distributed",
    "get_client",
    "scheduler_address",
    "similarity_blocks_distributed",
    "similarity_pairs_distributed",
]

#: Environment variable holding the scheduler address (``tcp://host:8786``).
SCHEDULER_ENV = "VPR_DASK_SCHEDULER"


# ----------------------------------------------------------------------------------------------
# client
# ----------------------------------------------------------------------------------------------
def scheduler_address(scheduler: str | None = None) -> str | None:
    """The scheduler to use: ``scheduler`` if given, else ``$VPR_DASK_SCHEDULER``, else None.

    Raises:
        ValueError: the address is blank or not a string.
    """
    addr = scheduler if scheduler is not None else os.environ.get(SCHEDULER_ENV)
    if addr is None:
        return None
    if not isinstance(addr, str) or not addr.strip():
        raise ValueError(f"Dask scheduler address must be a non-empty string such as "
                         f"'tcp://127.0.0.1:8786', got {addr!r} (check --scheduler / "
                         f"${SCHEDULER_ENV}; unset it to run in-process)")
    return addr.strip()


def get_client(scheduler: str | None = None, timeout: float = 30.0):
    """A ``dask.distributed.Client`` connected to the scheduler, or None to run in-process.

    Args:
        scheduler: address (``tcp://host:port``); None: ``$VPR_DASK_SCHEDULER``; neither: None.
        timeout: seconds to wait for the scheduler.

    Returns:
        A connected ``Client`` (close it when done, e.g. ``with get_client(...) as c``) or None.

    Raises:
        ImportError: Dask is not installed (names the package to install).
        ConnectionError: the scheduler cannot be reached (names the address and the fix).
    """
    addr = scheduler_address(scheduler)
    if addr is None:
        return None
    try:
        from distributed import Client
    except ImportError as e:  # pragma: no cover - dask[distributed] is a dependency
        raise ImportError("a Dask scheduler was given but dask.distributed is not installed: "
                          "pip install 'dask[distributed]'") from e
    try:
        client = Client(addr, timeout=timeout, set_as_default=False)
    except (OSError, TimeoutError) as e:
        raise ConnectionError(
            f"could not reach the Dask scheduler at {addr!r} within {timeout:g} s ({e}). Start "
            f"one (`dask scheduler`, then `dask worker {addr}` on each machine; see "
            f"docs/DISTRIBUTED.md), or unset --scheduler / ${SCHEDULER_ENV} to run in-process."
        ) from e
    logger.info("Dask: connected to %s (%d workers)", addr,
                len(client.scheduler_info().get("workers", {})))
    return client


def _gather_in_order(client, futures: list, desc: str) -> list:
    """Results of ``futures`` in list order (a progress bar counts completions)."""
    from distributed import as_completed

    bar = progress(None, total=len(futures), desc=desc, unit="task")
    try:
        for f in as_completed(futures):
            f.result()  # re-raises a worker's exception here, with its traceback
            bar.update()
    finally:
        bar.close()
    return client.gather(futures)


# ----------------------------------------------------------------------------------------------
# features
# ----------------------------------------------------------------------------------------------
def _encoder_key(encoder_kwargs: dict[str, Any]) -> str:
    return json.dumps(encoder_kwargs, sort_keys=True, default=str)


@lru_cache(maxsize=4)
def _encoder(key: str):
    """One encoder per process and config (model loading is the slow part)."""
    from ..features import LandmarkEncoder

    return LandmarkEncoder(**json.loads(key))


def _encode_shard(dataset, side: str, indices: list[int], boxes: list[np.ndarray] | None,
                  key: str, kind: str) -> tuple[list[np.ndarray], list[float], dict]:
    """Task: descriptors of a shard of images (runs on a worker, or in-process).

    Returns:
        ``(descriptors, seconds, encoder config)``: per image ``(K_i, dim)`` float32
        (``kind="landmarks"``) or ``(dim,)`` (``kind="global"``), its compute seconds, and the
        config of the encoder that made them.
    """
    enc = _encoder(key)
    descs, secs = [], []
    for n, i in enumerate(indices):
        image = dataset.load_image(side, int(i))
        t0 = time.perf_counter()
        d = enc.encode_global(image) if kind == "global" else enc.encode(image, boxes[n])
        secs.append(time.perf_counter() - t0)
        descs.append(np.asarray(d, dtype=np.float32))
    return descs, secs, dict(enc.config)


def extract_features_distributed(client, dataset, side: str, encoder_kwargs: dict[str, Any],
                                 indices: Sequence[int] | None = None,
                                 boxes: Sequence[np.ndarray] | None = None,
                                 kind: str = "landmarks", shard_size: int = 16,
                                 ) -> tuple[list[np.ndarray], list[float]]:
    """Descriptors of one side's images, computed in shards of images on a Dask cluster.

    Args:
        client: a ``dask.distributed.Client``, or None to run the same shards in-process.
        dataset: a :class:`~vpr_core.datasets.PlaceDataset` whose image paths the workers can
            read.
        side: ``"query"`` or ``"reference"``.
        encoder_kwargs: keyword arguments of :class:`~vpr_core.features.LandmarkEncoder`
            (JSON-serialisable); every worker builds the same encoder once and reuses it.
        indices: image indices to encode (default: all of the side), any order.
        boxes: with ``kind="landmarks"``, one ``(K_i, 4)`` array per entry of ``indices``.
        kind: ``"landmarks"`` (``encode(image, boxes)``) or ``"global"`` (``encode_global``).
        shard_size: images per task.

    Returns:
        ``(descriptors, seconds)`` in the order of ``indices``: ``(K_i, dim)`` float32 arrays
        (``(dim,)`` for ``global``) and per-image compute seconds.

    Raises:
        ValueError: bad side/kind/shard size, boxes missing or of the wrong length.
        RuntimeError: a worker's encoder config differs from the client's (package versions).
    """
    if side not in ("query", "reference"):
        raise ValueError(f"side must be 'query' or 'reference', got {side!r}")
    if kind not in ("landmarks", "global"):
        raise ValueError(f"kind must be 'landmarks' or 'global', got {kind!r}")
    if isinstance(shard_size, bool) or int(shard_size) < 1:
        raise ValueError(f"shard_size must be an integer >= 1, got {shard_size!r}")
    n_side = len(dataset.paths(side))
    idx = list(range(n_side)) if indices is None else [int(i) for i in indices]
    if kind == "landmarks":
        if boxes is None or len(boxes) != len(idx):
            raise ValueError(f"kind='landmarks' needs one boxes array per image: got "
                             f"{None if boxes is None else len(boxes)} for {len(idx)} images")
        boxes = [np.asarray(b, dtype=np.float64).reshape(-1, 4) for b in boxes]
    key = _encoder_key(encoder_kwargs)
    expected = dict(_encoder(key).config)
    shards = [slice(s, s + int(shard_size)) for s in range(0, len(idx), int(shard_size))]
    args = [(idx[s], None if kind == "global" else boxes[s]) for s in shards]
    if client is None:
        results = [_encode_shard(dataset, side, i, b, key, kind)
                   for i, b in progress(args, desc=f"features {side}")]
    else:
        ds = client.scatter(dataset, broadcast=False)
        futures = [client.submit(_encode_shard, ds, side, i, b, key, kind, pure=False)
                   for i, b in args]
        results = _gather_in_order(client, futures, f"features {side} (dask)")
    descs: list[np.ndarray] = []
    secs: list[float] = []
    for d, s, config in results:
        if config != expected:
            raise RuntimeError(
                "a Dask worker's encoder differs from the client's (config "
                f"{_diff(config, expected)}): install the same vpr_core version, torch build and "
                "backbone weights on every worker")
        descs.extend(d)
        secs.extend(s)
    return descs, secs


def _diff(a: dict, b: dict) -> str:
    keys = sorted(k for k in set(a) | set(b) if a.get(k) != b.get(k))
    return ", ".join(f"{k}: worker {a.get(k)!r} vs client {b.get(k)!r}" for k in keys)


# ----------------------------------------------------------------------------------------------
# matching
# ----------------------------------------------------------------------------------------------
def _check_lists(desc: Any, boxes: Any, side: str) -> tuple[list, list]:
    """One array per image on both lists, equal lengths (a stacked array is split)."""
    dl, bl = list(desc), list(boxes)
    if len(dl) != len(bl):
        raise ValueError(f"{side}_desc has {len(dl)} images but {side}_boxes has {len(bl)}")
    if not dl:
        raise ValueError(f"{side}_desc is empty")
    return dl, bl


@dataclass(frozen=True)
class _Part:
    """Landmark sets of a block of images: scattered as ONE object (a bare tuple or list would
    be scattered element by element)."""

    desc: list
    boxes: list


def _matrix_block(qd, qb, rd, rb, soft_nms_iou, sigma) -> np.ndarray:
    """Task: Eq. (1) of a query block x a reference block (the in-process function)."""
    from ..matching import similarity_matrix

    return similarity_matrix(qd, qb, rd, rb, soft_nms_iou=soft_nms_iou, sigma=sigma,
                             show_progress=False)


def similarity_blocks_distributed(client, query_desc, query_boxes, reference_desc,
                                  reference_boxes, soft_nms_iou: float | None = None,
                                  sigma: float = SOFT_NMS_SIGMA, block_queries: int = 64,
                                  block_references: int = 512) -> np.ndarray:
    """Exhaustive Eq. (1) matrix as a grid of (query block x reference block) Dask tasks.

    Each reference block is sent to the cluster once (``scatter``) and reused by every query
    block; each task runs :func:`vpr_core.matching.similarity_matrix` on its block and returns
    ``(bq, br)`` values, placed by position.

    Args:
        client: a ``dask.distributed.Client``, or None: one in-process ``similarity_matrix``.
        query_desc, query_boxes, reference_desc, reference_boxes: sequences of ``(K_i, D)`` /
            ``(K_i, 4)`` arrays (or stacked ``(N, K, D)`` / ``(N, K, 4)``), as
            :func:`~vpr_core.matching.similarity_matrix`.
        soft_nms_iou, sigma: Algorithm 4 settings.
        block_queries, block_references: images per block side.

    Returns:
        ``(Nq, Nr)`` float64, equal to the in-process ``similarity_matrix`` exactly.
    """
    if client is None:
        return _matrix_block(query_desc, query_boxes, reference_desc, reference_boxes,
                             soft_nms_iou, sigma)
    qd, qb = _check_lists(query_desc, query_boxes, "query")
    rd, rb = _check_lists(reference_desc, reference_boxes, "reference")
    bq, br = _block_size(block_queries, "block_queries"), _block_size(block_references,
                                                                       "block_references")
    qs = [slice(s, s + bq) for s in range(0, len(qd), bq)]
    rs = [slice(s, s + br) for s in range(0, len(rd), br)]
    rfut = [client.scatter(_Part(rd[s], rb[s]), broadcast=False) for s in rs]
    futures, where = [], []
    for q in qs:
        qfut = client.scatter(_Part(qd[q], qb[q]), broadcast=False)
        for r, rf in zip(rs, rfut):
            futures.append(client.submit(_matrix_pair_task, qfut, rf, soft_nms_iou, sigma,
                                         pure=False))
            where.append((q, r))
    out = np.empty((len(qd), len(rd)), dtype=np.float64)
    for (q, r), block in zip(where, _gather_in_order(client, futures, "similarity (dask)")):
        out[q, r] = block
    return out


def _matrix_pair_task(qpart: _Part, rpart: _Part, soft_nms_iou, sigma) -> np.ndarray:
    return _matrix_block(qpart.desc, qpart.boxes, rpart.desc, rpart.boxes, soft_nms_iou, sigma)


def _block_size(n: Any, name: str) -> int:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or int(n) < 1:
        raise ValueError(f"{name} must be an integer >= 1, got {n!r}")
    return int(n)


def _pairs_task(qpart: _Part, rblocks: list[_Part], rstarts: list[int], local_pairs: np.ndarray,
                ref_ids: np.ndarray, soft_nms_iou, sigma) -> np.ndarray:
    """Task: Eq. (1) of listed pairs; ``ref_ids`` are the global references the pairs use."""
    from ..matching import similarity_pairs

    rd, rb = [], []
    for j in ref_ids:
        b = int(np.searchsorted(rstarts, j, side="right")) - 1
        rd.append(rblocks[b].desc[j - rstarts[b]])
        rb.append(rblocks[b].boxes[j - rstarts[b]])
    return similarity_pairs(qpart.desc, qpart.boxes, rd, rb, local_pairs, soft_nms_iou=soft_nms_iou,
                            sigma=sigma, show_progress=False)


def similarity_pairs_distributed(client, query_desc, query_boxes, reference_desc,
                                 reference_boxes, pairs: np.ndarray,
                                 soft_nms_iou: float | None = None,
                                 sigma: float = SOFT_NMS_SIGMA, block_queries: int = 64,
                                 block_references: int = 512) -> np.ndarray:
    """Eq. (1) of listed pairs (a shortlist) as Dask tasks over query blocks.

    Reference blocks are scattered once; a query block's task receives only the reference
    blocks its pairs touch (for a route, a few neighbouring blocks), picks the references it
    needs and runs :func:`vpr_core.matching.similarity_pairs` on them.

    Args:
        client: a ``dask.distributed.Client``, or None: one in-process ``similarity_pairs``.
        query_desc, query_boxes, reference_desc, reference_boxes: as
            :func:`similarity_blocks_distributed`.
        pairs: ``(P, 2)`` int ``(query, reference)`` indices.
        soft_nms_iou, sigma: Algorithm 4 settings.
        block_queries, block_references: images per query block / per scattered reference block.

    Returns:
        ``(P,)`` float64 in the order of ``pairs``, equal to the in-process result exactly.
    """
    from ..matching import similarity_pairs

    if client is None:
        return similarity_pairs(query_desc, query_boxes, reference_desc, reference_boxes, pairs,
                                soft_nms_iou=soft_nms_iou, sigma=sigma)
    qd, qb = _check_lists(query_desc, query_boxes, "query")
    rd, rb = _check_lists(reference_desc, reference_boxes, "reference")
    pr = np.asarray(pairs)
    if pr.size == 0:
        return np.zeros(0, dtype=np.float64)
    if pr.ndim != 2 or pr.shape[1] != 2 or not np.issubdtype(pr.dtype, np.integer):
        raise ValueError(f"pairs must be a (P, 2) integer array, got shape {pr.shape}, "
                         f"dtype {pr.dtype}")
    pr = pr.astype(np.int64)
    for col, n, what in ((0, len(qd), "query"), (1, len(rd), "reference")):
        if pr[:, col].min() < 0 or pr[:, col].max() >= n:
            raise ValueError(f"pairs hold {what} indices outside 0..{n - 1}")
    bq = _block_size(block_queries, "block_queries")
    br = _block_size(block_references, "block_references")
    rstarts = list(range(0, len(rd), br))
    rfut = [client.scatter(_Part(rd[s:s + br], rb[s:s + br]), broadcast=False) for s in rstarts]
    futures, rows_of = [], []
    for q0 in range(0, len(qd), bq):
        rows = np.flatnonzero((pr[:, 0] >= q0) & (pr[:, 0] < q0 + bq))
        if rows.size == 0:
            continue
        ref_ids, local_r = np.unique(pr[rows, 1], return_inverse=True)
        blocks = sorted({int(j) // br for j in ref_ids})
        local = np.stack([pr[rows, 0] - q0, local_r.reshape(-1)], axis=1)
        qfut = client.scatter(_Part(qd[q0:q0 + bq], qb[q0:q0 + bq]), broadcast=False)
        futures.append(client.submit(_pairs_task, qfut, [rfut[b] for b in blocks],
                                     [rstarts[b] for b in blocks], local, ref_ids,
                                     soft_nms_iou, sigma, pure=False))
        rows_of.append(rows)
    out = np.empty(pr.shape[0], dtype=np.float64)
    for rows, vals in zip(rows_of, _gather_in_order(client, futures, "shortlist (dask)")):
        out[rows] = vals
    return out
