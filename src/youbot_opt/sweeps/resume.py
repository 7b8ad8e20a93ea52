"""The item loop of a resumable sweep: load what the store holds, run the rest, save each.

Owns the loop every start-based sweep shares (trajectory and IK-path
multistarts, the bound-scaling study; spec: the sweep layer of
``ARCHITECTURE.md``). :func:`run_resumable` asks the
:class:`~youbot_opt.sweeps.store.SweepStore` which items are finished (done,
or failed with their attempts used up) and loads them, runs the others with
:func:`~youbot_opt.sweeps.pool.run_tasks` (the attempts of earlier runs
count), and saves every attempt as it ends: a success with its payload and
summary, a failure with its reason. The caller supplies only what differs:
how an outcome becomes its own item type and what of it is saved.

    got = run_resumable(tasks, store=store, options=opts, load=load, convert=convert,
                        payload=lambda key, item: (item.result, item.summary()))
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import Any, Generic, NamedTuple, TypeVar

from youbot_opt.exceptions import YoubotOptError
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.sweeps.pool import Task, TaskOutcome, run_tasks
from youbot_opt.sweeps.scheduler import ClusterLostError
from youbot_opt.sweeps.store import SweepStore

__all__ = ["Resumed", "ShardFinished", "run_resumable"]

T = TypeVar("T")


class ShardFinished(YoubotOptError):
    """A shard run (``SweepOptions(shard=(i, k))``) solved its share; not a failure.

    The message says how many items this shard ran, how many of the sweep's
    items are finished in the shared folder, and how to collect them.
    """

    def __init__(self, message: str, *, ran: int, finished: int, total: int) -> None:
        super().__init__(message)
        self.ran, self.finished, self.total = ran, finished, total


class Resumed(NamedTuple, Generic[T]):
    """What :func:`run_resumable` returns."""

    items: dict[str, T]
    """The final item of every task, by key (loaded or run here)."""
    attempts: dict[str, int]
    """Attempts made per key, earlier runs included (0: none was needed here nor before)."""
    resumed: int
    """Items loaded from the store instead of run."""


def run_resumable(
    tasks: Sequence[Task],
    *,
    store: SweepStore | None,
    options: SweepOptions,
    load: Callable[[str], T],
    convert: Callable[[TaskOutcome], T],
    payload: Callable[[str, T], tuple[Any, dict[str, Any]]],
    initializer: Callable[..., Any] | None = None,
    initargs: tuple[Any, ...] = (),
    on_resumed: Callable[[dict[str, T]], None] | None = None,
    on_final: Callable[[str, T, int], None] | None = None,
) -> Resumed[T]:
    """Run the tasks a store does not hold as finished, saving every attempt as it ends.

    Parameters
    ----------
    tasks : sequence of Task
        Every item of the sweep, with unique keys (their ``attempts`` are
        taken from ``store``).
    store : SweepStore, optional
        Where finished items are loaded from and every attempt is saved.
    options : SweepOptions
        Executor, workers, timeout [s] and ``max_attempts``; ``out`` and
        ``progress`` are the caller's business.
    load : callable ``(key) -> item``
        A finished item from ``store`` (done or failed; see ``store.record(key)``).
    convert : callable ``(outcome) -> item``
        The item of an attempt's :class:`~youbot_opt.sweeps.pool.TaskOutcome`.
    payload : callable ``(key, item) -> (payload, summary)``
        What ``store`` saves of a successful item: its payload and JSON summary.
    initializer, initargs
        Run once in every worker of a pool owned by this call (see ``run_tasks``).
    on_resumed : callable ``(items)``, optional
        Called once, before any task runs, with the items loaded from ``store``.
    on_final : callable ``(key, item, n_final)``, optional
        Called in this process when an item is final; ``n_final`` counts the
        final items so far, loaded ones included.

    Returns
    -------
    Resumed
        The items, attempts and number of resumed items.

    Notes
    -----
    ``options.executor`` ``None`` runs on ``"process"``.

    Raises
    ------
    ResultFileError
        If a stored record or payload is corrupted or from a newer schema.
    ClusterLostError
        If the Dask scheduler is lost: the message says what was saved and how to resume.
    ShardFinished
        After a shard run (``options.shard``) solved its share.
    """
    max_attempts = options.max_attempts
    items: dict[str, T] = {}
    attempts: dict[str, int] = {}
    todo: list[Task] = []
    for task in tasks:
        made = 0
        if store is not None:
            again, made = store.needs_work(task.key, max_attempts)
            if not again:
                attempts[task.key] = made
                items[task.key] = load(task.key)
                continue
        attempts[task.key] = made
        todo.append(replace(task, attempts=made))
    resumed = len(items)
    shard = options.shard
    if shard is not None:  # only this shard's positions; the others are other jobs' work
        mine = {t.key for pos, t in enumerate(tasks) if pos % shard[1] == shard[0] - 1}
        todo = [t for t in todo if t.key in mine]
    if on_resumed is not None:
        on_resumed(dict(items))

    def record(o: TaskOutcome) -> None:
        attempts[o.key] = o.attempts
        item = convert(o)
        if store is not None:
            if o.ok:
                data, summary = payload(o.key, item)
                store.write_done(o.key, data, summary, attempts=o.attempts)
            else:
                store.write_failed(o.key, str(o.error), attempts=o.attempts)
        if o.final:
            items[o.key] = item
            if on_final is not None:
                on_final(o.key, item, len(items))

    try:
        run_tasks(
            todo,
            executor="process" if options.executor is None else options.executor,
            workers=options.workers,
            initializer=initializer,
            initargs=initargs,
            max_attempts=max_attempts,
            on_outcome=record,
            timeout=options.timeout,
            batch_size=options.batch_size,
        )
    except ClusterLostError as exc:
        final = len(items)
        if store is None:
            saved = (
                f"{final} of {len(tasks)} items had finished, but nothing was saved (no output "
                "directory): pass out= (--out DIR) to make a sweep resumable"
            )
        else:
            saved = (
                f"{final} of {len(tasks)} items are saved in {store.directory}; rerun the "
                "same sweep with the same output directory to resume from there"
            )
        raise ClusterLostError(f"sweep stopped: {exc}. {saved}") from exc
    if shard is not None:
        where = store.directory if store is not None else "?"
        raise ShardFinished(
            f"shard {shard[0]}/{shard[1]}: ran {len(todo)} item(s); {len(items)} of "
            f"{len(tasks)} items are finished in {where}; when every shard is done, run the "
            "same sweep without the shard to collect them",
            ran=len(todo),
            finished=len(items),
            total=len(tasks),
        )
    missing = [t.key for t in tasks if t.key not in items]
    assert not missing, f"run_tasks returned no final outcome for {missing}"
    return Resumed(items=items, attempts=attempts, resumed=resumed)
