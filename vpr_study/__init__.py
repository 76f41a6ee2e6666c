"""vpr_study: the workbench beside the pipeline (:mod:`vpr_core`): plots and ``save``
(:mod:`.viz`), the ``vpr-study`` CLI and the study runner, peers, downloads and the Dask
executor. Names here are imported on first use."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

#: Each name of this face and the module that defines it (imported on first use, so that the
#: CLI's ``--help`` loads no torch).
_FACE = {
    "check_parameters": "runner",
    "peer_result": "peers",
    "peer_from_matrix": "peers",
    "peer_from_descriptors": "peers",
    "find_vprbench_peers": "peers",
    "load_vprbench_precomputed": "peers",
    "download_dataset": "download",
    "DaskExecutor": "cluster",
}

__all__ = [
    "DaskExecutor",
    "check_parameters",
    "download_dataset",
    "find_vprbench_peers",
    "load_vprbench_precomputed",
    "peer_from_descriptors",
    "peer_from_matrix",
    "peer_result",
]


def __getattr__(name: str) -> Any:
    if name not in _FACE:
        raise AttributeError(f"module 'vpr_study' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{_FACE[name]}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_FACE))


if TYPE_CHECKING:
    from .cluster import DaskExecutor
    from .download import download_dataset
    from .peers import (
        find_vprbench_peers,
        load_vprbench_precomputed,
        peer_from_descriptors,
        peer_from_matrix,
        peer_result,
    )
    from .runner import check_parameters
