"""The item loop of a resumable sweep: load what the store holds, run the rest, save each.

:func:`run_resumable` is the loop every start-based sweep shares: it loads the
items the :class:`~youbot_opt.sweeps.store.SweepStore` holds as finished, runs
the others with :func:`~youbot_opt.sweeps.pool.run_tasks` (earlier attempts
count) and saves every attempt as it ends. Callers supply how an outcome
becomes their item type and what of it is saved; ``describe`` lets workers
write their own items, ``keep_results=False`` streams chunks and keeps only the
distinct optima (:class:`StoredItems` reads the rest back from the journal).

    got = run_resumable(tasks, store=store, options=opts, load=load, convert=convert,
                        payload=lambda key, item: (item.result, item.summary()))
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Iterator, Mapping, MutableMapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Generic, NamedTuple, Protocol, TypeVar

from youbot_opt._files import json_roundtrip
from youbot_opt.exceptions import ParameterError
from youbot_opt.sweeps.optima import KeepRule
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.sweeps.pool import Task, TaskOutcome, WorkerPool, run_tasks
from youbot_opt.sweeps.scheduler import ClusterLostError, connect, is_scheduler_address
from youbot_opt.sweeps.selection import Clusters, stream_optima
from youbot_opt.sweeps.store import ItemRecord, ItemWriter, SweepStore, WrittenItem
from youbot_opt.sweeps.tasks import TaskSequence, task_keys

__all__ = [
    "Describe",
    "Resumed",
    "ShardReport",
    "StoredAttempts",
    "StoredItems",
    "run_and_write",
    "run_resumable",
]

T = TypeVar("T")
V = TypeVar("V")
P = TypeVar("P")
V_contra = TypeVar("V_contra", contravariant=True)
P_co = TypeVar("P_co", covariant=True)


class Describe(Protocol[V_contra, P_co]):
    """``(key, args, value) -> (payload, summary)``: what a worker saves of a task's value.

    ``value`` is what the task's function returned for ``args``; the payload is
    what the store's codec writes, the summary the item's JSON figures.
    """

    def __call__(
        self, key: str, args: tuple[object, ...], value: V_contra, /
    ) -> tuple[P_co, Mapping[str, object]]:
        """Return the payload and the summary of ``value``, the task ``key``'s value."""
        ...


CHUNK = 4096
"""Tasks handed to the executor at once when ``keep_results=False`` (bounded driver memory)."""


@dataclass(frozen=True, slots=True, kw_only=True)
class ShardReport:
    """What a shard run (``SweepOptions(shard=(i, k))``) returns once it solved its share.

    ``str(report)`` says how many items this shard ran, how many of the
    sweep's items are finished in the shared folder, and how to collect them.

    Attributes
    ----------
    shard : tuple of (int, int)
        ``(i, k)``: this run solved items ``i - 1, i - 1 + k, ...`` (0-based).
    ran : int
        Items run by this shard (finished ones found in the folder not counted).
    finished : int
        Items of the whole sweep finished in ``directory`` (every shard's).
    total : int
        Items of the whole sweep.
    directory : Path
        The folder the shards share.
    """

    shard: tuple[int, int]
    ran: int
    finished: int
    total: int
    directory: Path

    @property
    def left(self) -> int:
        """Items of the sweep not yet finished (another shard's, or to be run again)."""
        return self.total - self.finished

    def __str__(self) -> str:
        i, k = self.shard
        return (
            f"shard {i}/{k}: ran {self.ran} item(s); {self.finished} of {self.total} items "
            f"are finished in {self.directory}; when every shard is done, run the same sweep "
            "without the shard to collect them"
        )


class Resumed(NamedTuple, Generic[T]):
    """What :func:`run_resumable` returns."""

    items: MutableMapping[str, T]
    """The final item of every task, by key (loaded or run here); ``keep_results=False``:
    a :class:`StoredItems`, read from the store's journal when asked for."""
    attempts: Mapping[str, int]
    """Attempts made per key, earlier runs included (0: none was needed here nor before);
    ``keep_results=False``: a :class:`StoredAttempts`, read from the store."""
    resumed: int
    """Items loaded from the store instead of run."""
    clusters: Sequence[Sequence[str]] = ()
    """``keep_results=False``: the distinct optima as keys, each best first, best
    optimum first (``select_optima``'s rule), as a :class:`~youbot_opt.sweeps.selection.Clusters`
    (members read from disk, counted by ``len``); empty otherwise."""
    not_run: int = 0
    """Tasks from the first one a ``deadline`` left unfinished on (0: every task
    finished); ``items``, ``attempts``, ``resumed`` and ``clusters`` cover the tasks before it."""


