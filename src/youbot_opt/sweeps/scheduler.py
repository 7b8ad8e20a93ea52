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

import os
from pathlib import Path
from typing import TYPE_CHECKING

from youbot_opt.exceptions import ParameterError, YoubotOptError

if TYPE_CHECKING:  # pragma: no cover - typing only; dask is optional
    from distributed import Client

__all__ = [
    "ClusterLostError",
    "cluster_threads",
    "connect",
    "is_dask_client",
    "is_scheduler_address",
]

_SCHEMES = ("tcp://", "tls://", "inproc://", "ucx://", "ws://", "wss://")
_CONNECT_TIMEOUT = 30.0  # [s] to reach a scheduler before giving up


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
    timeout: float = _CONNECT_TIMEOUT,
) -> Client:
    """Open a Dask client on a running scheduler (the caller closes it).

    Parameters
    ----------
    address : str, optional
        Scheduler address, e.g. ``"tcp://10.0.0.5:8786"``.
    scheduler_file : path-like, optional
        JSON file written by ``dask scheduler --scheduler-file FILE`` (or by
        dask-jobqueue / dask-mpi); exactly one of the two is given.
    timeout : float
        Time in [s] to reach the scheduler.

    Returns
    -------
    distributed.Client
        A connected client.

    Raises
    ------
    ParameterError
        If Dask is not installed, both or neither of ``address`` and
        ``scheduler_file`` are given, the address has no known scheme, the
        file is missing, or the scheduler cannot be reached within ``timeout``.
    """
    if (address is None) == (scheduler_file is None):
        raise ParameterError(
            "give exactly one of a scheduler address and a scheduler file", name="scheduler"
        )
    if address is not None and not is_scheduler_address(address):
        raise ParameterError(
            f"scheduler address must start with one of {', '.join(_SCHEMES)}, got {address!r}",
            name="scheduler",
            value=address,
        )
    if scheduler_file is not None:
        path = Path(scheduler_file).expanduser()
        if not path.is_file():
            raise ParameterError(
                f"scheduler file {str(path)!r} does not exist (start one with "
                "'dask scheduler --scheduler-file FILE')",
                name="scheduler_file",
                value=str(path),
            )
    client_type = _import_client()
    where = address if address is not None else f"the scheduler of {scheduler_file}"
    try:
        if address is not None:
            return client_type(address, timeout=timeout, set_as_default=False)
        return client_type(
            scheduler_file=str(Path(scheduler_file).expanduser()),  # type: ignore[arg-type]
            timeout=timeout,
            set_as_default=False,
        )
    except (OSError, TimeoutError) as exc:
        raise ParameterError(
            f"cannot reach {where} within {timeout:g} s: {exc}", name="scheduler"
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
