"""Worker processes for sweeps: :class:`WorkerPool`, one task per worker at a time.

The pool behind :func:`youbot_opt.sweeps.tasks.run_tasks`. Each worker runs one
``(key, fn, args)`` message at a time and answers on its own pipe, so the parent
always knows which task a worker is running: a worker that dies (segfault,
out-of-memory kill) or overruns a time limit is charged to exactly that task and
replaced. Workers are forked on Linux (inheriting modules and any built solver),
else spawned, and exit by themselves when their parent dies (a watchdog thread
polls the parent pid every ``_PARENT_POLL`` seconds), so a killed sweep leaves no
orphans.

Private test hooks (pool workers only): ``YOUBOT_OPT_TEST_CRASH``
(``YOUBOT_OPT_TEST_HANG``), comma-separated task keys, makes those tasks
SIGSEGV their worker (sleep an hour); with ``YOUBOT_OPT_TEST_CRASH_ONCE_DIR``
naming a directory, only on the first attempt (a marker file is left). Not API.
"""

from __future__ import annotations

import faulthandler
import multiprocessing
import os
import signal
import sys
import threading
import time
from collections.abc import Callable
from multiprocessing.connection import Connection
from multiprocessing.context import BaseContext
from multiprocessing.reduction import ForkingPickler
from pathlib import Path
from types import MappingProxyType
from typing import Any

from youbot_opt.exceptions import ParameterError

__all__ = ["WorkerPool", "default_workers", "process_context"]

_CRASH_ENV = "YOUBOT_OPT_TEST_CRASH"
_HANG_ENV = "YOUBOT_OPT_TEST_HANG"
_CRASH_ONCE_ENV = "YOUBOT_OPT_TEST_CRASH_ONCE_DIR"
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


def _test_hook_fires(env: str, key: str, tag: str) -> bool:
    """Whether the private test hook ``env`` lists ``key`` (pool workers only, once if asked)."""
    if os.environ.get("_YOUBOT_OPT_POOL_WORKER") != "1":
        return False
    if key not in {k.strip() for k in os.environ.get(env, "").split(",")}:
        return False
    once = os.environ.get(_CRASH_ONCE_ENV)
    if once:
        marker = Path(once) / f"{tag}-{key}"
        if marker.exists():
            return False
        marker.touch()
    return True


def _invoke(key: str, fn: Callable[..., Any], args: tuple[Any, ...]) -> tuple[Any, float]:
    """Run one task in a worker; returns its value and wall time in [s]."""
    if _test_hook_fires(_CRASH_ENV, key, "crashed"):
        faulthandler.disable()  # a quiet crash: no inherited traceback dump on stderr
        os.kill(os.getpid(), signal.SIGSEGV)
    if _test_hook_fires(_HANG_ENV, key, "hung"):
        time.sleep(3600.0)
    tic = time.perf_counter()
    value = fn(*args)
    return value, time.perf_counter() - tic


def _worker_main(
    conn: Connection,
    parent: int,
    initializer: Callable[..., Any] | None,
    initargs: tuple[Any, ...],
) -> None:
    """Body of a worker process: run ``(key, fn, args)`` messages until ``None`` or EOF."""
    threading.Thread(target=_watch_parent, args=(parent,), daemon=True).start()
    os.environ["_YOUBOT_OPT_POOL_WORKER"] = "1"
    init_error = None
    if initializer is not None:
        try:
            initializer(*initargs)
        except Exception as exc:  # reported with every task instead of a silent death
            init_error = f"worker initializer failed: {_reason(exc)}"
    while True:
        try:
            message = conn.recv()
        except (EOFError, OSError):
            return
        if message is None:
            return
        key, fn, args = message
        tic = time.perf_counter()
        try:
            if init_error is not None:
                raise RuntimeError(init_error)
            value, wall = _invoke(key, fn, args)
            conn.send((key, None, value, wall))  # pickles first: a bad value sends nothing
        except Exception as exc:  # one failing task must not end the worker
            conn.send((key, _reason(exc), None, time.perf_counter() - tic))


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
        self.process = ctx.Process(  # type: ignore[attr-defined]
            target=_worker_main,
            args=(child, os.getpid(), initializer, initargs),
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
                self.conn.send(None)
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
