"""Connecting to a Dask cluster: the scheduler address and the client (used by the engine).

The address comes from the ``scheduler`` argument (``--scheduler``), else from
``$VPR_DASK_SCHEDULER``, else there is none and everything runs in-process (Dask is then never
imported).
"""

from __future__ import annotations

import os

from ..utils import logger, progress

__all__ = ["SCHEDULER_ENV", "gather_in_order", "get_client", "scheduler_address"]

#: Environment variable holding the scheduler address (``tcp://host:8786``).
SCHEDULER_ENV = "VPR_DASK_SCHEDULER"


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


