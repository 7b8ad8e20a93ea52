"""What every executor of a sweep shares: tasks, outcomes, the retry queues.

Owns the executor-independent half of running a sweep's keyed items (spec:
the sweep layer of ``ARCHITECTURE.md``): :class:`Task` and
:class:`TaskOutcome`, the :class:`TaskRunner` (pending and retry queues,
attempts per key, one :class:`TaskOutcome` per attempt, ``run_serial``), and
the helpers both the local pool (:mod:`.pool`) and the Dask path
(:mod:`.distributed`) use: :func:`invoke` (one timed call) and
:func:`failure_reason`. What travels is pickled by :mod:`pickle` as it is.
Callers use :func:`youbot_opt.sweeps.pool.run_tasks`, not this module.

    runner = TaskRunner([Task(key="k", fn=abs, args=(-1,))], workers=1, max_attempts=2)
"""

from __future__ import annotations

import logging
import time
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, replace
from typing import Generic, TypeVar

from youbot_opt.exceptions import ParameterError
from youbot_opt.sweeps.lazy import LazySequence

__all__ = [
    "Task",
    "TaskOutcome",
    "TaskRunner",
    "TaskSequence",
    "failure_reason",
    "invoke",
    "task_keys",
]

_log = logging.getLogger(__name__)

V = TypeVar("V")
"""The type of a task's value."""


def invoke(fn: Callable[..., V], args: tuple[object, ...]) -> tuple[V, float]:
    """Run one task; returns its value and wall time in [s]."""
    tic = time.perf_counter()
    value = fn(*args)
    return value, time.perf_counter() - tic


def failure_reason(exc: BaseException) -> str:
    """One line naming an exception: ``"TypeError: last line of its message"``."""
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[-1] if text else ''}".rstrip(": ")


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
    fn: Callable[..., object]
    args: tuple[object, ...] = ()
    attempts: int = 0


class TaskSequence(LazySequence[Task]):
    """The tasks of a sweep made when asked for: task ``i`` is ``make(i)``, none is stored.

    A sweep with ``keep_results=False`` given one never holds all its tasks:
    :func:`~youbot_opt.sweeps.resume.run_resumable` takes them a chunk at a time.

    Parameters
    ----------
    count : int
        Number of tasks (>= 0).
    make : callable ``(i) -> Task``
        Task ``i``; must give the same key for the same ``i`` every time.
    key : callable ``(i) -> str``, optional
        Key of task ``i`` without making the task (equal to ``make(i).key``):
        the sweep then walks the keys (resume counts, the items' order)
        without building tasks it does not run (:func:`task_keys`).

    Examples
    --------
    >>> tasks = TaskSequence(3, lambda i: Task(key=f"s{i}", fn=abs, args=(-i,)))
    >>> [t.key for t in tasks]
    ['s0', 's1', 's2']
    """

    def __init__(
        self, count: int, make: Callable[[int], Task], key: Callable[[int], str] | None = None
    ) -> None:
        if isinstance(count, bool) or not isinstance(count, int) or count < 0:
            raise ParameterError(f"count must be an int >= 0, got {count!r}", name="count")
        self._count, self._make, self._key = count, make, key

    def keys(self) -> Iterator[str]:
        """Iterate over the task keys in order (without making tasks if ``key`` was given)."""
        if self._key is None:
            return (self._make(j).key for j in range(self._count))
        return (self._key(j) for j in range(self._count))

    def __len__(self) -> int:
        return self._count

    def head(self, count: int) -> TaskSequence:
        """Return the first ``count`` tasks (at most all), still made when asked for."""
        return TaskSequence(min(max(int(count), 0), self._count), self._make, self._key)

    noun = "task"

    def _item(self, j: int) -> Task:
        return self._make(j)

    def __iter__(self) -> Iterator[Task]:
        return (self._make(j) for j in range(self._count))


