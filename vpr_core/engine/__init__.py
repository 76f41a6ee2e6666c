"""Engines that make the study fast and scale it out (issue 10).

* :mod:`~vpr_core.engine.shortlist`: a whole-image descriptor picks each query's top-k
  references (:func:`shortlist_pairs`), Eq. (1) re-ranks only those (:func:`rerank`: NaN
  elsewhere, "not ranked").
* :mod:`~vpr_core.engine.distributed`: feature extraction over image shards and matching over
  query blocks as ``dask.distributed`` tasks when a scheduler is given (``--scheduler`` /
  ``$VPR_DASK_SCHEDULER``), in-process otherwise; results equal the in-process ones exactly.
  Dask is imported only when a scheduler is used.
"""

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
