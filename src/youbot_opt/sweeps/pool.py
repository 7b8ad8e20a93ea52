"""Crash-isolating worker pool and :func:`run_tasks`: one failing item never stops a sweep.

:func:`run_tasks` runs keyed :class:`Task` s on a :class:`WorkerPool` (its own
or the caller's), in-process (``"serial"``), on any
:class:`concurrent.futures.Executor`, or on Dask (:mod:`.distributed`), and
reports every attempt through ``on_outcome``. A worker that dies or overruns
``timeout`` is charged to exactly its task and replaced; a task gets at most
``max_attempts`` attempts. Spec: the sweep layer of ``ARCHITECTURE.md``.

    out = run_tasks([Task(key="k0", fn=math.sqrt, args=(4.0,))], executor="serial")
"""

from __future__ import annotations

import contextlib
import logging
import math
import multiprocessing
import os
import pickle
import signal
import threading
import time
from collections.abc import Callable, Iterable
from concurrent.futures import FIRST_COMPLETED, Executor, Future, wait
from concurrent.futures.process import BrokenProcessPool
from concurrent.futures.thread import BrokenThreadPool
from multiprocessing.connection import Connection
from multiprocessing.connection import wait as wait_ready
from multiprocessing.context import BaseContext
from typing import TYPE_CHECKING, Any, Literal, Union

from youbot_opt._cores import usable_cores
from youbot_opt.exceptions import ParameterError
from youbot_opt.sweeps.distributed import run_batch, run_dask
from youbot_opt.sweeps.forked import can_fork, watch_parent
from youbot_opt.sweeps.scheduler import (
    cluster_threads,
    connect,
    is_dask_client,
    is_scheduler_address,
)
from youbot_opt.sweeps.tasks import Task, TaskOutcome, TaskRunner, failure_reason, invoke

if TYPE_CHECKING:  # pragma: no cover - typing only; dask is optional
    from distributed import Client

__all__ = [
    "ExecutorLike",
    "Task",
    "TaskOutcome",
    "WorkerPool",
    "default_workers",
    "process_context",
    "run_batch",
    "run_tasks",
]

_log = logging.getLogger(__name__)

_STOP_WAIT = 5.0  # [s] a stopping worker gets this long to exit before it is killed


def default_workers() -> int:
    """Count the CPUs this process may use (at least 1)."""
    return usable_cores()


def process_context() -> BaseContext:
    """Multiprocessing context of the pools created here: ``fork`` on Linux, else ``spawn``."""
    return multiprocessing.get_context("fork" if can_fork() else "spawn")


def _send(conn: Connection, obj: Any) -> None:
    conn.send_bytes(pickle.dumps(obj))  # pickled first: one that does not pickle sends nothing


def _recv(conn: Connection) -> Any:
    return pickle.loads(conn.recv_bytes())


# ------------------------------------------------------------------ workers
def _worker_main(
    conn: Connection,
    parent: int,
    initializer: Callable[..., object] | None,
    initargs: tuple[object, ...],
    init_blob: bytes | None,
) -> None:
    """Body of a worker process: run ``(key, fn, args)`` messages until ``None`` or EOF."""
    threading.Thread(target=watch_parent, args=(parent,), daemon=True).start()
    init_error = None
    try:
        if init_blob is not None:  # spawned: the initializer came pickled
            initializer, initargs = pickle.loads(init_blob)
        if initializer is not None:
            initializer(*initargs)
    except Exception as exc:  # reported with every task instead of a silent death
        init_error = f"worker initializer failed: {failure_reason(exc)}"
    while True:
        try:
            message = _recv(conn)
        except (EOFError, OSError):
            return
        if message is None:
            return
        key, fn, args = message
        tic = time.perf_counter()
        try:
            if init_error is not None:
                raise RuntimeError(init_error)
            value, wall = invoke(fn, args)
            _send(conn, (key, None, value, wall))  # a value that does not pickle sends nothing
        except Exception as exc:  # one failing task must not end the worker
            _send(conn, (key, failure_reason(exc), None, time.perf_counter() - tic))


def _death_reason(exitcode: int | None) -> str:
    if exitcode is not None and exitcode < 0:
        try:
            how = f"killed by signal {signal.Signals(-exitcode).name}"
        except ValueError:
            how = f"killed by signal {-exitcode}"
    else:
        how = f"exit code {exitcode}"
    return (
        f"worker process crashed ({how}; e.g. a segfault or an out-of-memory kill) "
        "while running this item"
    )


