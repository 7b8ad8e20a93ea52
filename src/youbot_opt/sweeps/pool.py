"""Crash-isolating worker pool and :func:`run_tasks`: one failing item never stops a sweep.

Owns how a sweep's keyed items run (spec: the sweep layer of ``ARCHITECTURE.md``).
:func:`run_tasks` runs :class:`Task` s on ``"process"`` (a :class:`WorkerPool`
it owns, default), on a caller's :class:`WorkerPool` (kept across calls), on
``"serial"`` (in-process) or on any :class:`concurrent.futures.Executor`, and
reports every attempt through ``on_outcome`` as it ends. In a worker pool each
worker runs one task at a time and the parent knows which, so a worker that
dies (segfault, out-of-memory kill) or overruns ``timeout`` is charged to
exactly that task and replaced; a task gets at most ``max_attempts`` attempts.

    out = run_tasks([Task(key="k0", fn=math.sqrt, args=(4.0,))], executor="serial")
"""

from __future__ import annotations

import contextlib
import copyreg
import functools
import hashlib
import io
import logging
import math
import multiprocessing
import os
import pickle
import signal
import sys
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable
from concurrent.futures import FIRST_COMPLETED, Executor, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from concurrent.futures.thread import BrokenThreadPool
from dataclasses import dataclass, replace
from multiprocessing.connection import Connection
from multiprocessing.connection import wait as wait_ready
from multiprocessing.context import BaseContext
from multiprocessing.reduction import ForkingPickler
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, Literal, Union

from youbot_opt.exceptions import ParameterError
from youbot_opt.sweeps.scheduler import (
    ClusterLostError,
    cluster_threads,
    connect,
    is_dask_client,
    is_scheduler_address,
)

if TYPE_CHECKING:  # pragma: no cover - typing only; dask is optional
    from distributed import Client
    from distributed import Future as DaskFuture

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

_PARENT_POLL = 0.2  # [s] how often a worker checks that its parent is alive
_STOP_WAIT = 5.0  # [s] a stopping worker gets this long to exit before it is killed


