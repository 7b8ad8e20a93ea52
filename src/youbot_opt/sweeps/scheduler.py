"""Dask distributed as a sweep executor: connecting, sizing, and the error of a lost cluster.

Dask is an optional extra (``pip install youbot_opt[dask]``), imported only
when a client is asked for. :func:`connect` opens a client from an address or
a scheduler file, :func:`cluster_threads` sizes the work in flight from the
cluster's threads, :func:`is_dask_client` / :func:`is_scheduler_address`
recognise ``SweepOptions(executor=...)``, and :class:`ClusterLostError` stops a
sweep whose scheduler went away. Guide: ``docs/scaling.md``.

    client = connect(scheduler_file="~/scheduler.json"); n = cluster_threads(client)
"""

from __future__ import annotations

import asyncio
import json
import os
import stat
import threading
from pathlib import Path
from typing import TYPE_CHECKING, Any
from urllib.parse import urlsplit

from youbot_opt.exceptions import ParameterError, YoubotOptError

if TYPE_CHECKING:  # pragma: no cover - typing only; dask is optional
    from distributed import Client

__all__ = [
    "CONNECT_TIMEOUT",
    "MAX_ADDRESS_CHARS",
    "MAX_SCHEDULER_FILE_BYTES",
    "ClusterLostError",
    "check_scheduler_address",
    "cluster_threads",
    "connect",
    "is_dask_client",
    "is_scheduler_address",
    "read_scheduler_file",
]

# The schemes of a scheduler on another process or host (``inproc://`` names a
# scheduler inside this process: pass its ``Client`` instead).
_SCHEMES = ("tcp://", "tls://", "ucx://", "ws://", "wss://")

#: Time in [s] to reach a scheduler *and* finish Dask's handshake with it; a
#: listener that accepts and never answers is given up after this long.
CONNECT_TIMEOUT = 30.0

#: Longest scheduler address accepted, in characters (a host name has at most 253).
MAX_ADDRESS_CHARS = 300

#: Largest scheduler file read, in bytes (Dask's own are a few hundred bytes).
MAX_SCHEDULER_FILE_BYTES = 1 << 20


class ClusterLostError(YoubotOptError):
    """The Dask scheduler (or every worker) went away while a sweep was running.

    The message says which items were saved and how to resume; items already
    finished are never lost (each is saved as it completes).
    """


def is_dask_client(obj: object) -> bool:
    """Tell whether ``obj`` is a :class:`distributed.Client` (checked without importing Dask)."""
    return any(
        c.__name__ == "Client" and c.__module__.split(".")[0] == "distributed"
        for c in type(obj).__mro__
    )


def is_scheduler_address(obj: object) -> bool:
    """Tell whether ``obj`` is a string naming a Dask scheduler, e.g. ``"tcp://10.0.0.5:8786"``."""
    return isinstance(obj, str) and obj.startswith(_SCHEMES)


def check_scheduler_address(address: object, *, name: str = "scheduler") -> str:
    """Return ``address`` if it is a sane scheduler address, else raise a one-line error.

    Sane: a string of at most :data:`MAX_ADDRESS_CHARS` characters,
    ``SCHEME://HOST:PORT`` with a supported scheme (tcp, tls, ucx, ws, wss),
    a host and a port in 1..65535, no spaces or control characters.

    Raises
    ------
    ParameterError
        Naming what is wrong, with ``name`` as the parameter.
    """
    if not isinstance(address, str):
        raise ParameterError(
            f"scheduler address must be a string such as tcp://10.0.0.5:8786, "
            f"got {type(address).__name__}",
            name=name,
        )
    if len(address) > MAX_ADDRESS_CHARS:
        raise ParameterError(
            f"scheduler address has {len(address)} characters, more than the limit of "
            f"{MAX_ADDRESS_CHARS} (MAX_ADDRESS_CHARS)",
            name=name,
        )
    example = "such as tcp://10.0.0.5:8786"
    if not address.startswith(_SCHEMES):
        raise ParameterError(
            f"scheduler address must start with one of {', '.join(_SCHEMES)} ({example}), "
            f"got {address!r}",
            name=name,
        )
    if any(c.isspace() or not c.isprintable() for c in address):
        raise ParameterError(
            f"scheduler address {address!r} contains spaces or control characters", name=name
        )
    try:
        parts = urlsplit(address)
        port = parts.port
    except ValueError as exc:
        raise ParameterError(
            f"scheduler address {address!r} is not SCHEME://HOST:PORT ({exc})", name=name
        ) from exc
    if not parts.hostname or port is None or not 1 <= port <= 65535:
        raise ParameterError(
            f"scheduler address {address!r} needs a host and a port in 1..65535 ({example})",
            name=name,
        )
    if parts.path not in ("", "/") or parts.query or parts.fragment or parts.username:
        raise ParameterError(
            f"scheduler address {address!r} must be SCHEME://HOST:PORT, nothing more", name=name
        )
    return address


