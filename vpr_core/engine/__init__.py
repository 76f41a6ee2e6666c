"""Opt-in scale-out: a global-descriptor shortlist re-ranked by Eq. (1) (:mod:`.shortlist`), and
extraction and matching as ``dask.distributed`` tasks when a scheduler is given
(:mod:`.distributed`; Dask imported only then), equal to the in-process results."""

from __future__ import annotations

from .distributed import (
    SCHEDULER_ENV,
    extract_features_distributed,
    get_client,
    scheduler_address,
    similarity_blocks_distributed,
    similarity_pairs_distributed,
)
from .shortlist import global_cosine, rerank, shortlist_pairs, topk_lowest_index

__all__ = [
    "SCHEDULER_ENV",
    "extract_features_distributed",
    "get_client",
    "global_cosine",
    "rerank",
    "scheduler_address",
    "shortlist_pairs",
    "similarity_blocks_distributed",
    "similarity_pairs_distributed",
    "topk_lowest_index",
]