class _Worker:
    """One worker process, its pipe and the task it is running."""

    def __init__(
        self,
        ctx: BaseContext,
        initializer: Callable[..., object] | None,
        initargs: tuple[object, ...],
    ) -> None:
        self.conn, child = ctx.Pipe()
        args: tuple[Any, ...]
        if ctx.get_start_method() == "fork":  # inherited, not pickled (e.g. a built solver)
            args = (child, os.getpid(), initializer, initargs, None)
        else:
            args = (child, os.getpid(), None, (), pickle.dumps((initializer, initargs)))
        self.process = ctx.Process(  # type: ignore[attr-defined]
            target=_worker_main,
            args=args,
            daemon=True,  # also ended by multiprocessing at interpreter exit
            name="youbot_opt-worker",
        )
        self.process.start()
        child.close()
        self.key: str | None = None
        self.started = 0.0

    def stop(self, *, kill: bool) -> None:
        """End the process: ask it to exit (or kill it), wait, release the pipe."""
        if kill:
            self.process.kill()
        else:
            try:
                _send(self.conn, None)
            except OSError:
                pass
        self.process.join(None if kill else _STOP_WAIT)
        if self.process.is_alive():
            self.process.kill()
            self.process.join()
        self.conn.close()


class WorkerPool:
    """Worker processes kept across :func:`run_tasks` calls, one task per worker at a time.

    Use it as a context manager (or call :meth:`close`). Passing it to
    :func:`run_tasks` as ``executor`` runs the tasks in its workers, so a
    sequence of dependent items (e.g. warm-started Pareto points) reuses one
    warm process instead of starting one per item, yet a crash or a time-out
    of one item costs only its own worker (replaced on demand).

    Parameters
    ----------
    workers : int, optional
        Number of worker processes (default: the CPUs available).
    initializer : callable, optional
        Run once in every worker when it starts (e.g. to build a solver).
    initargs : tuple
        Its arguments (not pickled under ``fork``).
    """

    def __init__(
        self,
        workers: int | None = None,
        *,
        initializer: Callable[..., object] | None = None,
        initargs: tuple[object, ...] = (),
    ) -> None:
        self.workers = _check_workers(default_workers() if workers is None else workers)
        self._initializer = initializer
        self._initargs = initargs
        self._ctx = process_context()
        self._idle: list[_Worker] = []
        self._closed = False

    def _take(self) -> _Worker:
        if self._closed:
            raise ParameterError("this WorkerPool is closed", name="executor")
        while self._idle:
            worker = self._idle.pop()
            if worker.process.is_alive():
                return worker
            worker.stop(kill=True)
        return _Worker(self._ctx, self._initializer, self._initargs)

    def _give_back(self, worker: _Worker) -> None:
        worker.key = None
        if self._closed:
            worker.stop(kill=False)
        else:
            self._idle.append(worker)

    def close(self) -> None:
        """Stop every worker (safe to call more than once)."""
        self._closed = True
        while self._idle:
            self._idle.pop().stop(kill=False)

    def __enter__(self) -> WorkerPool:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _check_workers(workers: Any) -> int:
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ParameterError(f"workers must be an int >= 1, got {workers!r}", name="workers")
    return workers


ExecutorLike = Union[Literal["process", "serial"], Executor, WorkerPool, "Client", str]  # noqa: UP007
"""Where items run: ``"process"``, ``"serial"``, a :class:`WorkerPool`, any
:class:`concurrent.futures.Executor`, a :class:`distributed.Client` or a Dask
scheduler address (``"tcp://host:8786"``)."""


