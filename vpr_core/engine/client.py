"""Connecting to a Dask cluster: the scheduler address and the client (used by the engine).

The address comes from the ``scheduler`` argument only (the CLI fills it from ``--scheduler`` or
``$VPR_DASK_SCHEDULER`` via :func:`vpr_core.settings.dask_scheduler`); without one everything
runs in-process and Dask is never imported.
"""

from __future__ import annotations

from .. import settings
from ..settings import SCHEDULER_ENV
from ..utils import logger, progress

__all__ = ["SCHEDULER_ENV", "gather_in_order", "get_client", "scheduler_address"]


def scheduler_address(scheduler: str | None = None) -> str | None:
    """``scheduler`` stripped, or None (in-process). The environment is not read here.

    Raises:
        ValueError: the address is blank or not a string.
    """
    addr = scheduler
    if addr is None:
        return None
    if not isinstance(addr, str) or not addr.strip():
        raise ValueError(f"Dask scheduler address must be a non-empty string such as "
                         f"'tcp://127.0.0.1:8786', got {addr!r} (check --scheduler / "
                         f"${SCHEDULER_ENV}; unset it to run in-process)")
    return addr.strip()


def get_client(scheduler: str | None = None, timeout: float | None = None):
    """A ``dask.distributed.Client`` connected to the scheduler, or None to run in-process.

    Args:
        scheduler: address (``tcp://host:port``); None: None (in-process).
        timeout: seconds to wait for the scheduler; None:
            :func:`vpr_core.settings.scheduler_timeout` (``$VPR_SCHEDULER_TIMEOUT``, 15 s).

    Returns:
        A connected ``Client`` (close it when done, e.g. ``with get_client(...) as c``) or None.

    Raises:
        ImportError: Dask is not installed (names the package to install).
        ConnectionError: the scheduler cannot be reached (names the address and the fix).
    """
    addr = scheduler_address(scheduler)
    if addr is None:
        return None
    timeout = settings.scheduler_timeout() if timeout is None else float(timeout)
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


def gather_in_order(client, futures: list, desc: str) -> list:
    """Results of ``futures`` in list order (a progress bar counts completions)."""
    from distributed import as_completed

    bar = progress(None, total=len(futures), desc=desc, unit="task")
    try:
        for f in as_completed(futures, loop=client.loop):
            f.result()  # re-raises a worker's exception here, with its traceback
            bar.update()
    finally:
        bar.close()
    return client.gather(futures)