class StoredItems(MutableMapping[str, T]):
    """The items of a ``keep_results=False`` sweep, read lazily from its store.

    Keys are the tasks' keys, in task order; an item is ``light(key, record)``
    made from the item's journal line each time it is asked for (nothing per
    item is held), except the few items set here (the kept optima, in full).

    Parameters
    ----------
    tasks : sequence of Task
        The sweep's tasks (only their keys are used; may be a lazy sequence).
    store : SweepStore
        Where the items are recorded.
    light : callable ``(key, record) -> item``
        The item of a record without its payload.
    """

    def __init__(
        self, tasks: Sequence[Task], store: SweepStore, light: Callable[[str, ItemRecord], T]
    ) -> None:
        self._tasks, self._store, self._light = tasks, store, light
        self._set: dict[str, T] = {}

    def __getitem__(self, key: str) -> T:
        if key in self._set:
            return self._set[key]
        record = self._store.record(key)
        if record is None:
            raise KeyError(key)
        return self._light(key, record)

    def __setitem__(self, key: str, item: T) -> None:
        self._set[key] = item

    def __delitem__(self, key: str) -> None:
        raise TypeError("the items of a sweep cannot be deleted")

    def __iter__(self) -> Iterator[str]:
        return (k for k in task_keys(self._tasks) if k in self._set or self._store.has(k))

    def __len__(self) -> int:
        return sum(1 for _ in self)

    def __contains__(self, key: object) -> bool:
        return isinstance(key, str) and (key in self._set or self._store.has(key))


class StoredAttempts(Mapping[str, int]):
    """Attempts per task key of a ``keep_results=False`` sweep, read from its store (0: none)."""

    def __init__(self, tasks: Sequence[Task], store: SweepStore) -> None:
        self._tasks, self._store = tasks, store

    def __getitem__(self, key: str) -> int:
        record = self._store.record(key)
        return 0 if record is None else record.attempts

    def __iter__(self) -> Iterator[str]:
        return task_keys(self._tasks)

    def __len__(self) -> int:
        return len(self._tasks)


def run_and_write(
    writer: ItemWriter,
    describe: Describe[V, P],
    send_value: bool,
    key: str,
    fn: Callable[..., V],
    args: tuple[object, ...],
) -> WrittenItem:
    """Worker task: run ``fn(*args)`` and write the item's payload into the store's folder.

    Returns
    -------
    WrittenItem
        Where the payload is, its SHA-256, the summary, and the value itself
        if ``send_value`` (the driver keeps results), else ``None``.
    """
    value = fn(*args)
    data, summary = describe(key, args, value)
    name, checksum = writer.write(key, data)
    return WrittenItem(name, checksum, json_roundtrip(dict(summary)), value if send_value else None)