# ------------------------------------------------------------------- runner
class _LocalRunner(TaskRunner):
    """A :class:`TaskRunner` that also runs on worker pools and caller executors."""

    def run_workers(self, pool: WorkerPool) -> None:
        busy: list[_Worker] = []
        limit = min(self.workers, pool.workers)
        try:
            while self.pending or self.retry or busy:
                while len(busy) < limit and (self.pending or self.retry):
                    key = self.next_key()
                    task = self.tasks[key]
                    worker = pool._take()
                    try:
                        _send(worker.conn, (key, task.fn, task.args))
                    except (BrokenPipeError, ConnectionError):  # died idle: not this task's fault
                        worker.stop(kill=True)
                        self.retry.appendleft(key)
                        continue
                    except Exception as exc:  # the task does not pickle
                        pool._give_back(worker)
                        self.emit(key, None, f"cannot send the task: {failure_reason(exc)}", 0.0)
                        continue
                    worker.key, worker.started = key, time.monotonic()
                    busy.append(worker)
                if not busy:  # every task just sent failed to pickle: go on with the queues
                    continue
                wait_for = None
                if self.timeout is not None:
                    first = min(w.started for w in busy)
                    wait_for = max(0.0, first + self.timeout - time.monotonic())
                handles: list[Any] = [w.conn for w in busy] + [w.process.sentinel for w in busy]
                ready = set(wait_ready(handles, timeout=wait_for))
                for worker in list(busy):
                    if worker.conn in ready or worker.process.sentinel in ready:
                        busy.remove(worker)
                        self._collect(pool, worker)
                    elif (
                        self.timeout is not None
                        and time.monotonic() - worker.started >= self.timeout
                    ):
                        busy.remove(worker)
                        key = str(worker.key)
                        worker.stop(kill=True)
                        self.emit(key, None, f"timeout after {self.timeout:g} s", self.timeout)
        finally:
            for worker in busy:  # interrupted (e.g. KeyboardInterrupt): abandon their tasks
                worker.stop(kill=True)

    def _collect(self, pool: WorkerPool, worker: _Worker) -> None:
        """Read the reply of a worker that became ready, or charge its task with its death."""
        key = str(worker.key)
        wall = time.monotonic() - worker.started
        try:
            reply = _recv(worker.conn) if worker.conn.poll() else None
        except (EOFError, OSError):
            reply = None
        if reply is None:
            worker.process.join(_STOP_WAIT)
            exitcode = worker.process.exitcode
            worker.stop(kill=True)
            self.emit(key, None, _death_reason(exitcode), wall)
            return
        pool._give_back(worker)
        got, error, value, wall = reply
        assert got == key, f"worker answered for {got!r} while running {key!r}"
        self.emit(key, value, error, wall)

    def run_executor(self, pool: Executor) -> None:
        """Run on a caller's executor: it cannot be rebuilt, so a broken one ends the sweep."""
        inflight: dict[Future[Any], str] = {}
        while self.pending or self.retry or inflight:
            while len(inflight) < self.workers and (self.pending or self.retry):
                key = self.next_key()
                task = self.tasks[key]
                inflight[pool.submit(invoke, task.fn, task.args)] = key
            done, _ = wait(inflight, return_when=FIRST_COMPLETED)
            broken: list[str] = []
            for fut in done:
                key = inflight.pop(fut)
                exc = fut.exception()
                if isinstance(exc, BrokenProcessPool | BrokenThreadPool):
                    broken.append(key)
                elif exc is not None:
                    self.emit(key, None, failure_reason(exc), 0.0)
                else:
                    value, wall = fut.result()
                    self.emit(key, value, None, wall)
            if broken:
                why = "the executor broke (a worker crashed) and cannot be rebuilt by youbot_opt"
                for key in [*broken, *inflight.values()]:
                    self.emit(key, None, f"worker process crashed or was lost; {why}", 0.0)
                self.abandon(why)
                return


def run_tasks(
    tasks: Iterable[Task],
    *,
    executor: ExecutorLike = "process",
    workers: int | None = None,
    initializer: Callable[..., object] | None = None,
    initargs: tuple[object, ...] = (),
    max_attempts: int = 2,
    on_outcome: Callable[[TaskOutcome], None] | None = None,
    timeout: float | None = None,
    batch_size: int | None = None,
    keep_values: bool = True,
    deadline: float | None = None,
) -> dict[str, TaskOutcome]:
    """Run keyed tasks, retrying failures, and report each attempt as it ends.

    Parameters
    ----------
    tasks : iterable of Task
        The work, with unique keys.
    executor : {"process", "serial"}, WorkerPool, Executor, distributed.Client or str
        ``"process"`` (default): a :class:`WorkerPool` owned by this call;
        a ``WorkerPool``: its workers (kept open; its own initializer applies);
        ``"serial"``: in this process; an ``Executor``: used as is (not shut
        down; ``initializer`` is not run on it, and a broken executor ends the
        remaining tasks as failed); a Dask ``Client`` or a scheduler address
        (``"tcp://host:8786"``, connected and closed here): batches of tasks
        on the cluster, the initializer sent once per worker, a batch whose
        worker died re-run task by task (see ``docs/scaling.md``).
    workers : int, optional
        Tasks (Dask: batches) in flight at once; default: the CPUs available,
        a pool's size, or the Dask cluster's total threads.
    initializer : callable, optional
        Run once in every worker process of an owned pool (e.g. to build a solver).
    initargs : tuple
        Its arguments (not pickled under ``fork``).
    max_attempts : int
        Attempts per task in total, including earlier runs' (>= 1).
    on_outcome : callable, optional
        Called in this process with every :class:`TaskOutcome`, in completion order.
    timeout : float, optional
        Wall-clock limit in [s] per attempt (worker pools only; default none):
        a task still running then is killed with its worker and recorded as
        failed with ``"timeout after <timeout> s"``.
    batch_size : int, optional
        Tasks per Dask task (Dask only); default: an eighth of the tasks
        per thread, at most 64 (1 for small sweeps).
    keep_values : bool
        Return every task's last outcome (default); ``False`` returns only
        those of tasks whose last attempt failed, without values
        (``on_outcome`` still sees every outcome), so a long sweep's values
        are not held by this call.
    deadline : float, optional
        A :func:`time.monotonic` instant after which no new task begins (checked
        as attempts end: the first ``workers`` tasks always begin; tasks running
        then finish, and their retries run). A task it stopped gets no outcome.

    Returns
    -------
    dict of str to TaskOutcome
        The last outcome of each task run here, by key (none for a task the
        ``deadline`` stopped).

    Raises
    ------
    ParameterError
        On duplicate keys, ``workers < 1``, ``max_attempts < 1``, a
        ``timeout <= 0`` or one without a worker pool, or an unknown executor.
    ClusterLostError
        If the Dask scheduler is lost mid-run (outcomes already reported stay reported).
    """
    task_list = list(tasks)
    keys = [t.key for t in task_list]
    if len(set(keys)) != len(keys):
        dup = sorted({k for k in keys if keys.count(k) > 1})
        raise ParameterError(f"task keys must be unique, repeated: {dup}", name="tasks")
    client = None
    own_client = is_scheduler_address(executor)
    if own_client:
        client = connect(str(executor))
    elif is_dask_client(executor):
        client = executor  # type: ignore[assignment]
    try:
        return _run(
            task_list,
            executor,
            client,
            workers=workers,
            initializer=initializer,
            initargs=initargs,
            max_attempts=max_attempts,
            on_outcome=on_outcome,
            timeout=timeout,
            batch_size=batch_size,
            keep_values=keep_values,
            deadline=deadline,
        )
    finally:
        if own_client and client is not None:
            with contextlib.suppress(Exception):
                client.close()


