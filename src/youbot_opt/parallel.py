"""Run independent sweep items on an executor without letting one failure stop the sweep.

:func:`run_tasks` submits keyed tasks to ``"serial"`` (in-process), to
``"process"`` (a :class:`~concurrent.futures.ProcessPoolExecutor` it owns,
default) or to any :class:`concurrent.futures.Executor` the caller passes,
and reports every attempt through ``on_outcome`` as soon as it finishes, so
the caller can save it (:mod:`youbot_opt.sweep_store`) and show progress.

Failure handling:

* a task that raises becomes a failed attempt with ``"<Exception>: <message>"``;
* a worker that dies (segfault, ``os.abort``, out-of-memory kill) breaks the
  pool (:class:`~concurrent.futures.process.BrokenProcessPool`): the tasks
  that were running become failed attempts, the pool is rebuilt and the sweep
  goes on. At most ``workers`` tasks are in flight, so only those can be
  blamed; retries of crashed tasks run one at a time, so a task that crashes
  again is identified for certain and innocent neighbours are not blamed twice;
* each task gets at most ``max_attempts`` attempts in total (default 2: a
  failure is retried once), counting attempts made in earlier runs.

Worker processes use the ``fork`` start method where it exists (Linux), so
they inherit the imported modules and any solver the parent has already
built instead of rebuilding it; elsewhere ``spawn``. Each worker runs a
daemon thread that exits the worker when its parent process dies (e.g. is
killed with SIGKILL), so killed sweeps leave no orphans. With
``executor="serial"`` a crashing task takes the calling process down with it.

Private test hook: in worker processes of pools created here (never in
serial mode), the environment variable ``YOUBOT_OPT_TEST_CRASH`` holding a
comma-separated list of task keys makes those tasks kill their worker with
SIGSEGV before running. If ``YOUBOT_OPT_TEST_CRASH_ONCE_DIR`` also names a
directory, each listed task crashes only on its first attempt (a marker file
is left there). The tests use it to prove crash recovery; it is not API.
"""

from __future__ import annotations

import faulthandler
import logging
import multiprocessing
import os
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
from multiprocessing.context import BaseContext
from multiprocessing.reduction import ForkingPickler
from pathlib import Path
from types import MappingProxyType
from typing import Any, Literal

from youbot_opt.exceptions import ParameterError

__all__ = [
    "Task",
    "TaskOutcome",
    "ExecutorLike",
    "run_tasks",
    "process_context",
    "default_workers",
]

_log = logging.getLogger(__name__)

ExecutorLike = Literal["process", "serial"] | Executor
_CRASH_ENV = "YOUBOT_OPT_TEST_CRASH"
_CRASH_ONCE_ENV = "YOUBOT_OPT_TEST_CRASH_ONCE_DIR"
_PARENT_POLL = 0.2  # [s] how often a worker checks that its parent is alive


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
        Wall time of the attempt in [s] (measured in the worker; 0 for crashes).
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


def _mappingproxy(d: dict[Any, Any]) -> MappingProxyType[Any, Any]:
    return MappingProxyType(d)


def _reduce_mappingproxy(m: MappingProxyType[Any, Any]) -> tuple[Any, ...]:
    return _mappingproxy, (dict(m),)


# Read-only mappings (e.g. ``IpoptOptions.extra``) cannot be pickled by default;
# teach multiprocessing's pickler (only) to send them as a copied dict.
ForkingPickler.register(MappingProxyType, _reduce_mappingproxy)


# ------------------------------------------------------------------ workers
def _watch_parent(parent: int) -> None:
    while True:
        time.sleep(_PARENT_POLL)
        if os.getppid() != parent:
            os._exit(1)


def _init_worker(
    parent: int, initializer: Callable[..., Any] | None, initargs: tuple[Any, ...]
) -> None:
    """Initialise a pool worker: orphan watchdog, test-hook flag, user initializer."""
    threading.Thread(target=_watch_parent, args=(parent,), daemon=True).start()
    os.environ["_YOUBOT_OPT_POOL_WORKER"] = "1"
    if initializer is not None:
        initializer(*initargs)


def _maybe_crash(key: str) -> None:
    """Crash here if the private test hook lists ``key`` (pool workers only)."""
    if os.environ.get("_YOUBOT_OPT_POOL_WORKER") != "1":
        return
    keys = {k.strip() for k in os.environ.get(_CRASH_ENV, "").split(",") if k.strip()}
    if key not in keys:
        return
    once = os.environ.get(_CRASH_ONCE_ENV)
    if once:
        marker = Path(once) / f"crashed-{key}"
        if marker.exists():
            return
        marker.touch()
    faulthandler.disable()  # a quiet crash: no inherited traceback dump on stderr
    os.kill(os.getpid(), signal.SIGSEGV)


def _invoke(key: str, fn: Callable[..., Any], args: tuple[Any, ...]) -> tuple[Any, float]:
    """Run one task in a worker; returns its value and wall time in [s]."""
    _maybe_crash(key)
    tic = time.perf_counter()
    value = fn(*args)
    return value, time.perf_counter() - tic


# ------------------------------------------------------------------- runner
def _reason(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[-1] if text else ''}".rstrip(": ")