def read_scheduler_file(path: str | os.PathLike[str], *, name: str = "scheduler_file") -> str:
    """Read the ``address`` of a Dask scheduler file, without blocking or reading without end.

    The file must be a regular file (not a FIFO or a device) of at most
    :data:`MAX_SCHEDULER_FILE_BYTES` bytes, holding JSON with an ``address``;
    the address is checked by :func:`check_scheduler_address`.

    Raises
    ------
    ParameterError
        If the file is missing, not a regular file, too large, not JSON with
        an ``address``, or the address is not sane.
    """
    file = Path(path).expanduser()
    where = f"scheduler file {str(file)!r}"
    try:  # O_NONBLOCK: opening a FIFO with no writer must not wait for one
        fd = os.open(file, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError as exc:
        raise ParameterError(
            f"{where} does not exist (start a scheduler with "
            "'dask scheduler --scheduler-file FILE')",
            name=name,
        ) from exc
    except OSError as exc:
        raise ParameterError(f"{where} cannot be opened: {exc.strerror or exc}", name=name) from exc
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise ParameterError(
                f"{where} is not a regular file (a FIFO, device or folder); "
                "give the JSON file the scheduler wrote",
                name=name,
            )
        data = os.read(fd, MAX_SCHEDULER_FILE_BYTES + 1)
    except OSError as exc:
        raise ParameterError(f"{where} cannot be read: {exc.strerror or exc}", name=name) from exc
    finally:
        os.close(fd)
    if len(data) > MAX_SCHEDULER_FILE_BYTES:
        raise ParameterError(
            f"{where} is larger than the limit of {MAX_SCHEDULER_FILE_BYTES} bytes "
            "(MAX_SCHEDULER_FILE_BYTES); it is not a Dask scheduler file",
            name=name,
        )
    try:
        content: Any = json.loads(data.decode("utf-8"))
        address = content["address"]
    except (ValueError, KeyError, TypeError, RecursionError) as exc:
        raise ParameterError(
            f"{where} is not a Dask scheduler file (JSON with an 'address'): {type(exc).__name__}",
            name=name,
        ) from exc
    return check_scheduler_address(address, name=name)


def _import_client() -> type[Client]:
    try:
        from distributed import Client
    except ImportError as exc:
        raise ParameterError(
            "running a sweep on a Dask cluster needs Dask distributed: "
            "pip install 'youbot_opt[dask]' (or dask[distributed])",
            name="executor",
        ) from exc
    return Client


def connect(
    address: str | None = None,
    *,
    scheduler_file: str | os.PathLike[str] | None = None,
    timeout: float = CONNECT_TIMEOUT,
) -> Client:
    """Open a Dask client on a running scheduler (the caller closes it).

    Parameters
    ----------
    address : str, optional
        Scheduler address, e.g. ``"tcp://10.0.0.5:8786"`` (checked by
        :func:`check_scheduler_address` before connecting).
    scheduler_file : path-like, optional
        JSON file written by ``dask scheduler --scheduler-file FILE`` (or by
        dask-jobqueue / dask-mpi), read by :func:`read_scheduler_file`;
        exactly one of the two is given.
    timeout : float
        Time in [s] to reach the scheduler and finish the handshake
        (:data:`CONNECT_TIMEOUT` by default); a scheduler that has not
        answered by then is given up.

    Returns
    -------
    distributed.Client
        A connected client.

    Raises
    ------
    ParameterError
        If Dask is not installed, both or neither of ``address`` and
        ``scheduler_file`` are given, the address is not sane, the file is
        missing or not a scheduler file, or the scheduler cannot be reached
        (or answers with something that is not Dask) within ``timeout``.
    """
    if (address is None) == (scheduler_file is None):
        raise ParameterError(
            "give exactly one of a scheduler address and a scheduler file", name="scheduler"
        )
    if not timeout > 0:
        raise ParameterError(f"timeout must be > 0 [s], got {timeout!r}", name="timeout")
    if address is not None:
        address = check_scheduler_address(address)
    else:
        address = read_scheduler_file(scheduler_file)  # type: ignore[arg-type]
    client_type = _import_client()
    return _bounded_connect(client_type, address, float(timeout))


def _bounded_connect(client_type: type[Client], address: str, timeout: float) -> Client:
    """Probe ``address`` with Dask's handshake within ``timeout`` [s], then open the client.

    Dask bounds the TCP connection but not its handshake (a listener that
    accepts and never answers holds it forever), and a listener that answers
    garbage raises whatever its decoder raises. The probe runs in a helper
    thread with its own event loop (so it also works under a running loop,
    e.g. in a notebook) and ends in one :class:`ParameterError` naming the
    address and the limit; only a scheduler that completed the handshake is
    given to ``client_type``.
    """
    outcome: dict[str, BaseException] = {}

    async def probe() -> None:
        from distributed.comm import connect as comm_connect

        comm = await asyncio.wait_for(comm_connect(address, timeout=timeout), timeout)
        await comm.close()

    def attempt() -> None:
        try:
            asyncio.run(probe())
        except BaseException as exc:  # noqa: BLE001 - reported by the waiting thread
            outcome["error"] = exc

    thread = threading.Thread(target=attempt, name=f"dask-probe {address}", daemon=True)
    thread.start()
    thread.join(timeout + 1.0)  # the probe bounds itself; this is a second guard
    exc = outcome.get("error")
    if thread.is_alive() or isinstance(exc, TimeoutError):
        raise ParameterError(
            f"the Dask scheduler at {address} did not answer within {timeout:g} s "
            "(CONNECT_TIMEOUT); is a Dask scheduler listening there?",
            name="scheduler",
        ) from exc
    if exc is not None:
        detail = (
            f"{exc.strerror or exc}"
            if isinstance(exc, OSError)
            else f"it answered with something that is not Dask, or the address needs "
            f"settings Dask lacks ({type(exc).__name__})"
        )
        raise ParameterError(
            f"cannot connect to the Dask scheduler at {address} within {timeout:g} s: {detail}",
            name="scheduler",
        ) from exc
    try:
        return client_type(address, timeout=timeout, set_as_default=False)
    except (OSError, TimeoutError) as exc:
        raise ParameterError(
            f"cannot reach the Dask scheduler at {address} within {timeout:g} s: {exc}",
            name="scheduler",
        ) from exc


def cluster_threads(client: Client) -> int:
    """Total worker threads of the cluster behind ``client`` (at least 1).

    A cluster that has no worker yet (e.g. dask-jobqueue jobs still queued)
    counts as 1; the sweep keeps that much in flight until workers arrive.
    """
    try:
        threads = sum(int(n) for n in client.nthreads().values())
    except (OSError, TimeoutError) as exc:
        raise ClusterLostError(f"cannot reach the Dask scheduler: {exc}") from exc
    return max(1, threads)