def run_resumable(
    tasks: Sequence[Task],
    *,
    store: SweepStore | None,
    options: SweepOptions,
    load: Callable[[str], T],
    convert: Callable[[TaskOutcome], T],
    payload: Callable[[str, T], tuple[object, Mapping[str, object]]],
    initializer: Callable[..., object] | None = None,
    initargs: tuple[object, ...] = (),
    on_resumed: Callable[[dict[str, T]], None] | None = None,
    on_final: Callable[[str, T, int], None] | None = None,
    describe: Describe[V, P] | None = None,
    light: Callable[[str, ItemRecord], T] | None = None,
    keep: KeepRule[T] | None = None,
    deadline: float | None = None,
) -> Resumed[T] | ShardReport:
    """Run the tasks a store does not hold as finished, saving every attempt as it ends.

    Parameters
    ----------
    tasks : sequence of Task
        Every item of the sweep, with unique keys (their ``attempts`` are
        taken from ``store``).
    store : SweepStore, optional
        Where finished items are loaded from and every attempt is saved.
    options : SweepOptions
        Executor, workers, timeout [s], ``max_attempts`` and ``keep_results``;
        ``out`` and ``progress`` are the caller's business.
    load : callable ``(key) -> item``
        A finished item from ``store`` (done or failed; see ``store.record(key)``).
    convert : callable ``(outcome) -> item``
        The item of an attempt's :class:`~youbot_opt.sweeps.pool.TaskOutcome`.
    payload : callable ``(key, item) -> (payload, summary)``
        What ``store`` saves of a successful item: its payload and JSON summary.
    initializer, initargs
        Run once in every worker of a pool owned by this call (see ``run_tasks``).
    on_resumed : callable ``(items)``, optional
        Called once, before any task runs, with the items loaded from ``store``
        (``keep_results=False``: a read-only mapping read from the store, valid
        during the call).
    on_final : callable ``(key, item, n_final)``, optional
        Called in this process when an item is final; ``n_final`` counts the
        final items so far, loaded ones included.
    describe : callable ``(key, args, value) -> (payload, summary)``, optional
        Picklable: what a worker saves of its task's value. Given (with a
        schema-3 store and ``options.writes_in_workers``), each worker writes its own payload file
        (:func:`run_and_write`) and the driver checks it against the reported
        SHA-256 before recording it; a refused file is warned about and its
        item recomputed. A summary's ``"attempts"`` entry is set by the driver.
    light : callable ``(key, record) -> item``, optional
        The item of a finished record without its payload (from its summary);
        needed for ``options.keep_results=False``.
    keep : KeepRule, optional
        Which full items ``options.keep_results=False`` keeps (the distinct
        optima, :func:`~youbot_opt.sweeps.optima.select_optima`); needed then.
    deadline : float, optional
        A :func:`time.monotonic` instant after which no new task begins
        (:func:`~youbot_opt.sweeps.pool.run_tasks`; tasks running then finish,
        at least one task begins). The sweep then ends at its first unfinished
        task: the result covers the tasks before it and counts the others in
        :attr:`Resumed.not_run` (finished ones among them stay in ``store``,
        where a rerun loads them and goes on with the rest).

    Returns
    -------
    Resumed or ShardReport
        The items (``keep_results=False``: light ones, full for the kept
        optima), attempts, number of resumed items and the optima's clusters;
        a shard run (``options.shard``) returns what it did instead, a
        :class:`ShardReport` (not a failure).

    Notes
    -----
    ``options.executor`` ``None`` runs on ``"process"``. Items are recorded
    in durable groups (:meth:`SweepStore.grouped`). With ``keep_results=False``
    a resume reads only the journal; the final selection reads each
    converged payload once, one at a time, and is saved (``DIR/optima.json``),
    so a resume of an unchanged store loads only the kept optima.

    Raises
    ------
    ParameterError
        If ``keep_results=False`` lacks ``out``, ``light`` or ``keep``.
    ResultFileError
        If a stored record or payload is corrupted or from a newer schema.
    ClusterLostError
        If the Dask scheduler is lost: the message says what was saved and how to resume.
    """
    keep_all = options.keep_results
    if not keep_all and (store is None or light is None or keep is None):
        why = (
            "needs out= (the results not kept stay there)"
            if store is None
            else "is not supported by this sweep (its result holds every item's full result); "
            "use keep_results=True"
        )
        raise ParameterError(f"keep_results=False {why}", name="keep_results", value=False)
    if store is None or keep_all:
        with store.grouped() if store is not None else contextlib.nullcontext():
            return _run_all(
                tasks,
                store,
                options,
                load,
                convert,
                payload,
                initializer,
                initargs,
                on_resumed,
                on_final,
                describe if store is not None else None,
                light if store is not None else None,
                keep_all,
                deadline,
            )
    assert light is not None
    with store.grouped():
        got = _stream_all(
            tasks, store, options, convert, payload, initializer, initargs,
            on_resumed,  # type: ignore[arg-type]  # given a read-only view, not a dict
            on_final, describe, light, deadline,
        )  # fmt: skip
    if isinstance(got, ShardReport):
        return got
    assert keep is not None and light is not None
    if got.not_run:  # a deadline ended the sweep: its optima are those of the tasks run
        tasks = _head(tasks, len(tasks) - got.not_run)

    def full(key: str) -> T:
        if not store.verify(key):  # warned; forgotten by the store, so it is run again
            raise _Refused(key)
        return load(key)

    extra = {"obj_tol": keep.obj_tol, "dist_tol": keep.dist_tol, "best": keep.distance is None,
             "grouped": keep.group is not None}  # fmt: skip
    redone: set[str] = set()  # items counted as resumed, then refused and run again
    while True:  # the kept optima, loaded (a refused payload is recomputed, then chosen again)
        # every task is finished (checked by _stream_all), so if the store holds no other
        # item its records are exactly the sweep's: named without reading a line
        if store.count() == len(tasks):
            fingerprint = store.fingerprint_all(extra)
        else:
            fingerprint = store.fingerprint(got.items, extra)
        saved = store.selection(fingerprint)
        clusters: Clusters
        try:
            if saved is not None:  # chosen before over exactly these items: load only those
                clusters = saved
                kept = {c[0]: full(c[0]) for c in saved}
            else:
                kept, clusters = stream_optima(got.items, keep, full)
                store.save_selection(fingerprint, clusters)
        except _Refused as exc:
            redo = [tasks[i] for i, k in enumerate(task_keys(tasks)) if k == exc.key]
            redone.add(exc.key)
            with store.grouped():  # recorded in the store, which got.items reads from
                _stream_all(
                    redo, store, options, convert, payload, initializer, initargs, None, None,
                    describe, light, None,
                )  # fmt: skip
            continue
        got.items.update(kept)
        return got._replace(clusters=clusters, resumed=max(got.resumed - len(redone), 0))


