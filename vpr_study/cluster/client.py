"""Connecting to a Dask cluster: the scheduler address comes from the ``scheduler`` argument only
(the CLI fills it from ``--scheduler`` or ``$VPR_DASK_SCHEDULER``); without one everything runs
in-process and Dask is never imported."""

from __future__ import annotations

import re
import socket
import struct
import time
from concurrent.futures import CancelledError

from vpr_core import settings, utils

__all__ = ["POLL_S", "gather_in_order", "get_client", "scheduler_address"]

_ADDRESS = re.compile(r"(tcp|tls|inproc|ucx)://(\[[^\]]+\]|[^:/\[\]]+):(\d{1,5})")
#: A Dask handshake message is a few hundred bytes; anything near this is not Dask speaking.
_MAX_HANDSHAKE = 1 << 26


def scheduler_address(scheduler: str | None = None) -> str | None:
    """``scheduler`` stripped, or None (in-process). The environment is not read here.

    Raises:
        ValueError: the address is blank or not a string.
    """
    addr = scheduler
    if addr is None:
        return None
    if not isinstance(addr, str) or not addr.strip():
        raise ValueError(
            f"Dask scheduler address must be a non-empty string such as "
            f"'tcp://127.0.0.1:8786', got {addr!r} (check --scheduler / "
            f"${settings.SCHEDULER_ENV}; unset it to run in-process)"
        )
    addr = addr.strip()
    if "://" not in addr and re.fullmatch(r"[^:/]+:\d{1,5}", addr):
        addr = "tcp://" + addr  # host:port, as Dask itself accepts it
    m = _ADDRESS.fullmatch(addr)
    if not m:
        raise ValueError(
            f"{addr!r} is not a Dask scheduler address; write it as "
            f"tcp://HOST:PORT (e.g. tcp://127.0.0.1:8786) in --scheduler / "
            f"${settings.SCHEDULER_ENV}, or unset it to run in-process"
        )
    if not 1 <= int(m.group(3)) <= 65535:
        raise ValueError(
            f"{addr!r} has a bad port: port {int(m.group(3))} is not in 1 to 65535; give the "
            f"scheduler's port (8786 by default) in --scheduler / ${settings.SCHEDULER_ENV}"
        )
    return addr


def _probe_scheduler(addr: str, timeout: float) -> None:
    """Check, within ``timeout`` seconds, that a Dask scheduler answers at a ``tcp://`` address.

    A Dask server sends its handshake as soon as a connection opens: the probe reads its 8-byte
    length prefix and closes. It never lets a foreign server's bytes reach Dask's decoder (an
    HTTP reply read as a frame length asks for exabytes). Other schemes are left to Dask.

    Raises:
        ConnectionError: nothing listens, nothing is said within ``timeout``, or the bytes are
            not Dask's protocol (the message names the address and the fix).
    """
    m = _ADDRESS.fullmatch(addr)
    if m is None or m.group(1) != "tcp":
        return
    host, port = m.group(2).strip("[]"), int(m.group(3))
    fix = (
        f"start a scheduler there (`dask scheduler`, see docs/DISTRIBUTED.md), or unset "
        f"--scheduler / ${settings.SCHEDULER_ENV} to run in-process"
    )
    head = b""
    try:
        with socket.create_connection((host, port), timeout=timeout) as sock:
            sock.settimeout(timeout)
            while len(head) < 8:
                chunk = sock.recv(8 - len(head))
                if not chunk:
                    break
                head += chunk
    except TimeoutError:
        if not head:
            raise ConnectionError(
                f"{addr} accepted a connection but sent no Dask handshake "
                f"within {timeout:g} s: it is not a Dask scheduler; {fix}"
            ) from None
    except OSError as e:
        raise ConnectionError(
            f"could not reach the Dask scheduler at {addr} ({e}); {fix}"
        ) from None
    if len(head) < 8:
        raise ConnectionError(
            f"{addr} closed the connection without a Dask handshake: it is "
            f"not a Dask scheduler; {fix}"
        )
    (n,) = struct.unpack("<Q", head)
    if not 0 < n < _MAX_HANDSHAKE:
        raise ConnectionError(
            f"{addr} answered with bytes that are not Dask's protocol "
            f"({head!r}...): it is not a Dask scheduler; {fix}"
        )


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
    _probe_scheduler(addr, timeout)
    try:
        from distributed import Client
    except ImportError as e:  # pragma: no cover - dask[distributed] is a dependency
        raise ImportError(
            "a Dask scheduler was given but dask.distributed is not installed: "
            "pip install 'dask[distributed]'"
        ) from e
    try:
        client = Client(addr, timeout=timeout, set_as_default=False)
    except Exception as e:  # anything Dask raises on a bad peer becomes one clear error
        raise ConnectionError(
            f"could not reach the Dask scheduler at {addr!r} within {timeout:g} s ({e}). Start "
            f"one (`dask scheduler`, then `dask worker {addr}` on each machine; see "
            f"docs/DISTRIBUTED.md), or unset --scheduler / ${settings.SCHEDULER_ENV} to run "
            "in-process."
        ) from e
    try:
        client.wait_for_workers(1, timeout=timeout)
    except TimeoutError:
        client.close()
        raise ConnectionError(
            f"the Dask scheduler at {addr} has no workers (none joined within {timeout:g} s): "
            f"start `dask worker {addr}` on each machine and check that they can reach the "
            f"scheduler (their logs), or unset --scheduler / ${settings.SCHEDULER_ENV} to run "
            "in-process."
        ) from None
    utils.logger.info(
        "Dask: connected to %s (%d workers)", addr, len(client.scheduler_info().get("workers", {}))
    )
    return client


