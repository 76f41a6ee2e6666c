"""Results of given matrices for the figure tests: made through the one door
(``vpr_core.result_from_matrix``), as a peer or a run would be."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from vpr_core import Evaluation, MethodResult, result_from_matrix


def result_of(
    label: str,
    sim: np.ndarray,
    gt: np.ndarray,
    config: Any = None,
    n_bootstrap: int = 0,
    **fields: Any,
) -> MethodResult:
    """A result of ``sim`` against ``gt`` (tolerance 0, dataset ``toy``) as it was scored:
    ``config`` a ``Method`` or a peer's dict (default ``{"name": label}``), recorded as it is
    (a normalisation it names is taken as done); ``fields`` set after scoring (e.g.
    ``intervals``, ``metrics``)."""
    config = config if config is not None else {"name": label}
    made = MethodResult(
        method=label,
        label=label,
        dataset="toy",
        config={"name": label},
        encoder={},
        similarity=sim,
        ground_truth=np.asarray(gt, dtype=bool),
        boxes={"query": [], "reference": []},
        metrics={},
        timings={},
        tolerance=0,
    )
    r = result_from_matrix(
        np.asarray(sim, dtype=np.float64), made, Evaluation(n_bootstrap=n_bootstrap)
    )
    return dataclasses.replace(r, config=config, **fields)