def _run(
    task_list: list[Task],
    executor: ExecutorLike,
    client: Client | None,
    *,
    workers: int | None,
    initializer: Callable[..., object] | None,
    initargs: tuple[object, ...],
    max_attempts: int,
    on_outcome: Callable[[TaskOutcome], None] | None,
    timeout: float | None,
    batch_size: int | None,
    keep_values: bool,
    deadline: float | None,
) -> dict[str, TaskOutcome]:
    if workers is None:
        if isinstance(executor, WorkerPool):
            workers = executor.workers
        elif client is not None:
            workers = cluster_threads(client)
        elif is_dask_client(getattr(executor, "_client", None)):  # client.get_executor()
            workers = cluster_threads(executor._client)  # type: ignore[union-attr]
        else:
            workers = getattr(executor, "_max_workers", None) or default_workers()
    _check_workers(workers)
    if isinstance(max_attempts, bool) or not isinstance(max_attempts, int) or max_attempts < 1:
        raise ParameterError(
            f"max_attempts must be an int >= 1, got {max_attempts!r}", name="max_attempts"
        )
    if batch_size is not None and (
        isinstance(batch_size, bool) or not isinstance(batch_size, int) or batch_size < 1
    ):
        raise ParameterError(
            f"batch_size must be an int >= 1, got {batch_size!r}", name="batch_size"
        )
    pooled = executor == "process" or isinstance(executor, WorkerPool)
    if not (pooled or executor == "serial" or isinstance(executor, Executor) or client is not None):
        raise ParameterError(
            f"executor must be 'process', 'serial', a WorkerPool, a "
            f"concurrent.futures.Executor, a Dask Client or a scheduler address "
            f"('tcp://host:port'), got {executor!r}",
            name="executor",
        )
    if timeout is not None:
        if not (isinstance(timeout, int | float) and math.isfinite(timeout) and timeout > 0):
            raise ParameterError(f"timeout must be > 0 [s], got {timeout!r}", name="timeout")
        if not pooled:
            raise ParameterError(
                f"a timeout needs executor='process' or a WorkerPool (a task cannot be "
                f"stopped otherwise), got executor={executor!r}",
                name="timeout",
            )
    runner = _LocalRunner(
        task_list,
        workers,
        max_attempts,
        timeout,
        on_outcome,
        keep_values=keep_values,
        deadline=deadline,
    )
    if executor == "serial":
        if initializer is not None:
            initializer(*initargs)
        runner.run_serial()
    elif isinstance(executor, WorkerPool):
        runner.run_workers(executor)
    elif executor == "process":
        with WorkerPool(workers, initializer=initializer, initargs=initargs) as pool:
            runner.run_workers(pool)
    elif client is not None:
        run_dask(runner, client, initializer, initargs, batch_size)
    else:
        assert isinstance(executor, Executor)
        runner.run_executor(executor)
    return runner.outcomes