class _Runner:
    """State of one :func:`run_tasks` call (pending queues, attempts, pool)."""

    def __init__(
        self,
        tasks: list[Task],
        executor: ExecutorLike,
        workers: int,
        initializer: Callable[..., Any] | None,
        initargs: tuple[Any, ...],
        max_attempts: int,
        on_outcome: Callable[[TaskOutcome], None] | None,
    ) -> None:
        self.tasks = {t.key: t for t in tasks}
        self.attempts = {t.key: t.attempts for t in tasks}
        self.pending = deque(t.key for t in tasks)
        self.retry: deque[str] = deque()
        self.executor = executor
        self.workers = workers
        self.initializer = initializer
        self.initargs = initargs
        self.max_attempts = max_attempts
        self.on_outcome = on_outcome
        self.outcomes: dict[str, TaskOutcome] = {}
        self.retry_inflight: set[str] = set()

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
            key = self.retry.popleft() if self.retry else self.pending.popleft()
            task = self.tasks[key]
            tic = time.perf_counter()
            try:
                value = task.fn(*task.args)
            except Exception as exc:  # one failing task must not end the sweep
                self.emit(key, None, _reason(exc), time.perf_counter() - tic)
            else:
                self.emit(key, value, None, time.perf_counter() - tic)

    def _new_pool(self) -> Executor:
        return ProcessPoolExecutor(
            max_workers=self.workers,
            mp_context=process_context(),
            initializer=_init_worker,
            initargs=(os.getpid(), self.initializer, self.initargs),
        )

    def run_pool(self) -> None:
        own = self.executor == "process"
        pool = self._new_pool() if own else self.executor
        assert isinstance(pool, Executor)
        inflight: dict[Future[Any], str] = {}
        try:
            while self.pending or self.retry or inflight:
                solo = any(k in self.retry_inflight for k in inflight.values())
                while not solo and len(inflight) < self.workers and (self.pending or self.retry):
                    if self.retry:
                        if inflight:
                            break  # retries run alone: wait for the pool to drain
                        key, solo = self.retry.popleft(), True
                        self.retry_inflight.add(key)
                    else:
                        key = self.pending.popleft()
                    task = self.tasks[key]
                    inflight[pool.submit(_invoke, key, task.fn, task.args)] = key
                done, _ = wait(inflight, return_when=FIRST_COMPLETED)
                broken = False
                for fut in done:
                    key = inflight.pop(fut)
                    self.retry_inflight.discard(key)
                    exc = fut.exception()
                    if isinstance(exc, BrokenProcessPool | BrokenThreadPool):
                        broken = True
                        self._crashed(key, exc)
                    elif exc is not None:
                        self.emit(key, None, _reason(exc), 0.0)
                    else:
                        value, wall = fut.result()
                        self.emit(key, value, None, wall)
                if broken:
                    for key in list(inflight.values()):  # the others died with the pool
                        self.retry_inflight.discard(key)
                        self._crashed(key, BrokenProcessPool("pool broken"))
                    inflight.clear()
                    if not own:
                        self._abandon("the executor broke and cannot be rebuilt by youbot_opt")
                        return
                    pool.shutdown(wait=True, cancel_futures=True)
                    pool = self._new_pool()
        finally:
            if own:
                pool.shutdown(wait=True, cancel_futures=True)

    def _crashed(self, key: str, exc: BaseException) -> None:
        reason = (
            "worker process crashed (killed by a signal, e.g. segfault or out of memory) "
            f"while running this item [{type(exc).__name__}]"
        )
        self.emit(key, None, reason, 0.0)

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


def run_tasks(
    tasks: Iterable[Task],
    *,
    executor: ExecutorLike = "process",
    workers: int | None = None,
    initializer: Callable[..., Any] | None = None,
    initargs: tuple[Any, ...] = (),
    max_attempts: int = 2,
    on_outcome: Callable[[TaskOutcome], None] | None = None,
) -> dict[str, TaskOutcome]:
    """Run keyed tasks, retrying failures, and report each attempt as it ends.

    Parameters
    ----------
    tasks : iterable of Task
        The work, with unique keys.
    executor : {"process", "serial"} or concurrent.futures.Executor
        ``"process"`` (default): a process pool owned by this call, rebuilt if
        a worker crashes; ``"serial"``: in this process; an ``Executor``: used
        as is (not shut down; ``initializer`` is not run on it, and a broken
        executor ends the remaining tasks as failed).
    workers : int, optional
        Tasks in flight at once (pool size for ``"process"``); default: the
        CPUs available.
    initializer : callable, optional
        Run once in every worker process of an owned pool (e.g. to build a solver).
    initargs : tuple
        Its arguments (not pickled under ``fork``).
    max_attempts : int
        Attempts per task in total, including earlier runs' (>= 1).
    on_outcome : callable, optional
        Called in this process with every :class:`TaskOutcome`, in completion order.

    Returns
    -------
    dict of str to TaskOutcome
        The last outcome of each task run here, by key.

    Raises
    ------
    ParameterError
        On duplicate keys, ``workers < 1``, ``max_attempts < 1`` or an unknown executor.
    """
    task_list = list(tasks)
    keys = [t.key for t in task_list]
    if len(set(keys)) != len(keys):
        dup = sorted({k for k in keys if keys.count(k) > 1})
        raise ParameterError(f"task keys must be unique, repeated: {dup}", name="tasks")
    if workers is None:
        workers = getattr(executor, "_max_workers", None) or default_workers()
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ParameterError(f"workers must be an int >= 1, got {workers!r}", name="workers")
    if isinstance(max_attempts, bool) or not isinstance(max_attempts, int) or max_attempts < 1:
        raise ParameterError(
            f"max_attempts must be an int >= 1, got {max_attempts!r}", name="max_attempts"
        )
    if not (executor in ("process", "serial") or isinstance(executor, Executor)):
        raise ParameterError(
            f"executor must be 'process', 'serial' or a concurrent.futures.Executor, "
            f"got {executor!r}",
            name="executor",
        )
    runner = _Runner(task_list, executor, workers, initializer, initargs, max_attempts, on_outcome)
    if executor == "serial":
        if initializer is not None:
            initializer(*initargs)
        runner.run_serial()
    else:
        runner.run_pool()
    return runner.outcomes