def _stream_all(
    tasks: Sequence[Task],
    store: SweepStore,
    options: SweepOptions,
    convert: Callable[[TaskOutcome], T],
    payload: Callable[[str, T], tuple[object, Mapping[str, object]]],
    initializer: Callable[..., object] | None,
    initargs: tuple[object, ...],
    on_resumed: Callable[[Mapping[str, T]], None] | None,
    on_final: Callable[[str, T, int], None] | None,
    describe: Describe[V, P] | None,
    light: Callable[[str, ItemRecord], T],
    deadline: float | None,
) -> Resumed[T] | ShardReport:
    """``keep_results=False``: run the unfinished tasks in chunks, keeping nothing per item.

    Tasks are taken from ``tasks`` as they are needed, :data:`CHUNK` at a time;
    what an item is comes back from the store (:class:`StoredItems`). One
    worker pool (or Dask connection) serves every chunk; past ``deadline`` no
    further chunk is taken.
    """
    max_attempts = options.max_attempts
    items = StoredItems(tasks, store, light)
    finished = 0
    loaded = bytearray()  # with a deadline: which positions were loaded (resumed)
    for key in task_keys(tasks):  # what the store holds as finished (counted, not kept)
        done = not store.needs_work(key, max_attempts)[0]
        finished += done
        if deadline is not None:
            loaded.append(done)
    resumed = finished
    if on_resumed is not None:  # a view: read during the call, before anything runs
        on_resumed(_Finished(items, store, max_attempts))
    shard = options.shard
    use = describe is not None and options.writes_in_workers
    writer = store.writer() if use else None
    ran = 0

    def todo() -> Iterator[Task]:
        for pos, key in enumerate(task_keys(tasks)):
            if shard is not None and not _in_shard(pos, shard):
                continue  # another shard's item
            again, made = store.needs_work(key, max_attempts)
            if not again:
                continue
            task = tasks[pos]  # made only if it runs
            if writer is not None:
                args = (writer, describe, False, task.key, task.fn, task.args)
                yield replace(task, fn=run_and_write, args=args, attempts=made)
            else:
                yield replace(task, attempts=made)

    def record(o: TaskOutcome, chunk: dict[str, Task], redo: list[Task]) -> None:
        nonlocal finished
        if o.ok and isinstance(o.value, WrittenItem) and writer is not None:
            rec = _accept_written(store, o.key, o.value, o.attempts)
            if rec is None:  # refused (warned): a failed attempt, retried if attempts remain
                rec = store.write_failed(o.key, _REFUSED_PAYLOAD, attempts=o.attempts)
                if o.attempts < max_attempts:
                    redo.append(replace(chunk[o.key], attempts=o.attempts))
                    return
        elif o.ok:
            data, summary = payload(o.key, convert(o))
            rec = store.write_done(o.key, data, summary, attempts=o.attempts)
        else:
            rec = store.write_failed(o.key, str(o.error), attempts=o.attempts)
        if o.final:
            finished += 1
            if on_final is not None:
                on_final(o.key, light(o.key, rec), finished)

    executor = "process" if options.executor is None else options.executor
    owned: WorkerPool | None = None
    client = None
    stream = todo()
    try:
        while True:
            if ran and deadline is not None and time.monotonic() >= deadline:
                break  # past the deadline: no further chunk
            part = _take(stream, CHUNK)
            chunk = {t.key: t for t in part}
            if len(chunk) < len(part):
                raise ParameterError("task keys must be unique", name="tasks")
            if not chunk:
                break
            if executor == "process" and owned is None:  # one pool for every chunk
                owned = WorkerPool(options.workers, initializer=initializer, initargs=initargs)
            if is_scheduler_address(executor) and client is None:  # one connection
                client = connect(str(executor))
            run = owned if executor == "process" else client if client is not None else executor
            ran += len(chunk)
            while part:
                redo: list[Task] = []
                run_tasks(
                    part,
                    executor=run,  # type: ignore[arg-type]
                    workers=options.workers,
                    initializer=None if owned is not None else initializer,
                    initargs=() if owned is not None else initargs,
                    max_attempts=max_attempts,
                    on_outcome=lambda o, c=chunk, r=redo: record(o, c, r),  # type: ignore[misc]
                    timeout=options.timeout,
                    batch_size=options.batch_size,
                    keep_values=False,
                    deadline=deadline,
                )
                part = redo
    except ClusterLostError as exc:
        raise ClusterLostError(
            f"sweep stopped: {exc}. {finished} of {len(tasks)} items are saved in "
            f"{store.directory}; rerun the same sweep with the same output directory to "
            "resume from there"
        ) from exc
    finally:
        if owned is not None:
            owned.close()
        if client is not None:
            client.close()
    if shard is not None:
        return ShardReport(
            shard=shard, ran=ran, finished=finished, total=len(tasks), directory=store.directory
        )
    if deadline is not None and finished != len(tasks):  # the tasks before the first unrun
        cut = next(
            pos
            for pos, key in enumerate(task_keys(tasks))
            if store.needs_work(key, max_attempts)[0]
        )
        head = _head(tasks, cut)
        return Resumed(
            items=StoredItems(head, store, light),
            attempts=StoredAttempts(head, store),
            resumed=sum(loaded[:cut]),
            not_run=len(tasks) - cut,
        )
    if finished != len(tasks):  # a repeated key was skipped as finished by its first task
        raise ParameterError(
            f"task keys must be unique: {len(tasks)} tasks, {finished} finished items",
            name="tasks",
        )
    return Resumed(items=items, attempts=StoredAttempts(tasks, store), resumed=resumed)