def _cluster_lost(client, desc: str, why: object) -> ConnectionError:
    """The one-line error of a cluster fault during ``desc``: it names the scheduler's address,
    says that cached work is kept, and how to go on."""
    addr = getattr(getattr(client, "scheduler", None), "address", None) or "the scheduler"
    return ConnectionError(
        f"the Dask cluster at {addr} was lost during {desc} ({why}); cached work is kept: "
        f"check that its `dask worker` processes run and reach the scheduler (a worker killed "
        f"again and again is often out of memory: see its log and --memory-limit), restart "
        f"the scheduler and its workers and rerun to resume, or unset --scheduler / "
        f"${settings.SCHEDULER_ENV} to run in-process"
    )


#: Seconds between checks that the cluster still has workers while waiting for results.
POLL_S = 5.0


def gather_in_order(client, futures: list, desc: str) -> list:
    """Results of ``futures`` in list order (a utils.progress bar counts completions).

    A task's own exception is re-raised as it is. A cluster fault (the scheduler killed, every
    worker lost for longer than :func:`vpr_core.settings.scheduler_timeout`, tasks cancelled)
    becomes one :class:`ConnectionError` (:func:`_cluster_lost`).
    """
    from distributed import KilledWorker
    from distributed.comm.core import CommClosedError
    from tornado.iostream import StreamClosedError

    faults = (CancelledError, CommClosedError, StreamClosedError, KilledWorker)
    patience = settings.scheduler_timeout()
    bar = utils.progress(None, total=len(futures), desc=desc, unit="task")
    pending = list(futures)
    seen = asked = time.monotonic()  # when workers (or utils.progress) were last seen / asked for
    try:
        while pending:
            still = []
            for f in pending:
                if f.done():
                    f.result()  # re-raises a worker's exception here, with its traceback
                    bar.update()
                else:
                    still.append(f)
            now = time.monotonic()
            if len(still) < len(pending):
                seen = now
            elif now - asked >= POLL_S:
                asked = now
                if client.scheduler_info().get("workers"):
                    seen = now
                elif now - seen >= patience:
                    raise _cluster_lost(client, desc, f"no worker left for {now - seen:.0f} s")
            pending = still
            if pending:
                time.sleep(0.05)
        return client.gather(futures)
    except faults as exc:
        raise _cluster_lost(client, desc, f"{type(exc).__name__}: {exc}") from exc
    finally:
        bar.close()
