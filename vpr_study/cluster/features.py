"""Feature extraction in image shards on an existing Dask cluster.
Workers need the client's vpr_core and torch, and the images and weights at the same paths; they
return arrays (the client alone touches the cache) equal to the in-process ones bit for bit."""

from __future__ import annotations

import json
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
import torch
from torch import nn

from vpr_core import Encoder, LandmarkEncoder, checks, utils

from .client import gather_in_order

__all__ = ["extract_features_distributed"]


# ----------------------------------------------------------------------------------------------
# features
# ----------------------------------------------------------------------------------------------
def _encoder_key(encoder_kwargs: dict[str, Any]) -> tuple[str, nn.Module | None]:
    """JSON key of an encoder's arguments (:meth:`vpr_core.Encoder.identity`), and its backbone
    module if it has one (a module travels to the workers as an object)."""
    spec = Encoder(**encoder_kwargs)  # the defaults filled in, checked once
    module = spec.backbone if isinstance(spec.backbone, nn.Module) else None
    return spec.identity(), module


#: One encoder per process and config (model loading is the slow part), at most 4.
_ENCODERS: dict[str, LandmarkEncoder] = {}


def _encoder(key: str, module: nn.Module | None = None) -> LandmarkEncoder:
    """The encoder of ``key`` (built on first use; ``module`` replaces a module's key)."""
    if key not in _ENCODERS:
        kwargs = json.loads(key)
        kwargs.pop("weights_sha256", None)  # the identity's, not a field
        if module is not None:
            kwargs["backbone"] = module
        while len(_ENCODERS) >= 4:
            _ENCODERS.pop(next(iter(_ENCODERS)))
        _ENCODERS[key] = LandmarkEncoder(**kwargs)
    return _ENCODERS[key]


def _encode_shard(
    dataset,
    side: str,
    indices: list[int],
    boxes: list[np.ndarray] | None,
    key: str,
    kind: str,
    threads: int | None = None,
    module: nn.Module | None = None,
) -> tuple[list[np.ndarray], list[float], dict]:
    """Task: descriptors of a shard of images (runs on a worker, or in-process).

    ``threads``: torch intra-op threads for this task (restored afterwards); None keeps the
    process's setting. ``roi`` feature maps change in the last bits with torch's thread count,
    so the engine runs worker tasks with the client's count.

    Returns:
        ``(descriptors, seconds, encoder config)``: per image ``(K_i, dim)`` float32
        (``kind="landmarks"``) or ``(dim,)`` (``kind="global"``), its compute seconds, and the
        config of the encoder that made them.
    """
    enc = _encoder(key, module)
    before = torch.get_num_threads()
    if threads is not None:
        torch.set_num_threads(int(threads))
    descs, secs = [], []
    try:
        for n, i in enumerate(indices):
            image = dataset.load_image(side, int(i))
            t0 = time.perf_counter()
            if kind == "global" or boxes is None:
                d = enc.encode_global(image)
            else:
                d = enc.encode(image, boxes[n])
            secs.append(time.perf_counter() - t0)
            descs.append(np.asarray(d, dtype=np.float32))
    finally:
        torch.set_num_threads(before)
    return descs, secs, dict(enc.config)


def extract_features_distributed(
    client,
    dataset,
    side: str,
    encoder_kwargs: dict[str, Any],
    indices: Sequence[int] | None = None,
    boxes: Sequence[np.ndarray] | None = None,
    kind: str = "landmarks",
    shard_size: int = 16,
) -> tuple[list[np.ndarray], list[float]]:
    """Descriptors of one side's images, computed in shards of images on a Dask cluster.

    Args:
        client: a ``dask.distributed.Client``, or None to run the same shards in-process.
        dataset: a :class:`~vpr_core.datasets.PlaceDataset` whose image paths the workers can
            read.
        side: ``"query"`` or ``"reference"``.
        encoder_kwargs: keyword arguments of :class:`~vpr_core.features.LandmarkEncoder`
            (JSON-serialisable but for a module ``backbone``, which is sent to the workers);
            every worker builds the same encoder once and reuses it.
        indices: image indices to encode (default: all of the side), any order.
        boxes: with ``kind="landmarks"``, one ``(K_i, 4)`` array per entry of ``indices``.
        kind: ``"landmarks"`` (``encode(image, boxes)``) or ``"global"`` (``encode_global``).
        shard_size: images per task. Each task runs on this process's
            ``torch.get_num_threads()`` torch threads, so that descriptors equal the in-process
            ones bit for bit (``roi`` feature maps depend on the thread count); start workers
            with ``--nthreads 1`` and fewer processes than cores to leave room for them.

    Returns:
        ``(descriptors, seconds)`` in the order of ``indices``: ``(K_i, dim)`` float32 arrays
        (``(dim,)`` for ``global``) and per-image compute seconds.

    Raises:
        ValueError: bad side/kind/shard size, boxes missing or of the wrong length.
        RuntimeError: a worker's encoder config differs from the client's (package versions).
    """
    checks.check_choice(side, "side", ("query", "reference"))
    checks.check_choice(kind, "kind", ("landmarks", "global"))
    shard_size = checks.check_int(shard_size, "shard_size", 1)
    n_side = len(dataset.paths(side))
    idx = list(range(n_side)) if indices is None else [int(i) for i in indices]
    if kind == "landmarks":
        if boxes is None or len(boxes) != len(idx):
            raise ValueError(
                f"kind='landmarks' needs one boxes array per image: got "
                f"{None if boxes is None else len(boxes)} for {len(idx)} images"
            )
        boxes = [np.asarray(b, dtype=np.float64).reshape(-1, 4) for b in boxes]
    key, module = _encoder_key(encoder_kwargs)
    expected = dict(_encoder(key, module).config)
    shards = [slice(s, s + int(shard_size)) for s in range(0, len(idx), int(shard_size))]
    args = [(idx[s], None if boxes is None or kind == "global" else boxes[s]) for s in shards]
    if client is None:
        results = [
            _encode_shard(dataset, side, i, b, key, kind, None, module)
            for i, b in utils.progress(args, desc=f"features {side}")
        ]
    else:
        nthreads = torch.get_num_threads()
        ds = client.scatter(dataset, broadcast=False, hash=False)
        mod = None if module is None else client.scatter(module, broadcast=True, hash=False)
        futures = [
            client.submit(_encode_shard, ds, side, i, b, key, kind, nthreads, mod, pure=False)
            for i, b in args
        ]
        results = gather_in_order(client, futures, f"features {side} (dask)")
    descs: list[np.ndarray] = []
    secs: list[float] = []
    for d, s, config in results:
        if config != expected:
            raise RuntimeError(
                "a Dask worker's encoder differs from the client's (config "
                f"{_diff(config, expected)}): install the same vpr_core version, torch build and "
                "backbone weights on every worker"
            )
        descs.extend(d)
        secs.extend(s)
    return descs, secs


def _diff(a: dict, b: dict) -> str:
    keys = sorted(k for k in set(a) | set(b) if a.get(k) != b.get(k))
    return ", ".join(f"{k}: worker {a.get(k)!r} vs client {b.get(k)!r}" for k in keys)
