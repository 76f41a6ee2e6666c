"""Extraction and matching as ``dask.distributed`` tasks on a running cluster: the
:class:`DaskExecutor` value that ``run_method(..., executor=)`` takes, equal to in-process runs
(docs/DISTRIBUTED.md)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from vpr_core import Matching

from .blocks import similarity_blocks_distributed, similarity_pairs_distributed
from .client import get_client, scheduler_address
from .features import extract_features_distributed

__all__ = [
    "DaskExecutor",
    "extract_features_distributed",
    "get_client",
    "scheduler_address",
    "similarity_blocks_distributed",
    "similarity_pairs_distributed",
]


class DaskExecutor:
    """A connection to a Dask scheduler as the executor of ``run_method`` (features in image
    shards, Eq. (1) in query blocks). Close it when done: ``with DaskExecutor(addr) as ex:``.

    Args:
        scheduler: the scheduler's address (``tcp://host:port``).
        timeout: seconds to wait for it (default ``$VPR_SCHEDULER_TIMEOUT``, 15 s).
    """

    def __init__(self, scheduler: str, timeout: float | None = None) -> None:
        self.client = get_client(scheduler, timeout)
        if self.client is None:  # an empty address
            raise ValueError(
                f"DaskExecutor needs a scheduler address (tcp://host:port), got {scheduler!r}"
            )

    def encode(
        self, dataset: Any, side: str, encoder_kwargs: dict, indices: list[int], boxes: list
    ) -> tuple[list, list]:
        """Descriptors and seconds of images ``indices`` of ``side`` (image shards as tasks)."""
        return extract_features_distributed(
            self.client, dataset, side, encoder_kwargs, indices=indices, boxes=boxes
        )

    def similarity_matrix(
        self,
        query_desc: Sequence,
        query_boxes: Sequence,
        reference_desc: Sequence,
        reference_boxes: Sequence,
        matching: Matching,
    ) -> np.ndarray:
        """``(Nq, Nr)`` Eq. (1) in query blocks."""
        return similarity_blocks_distributed(
            self.client, query_desc, query_boxes, reference_desc, reference_boxes, matching
        )

    def similarity_pairs(
        self,
        query_desc: Sequence,
        query_boxes: Sequence,
        reference_desc: Sequence,
        reference_boxes: Sequence,
        pairs: np.ndarray,
        matching: Matching,
    ) -> np.ndarray:
        """``(P,)`` Eq. (1) of listed pairs in query blocks."""
        return similarity_pairs_distributed(
            self.client, query_desc, query_boxes, reference_desc, reference_boxes, pairs, matching
        )

    def close(self) -> None:
        """Close the connection (the cluster keeps running)."""
        self.client.close()

    def __enter__(self) -> DaskExecutor:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
