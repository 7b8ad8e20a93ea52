"""How a sweep runs: :class:`SweepOptions`, the one argument every sweep takes for it.

Owns the execution settings shared by the multistarts, the Pareto sweep and
the bound-scaling study (spec: rule 6 of ``ARCHITECTURE.md``): where items
run, how many at once (:func:`resolve_executor`), the per-attempt time limit,
the attempts per item, the output directory a rerun resumes from, and the
progress callback. What a sweep computes (its solver, starts, weights, seeds)
stays in its own arguments; how it is run is this one frozen value.

    sweep = SweepOptions(executor="serial", out="runs/ms", max_attempts=3)
    res = run_multistart(solver, 50, sweep=sweep)
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from concurrent.futures import Executor
from dataclasses import dataclass, replace
from pathlib import Path

from youbot_opt.exceptions import ParameterError
from youbot_opt.sweeps.pool import ExecutorLike, WorkerPool, default_workers
from youbot_opt.sweeps.scheduler import (
    cluster_threads,
    connect,
    is_dask_client,
    is_scheduler_address,
)

__all__ = ["SweepOptions", "resolve_executor"]


@dataclass(frozen=True, slots=True, kw_only=True)
class SweepOptions:
    """Execution settings of a sweep (all optional; the defaults run a process pool).

    Attributes
    ----------
    executor : {"process", "serial"}, WorkerPool, Executor, distributed.Client or str, optional
        Where items run (:func:`youbot_opt.sweeps.pool.run_tasks`): a process
        pool owned by the sweep, a caller's ``WorkerPool``, this process, a
        caller's executor (not shut down by the sweep), a Dask ``Client`` or
        a Dask scheduler address such as ``"tcp://10.0.0.5:8786"``
        (``docs/scaling.md``). Default ``None``: the sweep's default,
        ``"process"`` (the IK-path multistart: ``"serial"`` when ``workers``
        is 1).
    workers : int, optional
        Items (on Dask: batches) in flight at once (>= 1); default: the CPUs
        available, a caller's pool's size, or the Dask cluster's total threads.
    timeout : float, optional
        Wall-clock limit in [s] per attempt (worker pools only): an item still
        running then is killed with its worker and recorded as failed
        (``"timeout after <timeout> s"``). Default: none.
    max_attempts : int
        Attempts per item in total, earlier runs on ``out`` included (default
        2: a failed item is retried once).
    out : path-like, optional
        Output directory: each finished item is saved there as it completes
        and a rerun with the same parameters resumes.
    progress : callable ``(done, total, last)``, optional
        Called in this process as items finish; ``last`` is what the sweep
        reports per item (see each sweep).
    shard : tuple of (int, int), optional
        ``(i, k)`` with ``1 <= i <= k``: run only this share of the items
        (positions ``i - 1, i - 1 + k, ...``) into ``out`` and return a
        :class:`~youbot_opt.sweeps.resume.ShardReport`; a job array runs
        the ``k`` shards into one shared folder and a run without ``shard``
        collects (it loads what the shards saved and runs what is missing).
    batch_size : int, optional
        Items per Dask task (Dask only; default: an eighth of the items per
        cluster thread, at most 64). A batch whose worker dies is re-run
        item by item, so a crash is still charged to one item.
    keep_results : bool
        Keep every item's full result in memory (default). ``False`` (needs
        ``out``): the sweep keeps each item's summary and only the full
        results of the best item and of the distinct optima; every other
        result stays in ``out``, where it can be loaded later. Driver memory
        then does not grow with the results (``docs/scaling.md``).
    worker_writes : bool, optional
        Workers write their own item files into ``out`` (the driver checks
        each file's SHA-256 and records it) instead of sending every result
        to the driver to write. Default ``None``: on for this machine's
        workers, off on Dask and other executors, whose workers may not
        share ``out``; set ``True`` when they do (a shared filesystem).
    """

    executor: ExecutorLike | None = None
    workers: int | None = None
    timeout: float | None = None
    max_attempts: int = 2
    out: str | os.PathLike[str] | None = None
    progress: Callable[..., None] | None = None  # (done, total, last): last per sweep
    batch_size: int | None = None
    shard: tuple[int, int] | None = None
    keep_results: bool = True
    worker_writes: bool | None = None

    def __post_init__(self) -> None:
        ex = self.executor
        if not (
            (isinstance(ex, str | None) and ex in (None, "process", "serial"))
            or isinstance(ex, WorkerPool | Executor)
            or is_dask_client(ex)
            or is_scheduler_address(ex)
        ):
            raise ParameterError(
                f"executor must be 'process', 'serial', a WorkerPool, a "
                f"concurrent.futures.Executor, a Dask Client or a Dask scheduler address "
                f"('tcp://host:port'), got {ex!r}",
                name="executor",
                value=ex,
            )
        s = self.shard
        if s is not None:
            ok = (
                isinstance(s, tuple)
                and len(s) == 2
                and all(isinstance(x, int) and not isinstance(x, bool) for x in s)
                and 1 <= s[0] <= s[1]
            )
            if not ok:
                raise ParameterError(
                    f"shard must be (i, k) with 1 <= i <= k, got {s!r}", name="shard", value=s
                )
            if self.out is None:
                raise ParameterError(
                    "a shard run needs out= (the folder the shards share)", name="shard", value=s
                )
        if not isinstance(self.keep_results, bool):
            raise ParameterError(
                f"keep_results must be True or False, got {self.keep_results!r}",
                name="keep_results",
                value=self.keep_results,
            )
        if not isinstance(self.worker_writes, bool | None):
            raise ParameterError(
                f"worker_writes must be True, False or None, got {self.worker_writes!r}",
                name="worker_writes",
                value=self.worker_writes,
            )
        if not self.keep_results and self.out is None:
            raise ParameterError(
                "keep_results=False needs out= (the results not kept stay there)",
                name="keep_results",
                value=False,
            )
        b = self.batch_size
        if b is not None and (isinstance(b, bool) or not isinstance(b, int) or b < 1):
            raise ParameterError(
                f"batch_size must be an int >= 1, got {b!r}", name="batch_size", value=b
            )
        w = self.workers
        if w is not None and (isinstance(w, bool) or not isinstance(w, int) or w < 1):
            raise ParameterError(f"workers must be an int >= 1, got {w!r}", name="workers", value=w)
        m = self.max_attempts
        if isinstance(m, bool) or not isinstance(m, int) or m < 1:
            raise ParameterError(
                f"max_attempts must be an int >= 1, got {m!r}", name="max_attempts", value=m
            )
        t = self.timeout
        if t is not None and not (
            isinstance(t, int | float) and not isinstance(t, bool) and math.isfinite(t) and t > 0
        ):
            raise ParameterError(f"timeout must be > 0 [s], got {t!r}", name="timeout", value=t)

    @property
    def distributed(self) -> bool:
        """True if items run on a Dask cluster (a client or a scheduler address)."""
        return is_dask_client(self.executor) or is_scheduler_address(self.executor)

    def with_executor(self, default: ExecutorLike) -> SweepOptions:
        """Return these options with ``executor`` set to ``default`` if it is ``None``."""
        return self if self.executor is not None else replace(self, executor=default)

    @property
    def writes_in_workers(self) -> bool:
        """True if workers write their own item files (see ``worker_writes``)."""
        if self.worker_writes is not None:
            return self.worker_writes
        ex = self.executor
        return ex in (None, "process", "serial") or isinstance(ex, WorkerPool)

    @property
    def directory(self) -> Path | None:
        """``out`` as a :class:`~pathlib.Path` (``None``: nothing is saved)."""
        return None if self.out is None else Path(self.out)


def resolve_executor(sweep: SweepOptions) -> tuple[ExecutorLike, int]:
    """Return where the starts of a multistart run and how many run at once.

    ``executor`` ``None`` becomes ``"serial"`` when ``workers`` is 1, else
    ``"process"``; the count is ``workers`` if given, else the CPUs available,
    the caller's pool size or the Dask cluster's total threads.
    """
    executor, max_workers = sweep.executor, sweep.workers
    if executor is None:
        workers = max_workers or default_workers()
        executor = "serial" if workers == 1 else "process"
    elif executor == "serial":
        workers = 1
    elif executor == "process":
        workers = max_workers or default_workers()
    elif sweep.distributed:  # a Dask cluster: its total threads unless workers says otherwise
        workers = max_workers or _dask_threads(executor)
    else:  # the caller's pool or executor: its size unless max_workers says otherwise
        size = getattr(executor, "workers", None) or getattr(executor, "_max_workers", None)
        dask_client = getattr(executor, "_client", None)  # client.get_executor()
        if size is None and dask_client is not None and is_dask_client(dask_client):
            size = cluster_threads(dask_client)
        workers = max_workers or int(size or default_workers())
    return executor, workers


def _dask_threads(executor: object) -> int:
    """Total threads of the Dask cluster of a client or scheduler address."""
    if is_dask_client(executor):
        return cluster_threads(executor)  # type: ignore[arg-type]
    client = connect(str(executor))
    try:
        return cluster_threads(client)
    finally:
        client.close()
