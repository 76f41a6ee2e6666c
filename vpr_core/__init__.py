"""vpr_core: the pipeline of Yang et al., "Towards A Deep Insight into Landmark-based Visual Place
Recognition", by stage: datasets, landmarks, features, matching, evaluation, Sec. 3.1 statistics;
this face holds the run, its values and the shared modules (docs/ARCHITECTURE.md)."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

#: Each name of this face and the module that defines it ("": the name is a module). A name is
#: imported on first use, so ``import vpr_core.settings`` (``vpr-study --help``) loads no torch.
_FACE = {
    "checks": "",
    "paper": "",
    "paths": "",
    "settings": "",
    "utils": "",
    "Executor": "run",
    "run_method": "run",
    "MethodResult": "result",
    "constant_notice": "result",
    "normalise_result": "result",
    "Method": "methods",
    "available_methods": "methods",
    "get_method": "methods",
    "run_key": "methods",
    "step_between": "methods",
    "scale_statistics": "statistics",
    "check_per_match": "statistics",
    "dataset_fingerprint": "cache",
    "VPRWarning": "notices",
    "notice": "notices",
    "configure_logging": "utils",
    "make_deterministic": "utils",
    "tune_allocator": "utils",
}

__all__ = [
    "__version__",
    "Executor",
    "Method",
    "MethodResult",
    "VPRWarning",
    "available_methods",
    "check_per_match",
    "checks",
    "configure_logging",
    "constant_notice",
    "dataset_fingerprint",
    "get_method",
    "make_deterministic",
    "normalise_result",
    "notice",
    "paper",
    "paths",
    "run_key",
    "run_method",
    "scale_statistics",
    "settings",
    "step_between",
    "tune_allocator",
    "utils",
]


def __getattr__(name: str) -> Any:
    if name not in _FACE:
        raise AttributeError(f"module 'vpr_core' has no attribute {name!r}")
    module = importlib.import_module(f".{_FACE[name] or name}", __name__)
    value = getattr(module, name) if _FACE[name] else module
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_FACE))


if TYPE_CHECKING:
    from . import checks, paper, paths, settings, utils
    from .cache import dataset_fingerprint
    from .methods import Method, available_methods, get_method, run_key, step_between
    from .notices import VPRWarning, notice
    from .result import MethodResult, constant_notice, normalise_result
    from .run import Executor, run_method
    from .statistics import check_per_match, scale_statistics
    from .utils import configure_logging, make_deterministic, tune_allocator