_REFUSED_PAYLOAD = "its worker-written payload was refused (checksum or file mismatch)"
"""Why a worker-written payload that the store refused counts as a failed attempt."""


def _accept_written(
    store: SweepStore, key: str, written: WrittenItem, attempts: int
) -> ItemRecord | None:
    """Record a worker-written payload under its final attempt count (None: refused, warned).

    The attempt count in the summary, if it has one, is the outcome's: the worker
    could not know it.
    """
    if "attempts" in written.summary:
        written = replace(written, summary={**written.summary, "attempts": attempts})
    return store.accept(key, written, attempts=attempts)


def _in_shard(pos: int, shard: tuple[int, int]) -> bool:
    """Whether the task at 0-based position ``pos`` is shard ``(i, n)``'s (``i`` 1-based)."""
    return pos % shard[1] == shard[0] - 1


def _head(tasks: Sequence[Task], count: int) -> Sequence[Task]:
    """Return the first ``count`` tasks (a :class:`TaskSequence` stays lazy)."""
    return tasks.head(count) if isinstance(tasks, TaskSequence) else tasks[:count]


def _take(stream: Iterator[Task], n: int) -> list[Task]:
    out: list[Task] = []
    for task in stream:
        out.append(task)
        if len(out) == n:
            break
    return out


class _Finished(Mapping[str, T]):
    """The items a store holds as finished (done, or failed with attempts used up), lazily."""

    def __init__(self, items: StoredItems[T], store: SweepStore, max_attempts: int) -> None:
        self._items, self._store, self._max = items, store, max_attempts

    def __getitem__(self, key: str) -> T:
        if self._store.needs_work(key, self._max)[0]:
            raise KeyError(key)
        return self._items[key]

    def __iter__(self) -> Iterator[str]:
        return (k for k in self._items if not self._store.needs_work(k, self._max)[0])

    def __len__(self) -> int:
        return sum(1 for _ in self)


class _Refused(Exception):
    """A kept item's payload was refused while selecting the optima."""

    def __init__(self, key: str) -> None:
        super().__init__(key)
        self.key = key