def task_keys(tasks: Sequence[Task]) -> Iterator[str]:
    """Iterate over the keys of ``tasks`` in order (a :class:`TaskSequence` makes no task)."""
    if isinstance(tasks, TaskSequence):
        return tasks.keys()
    return (t.key for t in tasks)


@dataclass(frozen=True, slots=True, kw_only=True)
class TaskOutcome(Generic[V]):
    """Outcome of one attempt of a task.

    Attributes
    ----------
    key : str
        Task key.
    value : object
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
    value: V
    error: str | None
    attempts: int
    final: bool
    wall_time: float

    @property
    def ok(self) -> bool:
        """True if the attempt returned a value."""
        return self.error is None


# ------------------------------------------------------------------- runner
class TaskRunner:
    """State of one ``run_tasks`` call: pending and retry queues, attempts, outcomes.

    Parameters
    ----------
    tasks : list of Task
        The work (unique keys; ``attempts`` from earlier runs).
    workers : int
        Tasks (or Dask batches) kept in flight at once.
    max_attempts : int
        Attempts per task in total.
    timeout : float or None
        Wall-clock limit per attempt in [s] (worker pools only).
    on_outcome : callable, optional
        Called with every :class:`TaskOutcome` as it is made.
    keep_values : bool
        Keep every outcome in :attr:`outcomes` (default); ``False`` keeps
        only failed ones, without values, and forgets finished tasks, so a
        long sweep's values and tasks are not held here.
    deadline : float, optional
        A :func:`time.monotonic` instant after which no pending task begins:
        checked as attempts end, so the first tasks always begin, and the
        retries of begun tasks still run. The tasks it stopped are in
        :attr:`not_begun`, in order, and get no outcome.
    """

    def __init__(
        self,
        tasks: list[Task],
        workers: int,
        max_attempts: int,
        timeout: float | None,
        on_outcome: Callable[[TaskOutcome[object]], None] | None,
        *,
        keep_values: bool = True,
        deadline: float | None = None,
    ) -> None:
        self.keep_values = keep_values
        self.deadline = deadline
        self.not_begun: list[str] = []
        self.tasks = {t.key: t for t in tasks}
        self.attempts = {t.key: t.attempts for t in tasks}
        self.pending = deque(t.key for t in tasks)
        self.retry: deque[str] = deque()
        self.workers = workers
        self.max_attempts = max_attempts
        self.timeout = timeout
        self.on_outcome = on_outcome
        self.outcomes: dict[str, TaskOutcome[object]] = {}

    def next_key(self) -> str:
        """Key of the next task to run: a retry first, else the next pending one."""
        return self.retry.popleft() if self.retry else self.pending.popleft()

    def emit(
        self, key: str, value: object, error: str | None, wall: float, *, final: bool = False
    ) -> None:
        """Record one attempt of ``key`` (a retry is queued unless it is final)."""
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
        if self.keep_values:
            self.outcomes[key] = outcome
        elif error is not None:  # failures only (a retry needs its reasons), without values
            self.outcomes[key] = replace(outcome, value=None)
        else:
            self.outcomes.pop(key, None)
        if final and not self.keep_values:  # a finished task is never needed again
            del self.tasks[key], self.attempts[key]
        if self.pending and self.deadline is not None and time.monotonic() >= self.deadline:
            self.not_begun += self.pending  # past the deadline: no new task begins
            self.pending.clear()
        if self.on_outcome is not None:
            self.on_outcome(outcome)

    def run_serial(self) -> None:
        """Run every task in this process, in order (retries after the first pass)."""
        while self.pending or self.retry:
            key = self.next_key()
            task = self.tasks[key]
            tic = time.perf_counter()
            try:
                value = task.fn(*task.args)
            except Exception as exc:  # one failing task must not end the sweep
                self.emit(key, None, failure_reason(exc), time.perf_counter() - tic)
            else:
                self.emit(key, value, None, time.perf_counter() - tic)

    def abandon(self, why: str) -> None:
        """End every queued task as failed with ``why`` (the executor cannot go on)."""
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