def default_workers() -> int:
    """Count the CPUs this process may use (at least 1)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def process_context() -> BaseContext:
    """Multiprocessing context of the pools created here: ``fork`` on Linux, else ``spawn``."""
    if sys.platform.startswith("linux") and "fork" in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("fork")
    return multiprocessing.get_context("spawn")


# ----------------------------------------------------------------- pickling
def _mappingproxy(d: dict[Any, Any]) -> MappingProxyType[Any, Any]:
    return MappingProxyType(d)


def _reduce_mappingproxy(m: MappingProxyType[Any, Any]) -> tuple[Any, ...]:
    return _mappingproxy, (dict(m),)


class _SweepPickler(ForkingPickler):
    """multiprocessing's pickler that also sends read-only mappings, as a copied dict.

    Read-only mappings (e.g. ``IpoptOptions.extra``) cannot be pickled by
    default. The reducer is added to this pickler's own table only, so
    importing the package registers nothing in :mod:`multiprocessing` or
    :mod:`copyreg`.
    """

    def __init__(self, file: Any, protocol: int | None = None) -> None:
        super().__init__(file, protocol)
        table = dict(getattr(self, "dispatch_table", copyreg.dispatch_table))
        table[MappingProxyType] = _reduce_mappingproxy
        self.dispatch_table = table


def _dumps(obj: Any) -> bytes:
    """Pickle ``obj`` for a worker pipe (or a process executor) with :class:`_SweepPickler`."""
    buf = io.BytesIO()
    _SweepPickler(buf, pickle.HIGHEST_PROTOCOL).dump(obj)
    return buf.getvalue()


def _send(conn: Connection, obj: Any) -> None:
    conn.send_bytes(_dumps(obj))  # pickles first: a message that does not pickle sends nothing


def _recv(conn: Connection) -> Any:
    return pickle.loads(conn.recv_bytes())


# ------------------------------------------------------------------ workers
def _watch_parent(parent: int) -> None:
    while True:
        time.sleep(_PARENT_POLL)
        if os.getppid() != parent:
            os._exit(1)


def _invoke(fn: Callable[..., Any], args: tuple[Any, ...]) -> tuple[Any, float]:
    """Run one task; returns its value and wall time in [s]."""
    tic = time.perf_counter()
    value = fn(*args)
    return value, time.perf_counter() - tic


def _invoke_pickled(blob: bytes) -> bytes:
    """Run a pickled ``(fn, args)`` in a process executor; return the pickled ``(value, wall)``."""
    fn, args = pickle.loads(blob)
    return _dumps(_invoke(fn, args))


def _worker_main(
    conn: Connection,
    parent: int,
    initializer: Callable[..., Any] | None,
    initargs: tuple[Any, ...],
    init_blob: bytes | None,
) -> None:
    """Body of a worker process: run ``(key, fn, args)`` messages until ``None`` or EOF."""
    threading.Thread(target=_watch_parent, args=(parent,), daemon=True).start()
    init_error = None
    try:
        if init_blob is not None:  # spawned: the initializer came pickled by _SweepPickler
            initializer, initargs = pickle.loads(init_blob)
        if initializer is not None:
            initializer(*initargs)
    except Exception as exc:  # reported with every task instead of a silent death
        init_error = f"worker initializer failed: {_reason(exc)}"
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
            value, wall = _invoke(fn, args)
            _send(conn, (key, None, value, wall))  # a value that does not pickle sends nothing
        except Exception as exc:  # one failing task must not end the worker
            _send(conn, (key, _reason(exc), None, time.perf_counter() - tic))


def _reason(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[-1] if text else ''}".rstrip(": ")


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

    def __init__(self, ctx: BaseContext, initializer: Any, initargs: tuple[Any, ...]) -> None:
        self.conn, child = ctx.Pipe()
        args: tuple[Any, ...]
        if ctx.get_start_method() == "fork":  # inherited, not pickled (e.g. a built solver)
            args = (child, os.getpid(), initializer, initargs, None)
        else:
            args = (child, os.getpid(), None, (), _dumps((initializer, initargs)))
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
        initializer: Callable[..., Any] | None = None,
        initargs: tuple[Any, ...] = (),
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


# ------------------------------------------------------------------- tasks
@dataclass(frozen=True, slots=True, kw_only=True)
class Task:
    """One keyed unit of work: ``fn(*args)``, run in a worker.

    Attributes
    ----------
    key : str
        Unique key of the item.
    fn : callable
        A module-level (picklable) function.
    args : tuple
        Its positional arguments (picklable for process pools).
    attempts : int
        Attempts already made in earlier runs (from a store).
    """

    key: str
    fn: Callable[..., Any]
    args: tuple[Any, ...] = ()
    attempts: int = 0


@dataclass(frozen=True, slots=True, kw_only=True)
class TaskOutcome:
    """Outcome of one attempt of a task.

    Attributes
    ----------
    key : str
        Task key.
    value : Any
        What ``fn`` returned (``None`` for a failed attempt).
    error : str or None
        Why the attempt failed; ``None`` on success.
    attempts : int
        Attempts made so far, including this one.
    final : bool
        True if no further attempt will be made (success, or attempts used up).
    wall_time : float
        Wall time of the attempt in [s] (measured in the worker; for crashes
        and time-outs, as seen by the parent).
    """

    key: str
    value: Any
    error: str | None
    attempts: int
    final: bool
    wall_time: float

    @property
    def ok(self) -> bool:
        """True if the attempt returned a value."""
        return self.error is None


ExecutorLike = Union[Literal["process", "serial"], Executor, WorkerPool, "Client", str]  # noqa: UP007
"""Where items run: ``"process"``, ``"serial"``, a :class:`WorkerPool`, any
:class:`concurrent.futures.Executor`, a :class:`distributed.Client` or a Dask
scheduler address (``"tcp://host:8786"``)."""

_MAX_BATCH = 64  # items per Dask task at most
_DIED = "worker-died"  # a Dask batch's reply when it was started again after its worker died

# Per worker thread: digest of the initializer blob already run, and its error (Dask runs).
_INIT = threading.local()


def _reruns_after_death() -> int:
    """How often Dask restarted the running task after a worker died (0 outside Dask).

    Asked of the scheduler (one round trip per task); the probe is sent by
    value, so the scheduler needs no youbot_opt. Any failure reads as 0 and
    leaves the accounting to Dask's own ``allowed-failures``.
    """
    try:
        from distributed import get_client, get_worker

        key = get_worker().get_current_task()

        def probe(dask_scheduler: Any = None) -> int:  # noqa: ANN401 - Dask's Scheduler
            ts = dask_scheduler.tasks.get(key)
            return int(ts.suspicious) if ts is not None else 0

        return int(get_client().run_on_scheduler(probe))
    except Exception:  # not in a worker, or the scheduler refuses pickled code
        return 0


def run_batch(init: bytes | None, batch: bytes) -> bytes:
    """Dask task: run a pickled list of ``(key, fn, args)`` and return each item's reply.

    Parameters
    ----------
    init : bytes or None
        Pickled ``(initializer, initargs)``, run once per worker thread (the
        same blob is not run again), e.g. to build and hold a solver.
    batch : bytes
        Pickled ``[(key, fn, args), ...]``.

    Returns
    -------
    bytes
        Pickled ``[(key, error, value, wall), ...]`` (``error`` ``None`` on
        success, wall times in [s]), or pickled ``"worker-died"`` when Dask
        started this task again after its worker died: the driver then runs
        the batch's items one by one, so a crash is charged to one item.
    """
    if _reruns_after_death() > 0:
        return _dumps(_DIED)
    init_error = None
    if init is not None:
        digest = hashlib.blake2b(init, digest_size=16).hexdigest()
        if getattr(_INIT, "digest", None) != digest:
            try:
                initializer, initargs = pickle.loads(init)
                initializer(*initargs)
                _INIT.error = None
            except Exception as exc:  # reported with every item instead of a silent failure
                _INIT.error = f"worker initializer failed: {_reason(exc)}"
            _INIT.digest = digest
        init_error = _INIT.error
    replies: list[tuple[Any, str | None, Any, float]] = []
    for key, fn, args in pickle.loads(batch):
        tic = time.perf_counter()
        try:
            if init_error is not None:
                raise RuntimeError(init_error)
            value, wall = _invoke(fn, args)
            replies.append((key, None, value, wall))
        except Exception as exc:  # one failing item must not end the batch
            replies.append((key, _reason(exc), None, time.perf_counter() - tic))
    try:
        return _dumps(replies)
    except Exception:  # some value does not pickle: charge that item alone
        safe: list[tuple[Any, str | None, Any, float]] = []
        for key, error, value, wall in replies:
            try:
                _dumps(value)
                safe.append((key, error, value, wall))
            except Exception as exc:
                safe.append((key, f"cannot send the result: {_reason(exc)}", None, wall))
        return _dumps(safe)


# ------------------------------------------------------------------- runner
class _Runner:
    """State of one :func:`run_tasks` call (pending queues, attempts)."""

    def __init__(
        self,
        tasks: list[Task],
        workers: int,
        max_attempts: int,
        timeout: float | None,
        on_outcome: Callable[[TaskOutcome], None] | None,
    ) -> None:
        self.tasks = {t.key: t for t in tasks}
        self.attempts = {t.key: t.attempts for t in tasks}
        self.pending = deque(t.key for t in tasks)
        self.retry: deque[str] = deque()
        self.workers = workers
        self.max_attempts = max_attempts
        self.timeout = timeout
        self.on_outcome = on_outcome
        self.outcomes: dict[str, TaskOutcome] = {}

    def next_key(self) -> str:
        return self.retry.popleft() if self.retry else self.pending.popleft()

    def emit(
        self, key: str, value: Any, error: str | None, wall: float, *, final: bool = False
    ) -> None:
        self.attempts[key] += 1
        n = self.attempts[key]
        final = final or error is None or n >= self.max_attempts
        outcome = TaskOutcome(
            key=key, value=value, error=error, attempts=n, final=final, wall_time=wall
        )
        if error is not None:
            _log.warning("task %s failed (attempt %d of %d): %s", key, n, self.max_attempts, error)
        if not final:
            self.retry.append(key)
        self.outcomes[key] = outcome
        if self.on_outcome is not None:
            self.on_outcome(outcome)

    def run_serial(self) -> None:
        while self.pending or self.retry:
            key = self.next_key()
            task = self.tasks[key]
            tic = time.perf_counter()
            try:
                value = task.fn(*task.args)
            except Exception as exc:  # one failing task must not end the sweep
                self.emit(key, None, _reason(exc), time.perf_counter() - tic)
            else:
                self.emit(key, value, None, time.perf_counter() - tic)

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
                        self.emit(key, None, f"cannot send the task: {_reason(exc)}", 0.0)
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
                fut: Future[Any]
                if isinstance(pool, ProcessPoolExecutor):  # pickled here: read-only mappings too
                    fut = pool.submit(_invoke_pickled, _dumps((task.fn, task.args)))
                else:
                    fut = pool.submit(_invoke, task.fn, task.args)
                inflight[fut] = key
            done, _ = wait(inflight, return_when=FIRST_COMPLETED)
            broken: list[str] = []
            for fut in done:
                key = inflight.pop(fut)
                exc = fut.exception()
                if isinstance(exc, BrokenProcessPool | BrokenThreadPool):
                    broken.append(key)
                elif exc is not None:
                    self.emit(key, None, _reason(exc), 0.0)
                else:
                    got = fut.result()
                    value, wall = pickle.loads(got) if isinstance(got, bytes) else got
                    self.emit(key, value, None, wall)
            if broken:
                why = "the executor broke (a worker crashed) and cannot be rebuilt by youbot_opt"
                for key in [*broken, *inflight.values()]:
                    self.emit(key, None, f"worker process crashed or was lost; {why}", 0.0)
                self._abandon(why)
                return

    def run_dask(
        self,
        client: Client,
        initializer: Callable[..., Any] | None,
        initargs: tuple[Any, ...],
        batch_size: int | None,
    ) -> None:
        """Run on a Dask cluster: batches of items, per-item outcomes, crash-charged singles.

        ``self.workers`` batches are kept in flight (the cluster's threads by
        default): not more, so that a task Dask finds on a dead worker was
        running there, not queued (a queued single item would be charged a
        crash it did not cause). The initializer travels to each worker once (scattered);
        a batch whose worker died is re-run item by item, so a crash is
        charged to one item. Dask's own retries are off (``retries=0``).
        """
        from distributed import KilledWorker, as_completed

        n = len(self.pending)
        size = batch_size or max(1, min(_MAX_BATCH, n // (8 * self.workers)))
        solo: set[str] = set()  # items to run alone: after a crash of their batch, or a retry
        init = None
        if initializer is not None:
            blob = _dumps((initializer, initargs))
            init = self._dask_call(lambda: client.scatter(blob, broadcast=True, hash=False))
        inflight: dict[DaskFuture, list[str]] = {}
        done = as_completed(loop=client.loop)
        try:
            while self.pending or self.retry or inflight:
                while len(inflight) < self.workers and (self.pending or self.retry):
                    keys = self._next_batch(size, solo)
                    items = [(k, self.tasks[k].fn, self.tasks[k].args) for k in keys]
                    try:
                        payload = _dumps(items)
                    except Exception as exc:  # a task does not pickle: charge it alone
                        if len(keys) > 1:
                            solo.update(keys)
                            self.pending.extendleft(reversed(keys))
                        else:
                            self.emit(keys[0], None, f"cannot send the task: {_reason(exc)}", 0.0)
                        continue
                    fut = self._dask_call(
                        functools.partial(
                            client.submit, run_batch, init, payload, pure=False, retries=0
                        )
                    )
                    inflight[fut] = keys
                    done.add(fut)
                if not inflight:
                    continue
                fut = next(done)
                keys = inflight.pop(fut)
                self._collect_dask(fut, keys, solo, KilledWorker)
        finally:
            for fut in inflight:  # interrupted: do not leave our work on the cluster
                with contextlib.suppress(Exception):
                    fut.cancel()

    def _next_batch(self, size: int, solo: set[str]) -> list[str]:
        """Keys of the next batch: one retried or solo item, else up to ``size`` fresh ones."""
        if self.retry:
            key = self.retry.popleft()
            solo.add(key)
            return [key]
        keys = [self.pending.popleft()]
        if keys[0] in solo:
            return keys
        while self.pending and len(keys) < size and self.pending[0] not in solo:
            keys.append(self.pending.popleft())
        return keys

    def _collect_dask(
        self, fut: DaskFuture, keys: list[str], solo: set[str], killed: type[Exception]
    ) -> None:
        """Turn a finished Dask batch into outcomes (or solo re-runs after a worker death)."""
        status = fut.status
        if status in ("cancelled", "lost") or (status == "error" and _is_cancel(fut)):
            self.pending.extendleft(reversed(keys))  # not started or lost with the scheduler
            raise ClusterLostError(f"the Dask scheduler or cluster went away (task {status})")
        died = False
        replies: Any = None
        if status == "error":
            exc = self._dask_call(fut.exception)
            if isinstance(exc, killed):
                died = True
            else:  # the batch itself failed (e.g. its payload did not unpickle there)
                for key in keys:
                    self.emit(key, None, _reason(exc), 0.0)
                return
        else:
            replies = pickle.loads(self._dask_call(fut.result))
            died = replies == _DIED
        if died:
            if len(keys) > 1:  # nothing charged: each item runs alone next
                solo.update(keys)
                self.pending.extendleft(reversed(keys))
                return
            self.emit(
                keys[0],
                None,
                "Dask worker died (e.g. a segfault or an out-of-memory kill) "
                "while running this item",
                0.0,
            )
            return
        for key, error, value, wall in replies:
            self.emit(key, value, error, wall)

    @staticmethod
    def _dask_call(fn: Callable[[], Any]) -> Any:
        """Call ``fn``, turning a lost scheduler connection into :class:`ClusterLostError`."""
        from asyncio import CancelledError as AsyncCancelled
        from concurrent.futures import CancelledError

        try:
            return fn()
        except (CancelledError, AsyncCancelled, OSError, TimeoutError) as exc:
            raise ClusterLostError(
                f"lost the connection to the Dask scheduler ({type(exc).__name__}: {exc})"
            ) from exc

    def _abandon(self, why: str) -> None:
        for key in self.retry:  # already failed once here: no further attempt
            prev = self.outcomes[key]
            outcome = replace(prev, error=f"{prev.error}; {why}", final=True)
            self.outcomes[key] = outcome
            if self.on_outcome is not None:
                self.on_outcome(outcome)
        for key in self.pending:
            self.emit(key, None, why, 0.0, final=True)
        self.retry.clear()
        self.pending.clear()


def _is_cancel(fut: DaskFuture) -> bool:
    from asyncio import CancelledError as AsyncCancelled
    from concurrent.futures import CancelledError

    try:
        exc = fut.exception(timeout=0)
    except (CancelledError, AsyncCancelled):
        return True
    except Exception:
        return False
    return isinstance(exc, CancelledError | AsyncCancelled)


def run_tasks(
    tasks: Iterable[Task],
    *,
    executor: ExecutorLike = "process",
    workers: int | None = None,
    initializer: Callable[..., Any] | None = None,
    initargs: tuple[Any, ...] = (),
    max_attempts: int = 2,
    on_outcome: Callable[[TaskOutcome], None] | None = None,
    timeout: float | None = None,
    batch_size: int | None = None,
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

    Returns
    -------
    dict of str to TaskOutcome
        The last outcome of each task run here, by key.

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
    initializer: Callable[..., Any] | None,
    initargs: tuple[Any, ...],
    max_attempts: int,
    on_outcome: Callable[[TaskOutcome], None] | None,
    timeout: float | None,
    batch_size: int | None,
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
    runner = _Runner(task_list, workers, max_attempts, timeout, on_outcome)
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
        runner.run_dask(client, initializer, initargs, batch_size)
    else:
        assert isinstance(executor, Executor)
        runner.run_executor(executor)
    return runner.outcomes
