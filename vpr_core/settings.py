"""The environment, read in one place: every ``VPR_*`` variable the workbench honours (table in
environment.md). Library functions take parameters and fall back to these only where one is
None; nothing in ``vpr_core`` reads ``os.environ`` elsewhere, and nothing writes it."""

from __future__ import annotations

import math
import os
from collections.abc import Mapping

__all__ = [
    "ALEXNET_ENV",
    "BENCH_ROOT_ENV",
    "CACHE_ENV",
    "DATASETS_ENV",
    "OUTPUT_ENV",
    "PROGRESS_ENV",
    "QUICK_ENV",
    "SCHEDULER_ENV",
    "SCHEDULER_TIMEOUT_ENV",
    "SED_MODEL_ENV",
    "TUNE_MALLOC_ENV",
    "alexnet_weights",
    "bench_root",
    "cache_dir",
    "child_environment",
    "dask_scheduler",
    "efficientnet_weights",
    "efficientnet_weights_env",
    "extra_datasets",
    "output_dir",
    "progress_disabled",
    "progress_style",
    "quick",
    "scheduler_timeout",
    "sed_model",
    "tune_malloc",
]

OUTPUT_ENV = "VPR_OUTPUT_DIR"
CACHE_ENV = "VPR_CACHE_DIR"
SCHEDULER_ENV = "VPR_DASK_SCHEDULER"
SCHEDULER_TIMEOUT_ENV = "VPR_SCHEDULER_TIMEOUT"
SED_MODEL_ENV = "VPR_SED_MODEL"
ALEXNET_ENV = "VPR_ALEXNET_WEIGHTS"
BENCH_ROOT_ENV = "VPR_BENCH_ROOT"
DATASETS_ENV = "VPR_DATASETS"
TUNE_MALLOC_ENV = "VPR_TUNE_MALLOC"
PROGRESS_ENV = "VPR_PROGRESS"
QUICK_ENV = "VPR_QUICK"


def _get(name: str) -> str | None:
    value = os.environ.get(name)
    return value if value and value.strip() else None


def output_dir() -> str | None:
    """``$VPR_OUTPUT_DIR`` or None."""
    return _get(OUTPUT_ENV)


def cache_dir() -> str | None:
    """``$VPR_CACHE_DIR`` or None."""
    return _get(CACHE_ENV)


def dask_scheduler() -> str | None:
    """``$VPR_DASK_SCHEDULER`` or None (the CLI's default for ``--scheduler``)."""
    return _get(SCHEDULER_ENV)


def scheduler_timeout(default: float = 15.0) -> float:
    """``$VPR_SCHEDULER_TIMEOUT`` in seconds (default 15); ValueError unless positive, finite."""
    raw = _get(SCHEDULER_TIMEOUT_ENV)
    if raw is None:
        return default
    try:
        value = float(raw)
    except ValueError:
        value = -1.0
    if not (value > 0 and math.isfinite(value)):
        raise ValueError(
            f"{SCHEDULER_TIMEOUT_ENV}={raw!r} is not a positive number of seconds; "
            f"set e.g. {SCHEDULER_TIMEOUT_ENV}=15 or unset it."
        )
    return value


def sed_model() -> str | None:
    """``$VPR_SED_MODEL`` (structured-edge model file) or None."""
    return _get(SED_MODEL_ENV)


def alexnet_weights() -> str | None:
    """``$VPR_ALEXNET_WEIGHTS`` or None."""
    return _get(ALEXNET_ENV)


def efficientnet_weights(variant: str) -> str | None:
    """``$VPR_EFFICIENTNET_<VARIANT>_WEIGHTS`` (e.g. ``LITE1``) or None."""
    return _get(efficientnet_weights_env(variant))


def efficientnet_weights_env(variant: str) -> str:
    """The variable name of :func:`efficientnet_weights`."""
    return f"VPR_EFFICIENTNET_{variant.upper()}_WEIGHTS"


def bench_root() -> str | None:
    """``$VPR_BENCH_ROOT`` (a VPR-Bench checkout) or None."""
    return _get(BENCH_ROOT_ENV)


def extra_datasets() -> dict[str, str]:
    """``$VPR_DATASETS`` as ``{name: root}`` (entries ``name=root`` separated by ``;``)."""
    found: dict[str, str] = {}
    for item in filter(None, (os.environ.get(DATASETS_ENV) or "").split(";")):
        name, sep, root = item.partition("=")
        if not sep or not name.strip() or not root.strip():
            raise ValueError(
                f"{DATASETS_ENV} entry {item!r} is not 'name=root'; write entries "
                "as 'gardens_point=/data/gp;folder=/data/x'."
            )
        found[name.strip()] = root.strip()
    return found


def tune_malloc() -> bool:
    """False when ``$VPR_TUNE_MALLOC`` is ``0`` / ``false`` / ``no`` / ``off``."""
    return (_get(TUNE_MALLOC_ENV) or "1").strip().lower() not in ("0", "false", "no", "off")


def progress_style() -> str:
    """``$VPR_PROGRESS``: ``"text"`` (plain text bars on stdout, as the study runner sets for its
    kernels so saved notebooks keep a readable final bar) or ``"auto"`` (tqdm.auto: a widget in
    Jupyter, text in a terminal; the default)."""
    value = (_get(PROGRESS_ENV) or "auto").strip().lower()
    return value if value in ("auto", "text") else "auto"


def quick() -> bool:
    """True when ``$VPR_QUICK`` is set and not ``0`` / ``false`` / ``no`` / ``off``: a study
    notebook run without papermill's parameters (``jupyter nbconvert --execute``, Lab) takes
    the small set of ``vpr-study run --quick``."""
    return (_get(QUICK_ENV) or "0").strip().lower() not in ("0", "false", "no", "off")


def progress_disabled() -> bool:
    """True when ``$TQDM_DISABLE`` is set (tqdm's own convention)."""
    return bool(os.environ.get("TQDM_DISABLE"))


def child_environment(values: Mapping[str, str]) -> dict[str, str]:
    """This process's environment with ``values`` added, for the ``env=`` of a child process
    (the study runner's notebook kernels); ``os.environ`` itself is left unchanged."""
    return {**os.environ, **{k: str(v) for k, v in values.items()}}