def _run_all(
    tasks: Sequence[Task],
    store: SweepStore | None,
    options: SweepOptions,
    load: Callable[[str], T],
    convert: Callable[[TaskOutcome], T],
    payload: Callable[[str, T], tuple[object, Mapping[str, object]]],
    initializer: Callable[..., object] | None,
    initargs: tuple[object, ...],
    on_resumed: Callable[[dict[str, T]], None] | None,
    on_final: Callable[[str, T, int], None] | None,
    describe: Describe[V, P] | None,
    light: Callable[[str, ItemRecord], T] | None,
    keep_all: bool,
    deadline: float | None,
) -> Resumed[T] | ShardReport:
    max_attempts = options.max_attempts
    items: dict[str, T] = {}
    attempts: dict[str, int] = {}
    todo: list[Task] = []
    for task in tasks:
        made = 0
        if store is not None:
            again, made = store.needs_work(task.key, max_attempts)
            if not again:
                if not keep_all:
                    assert light is not None
                    attempts[task.key] = made
                    items[task.key] = light(task.key, store.record(task.key))  # type: ignore[arg-type]
                    continue
                if store.verify(task.key):
                    attempts[task.key] = made
                    items[task.key] = load(task.key)
                    continue
                made = 0  # refused (warned): recomputed from scratch
        attempts[task.key] = made
        todo.append(replace(task, attempts=made))
    resumed = len(items)
    resumed_keys = set(items)
    shard = options.shard
    if shard is not None:  # only this shard's positions; the others are other jobs' work
        mine = {t.key for pos, t in enumerate(tasks) if _in_shard(pos, shard)}
        todo = [t for t in todo if t.key in mine]
    if on_resumed is not None:
        on_resumed(dict(items))
    use = store is not None and describe is not None and options.writes_in_workers
    writer = store.writer() if use and store is not None else None
    if writer is not None:
        assert describe is not None
        todo = [
            replace(t, fn=run_and_write, args=(writer, describe, keep_all, t.key, t.fn, t.args))
            for t in todo
        ]
    redo: list[Task] = []
    ran = len(todo)

    def finish(o: TaskOutcome, item: T) -> None:
        if o.final:
            items[o.key] = item
            if on_final is not None:
                on_final(o.key, item, len(items))

    def record(o: TaskOutcome) -> None:
        attempts[o.key] = o.attempts
        if store is None:
            finish(o, convert(o))
            return
        if o.ok and isinstance(o.value, WrittenItem) and writer is not None:
            written = o.value
            rec = _accept_written(store, o.key, written, o.attempts)
            if rec is None:  # refused (warned): a failed attempt, retried if attempts remain
                why = _REFUSED_PAYLOAD
                store.write_failed(o.key, why, attempts=o.attempts)
                failed = replace(o, value=None, error=why, final=o.attempts >= max_attempts)
                if failed.final:
                    finish(failed, convert(failed))
                else:
                    task = next(t for t in todo if t.key == o.key)  # rare: a refusal
                    redo.append(replace(task, attempts=o.attempts))
                return
            if keep_all:
                finish(o, convert(replace(o, value=written.value)))
            else:
                assert light is not None
                finish(o, light(o.key, rec))
            return
        item = convert(o)
        if o.ok:
            data, summary = payload(o.key, item)
            rec = store.write_done(o.key, data, summary, attempts=o.attempts)
        else:
            rec = store.write_failed(o.key, str(o.error), attempts=o.attempts)
        if o.ok and not keep_all:
            assert light is not None
            item = light(o.key, rec)
        finish(o, item)

    try:
        while todo:
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
                keep_values=False,
                deadline=deadline,
            )
            todo, redo = redo, []
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
        where = store.directory if store is not None else options.directory
        assert where is not None  # SweepOptions refuses a shard without out=
        return ShardReport(
            shard=shard, ran=ran, finished=len(items), total=len(tasks), directory=where
        )
    keys = list(task_keys(tasks))
    cut = next((pos for pos, key in enumerate(keys) if key not in items), len(keys))
    assert deadline is not None or cut == len(keys), f"run_tasks left {keys[cut:]} unfinished"
    if cut < len(keys):  # a deadline stopped the sweep: the tasks before the first unrun
        loaded = sum(1 for key in keys[:cut] if key in resumed_keys)
        head = {key: items[key] for key in keys[:cut]}
        return Resumed(
            items=head,
            attempts={key: attempts[key] for key in keys[:cut]},
            resumed=loaded,
            not_run=len(keys) - cut,
        )
    return Resumed(items=items, attempts=attempts, resumed=resumed)
