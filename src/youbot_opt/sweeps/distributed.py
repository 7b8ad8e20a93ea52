"""Running a sweep's tasks on a Dask cluster: batches, per-item outcomes, crash-charged singles.

Owns the Dask half of :func:`youbot_opt.sweeps.pool.run_tasks` (spec: the
sweep layer of ``ARCHITECTURE.md``; guide: ``docs/scaling.md``).
:func:`run_dask` keeps the cluster's threads busy with batches of items, the
initializer scattered to every worker once; :func:`run_batch` is the task a
Dask worker runs. A batch whose worker died is re-run item by item, so a
crash is charged to exactly one item, and Dask's own retries are off. The
connection, sizing and :class:`~youbot_opt.sweeps.scheduler.ClusterLostError`
live in :mod:`.scheduler`; Dask is imported only when a cluster is used.

    run_dask(runner, client, initializer=None, initargs=(), batch_size=None)
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import pickle
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from youbot_opt.sweeps.scheduler import ClusterLostError
from youbot_opt.sweeps.tasks import TaskRunner, failure_reason, invoke

if TYPE_CHECKING:  # pragma: no cover - typing only; dask is optional
    from distributed import Client
    from distributed import Future as DaskFuture

__all__ = ["run_batch", "run_dask"]

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
        return pickle.dumps(_DIED)
    init_error = None
    if init is not None:
        digest = hashlib.blake2b(init, digest_size=16).hexdigest()
        if getattr(_INIT, "digest", None) != digest:
            try:
                initializer, initargs = pickle.loads(init)
                initializer(*initargs)
                _INIT.error = None
            except Exception as exc:  # reported with every item instead of a silent failure
                _INIT.error = f"worker initializer failed: {failure_reason(exc)}"
            _INIT.digest = digest
        init_error = _INIT.error
    replies: list[tuple[Any, str | None, Any, float]] = []
    for key, fn, args in pickle.loads(batch):
        tic = time.perf_counter()
        try:
            if init_error is not None:
                raise RuntimeError(init_error)
            value, wall = invoke(fn, args)
            replies.append((key, None, value, wall))
        except Exception as exc:  # one failing item must not end the batch
            replies.append((key, failure_reason(exc), None, time.perf_counter() - tic))
    try:
        return pickle.dumps(replies)
    except Exception:  # some value does not pickle: charge that item alone
        safe: list[tuple[Any, str | None, Any, float]] = []
        for key, error, value, wall in replies:
            try:
                pickle.dumps(value)
                safe.append((key, error, value, wall))
            except Exception as exc:
                safe.append((key, f"cannot send the result: {failure_reason(exc)}", None, wall))
        return pickle.dumps(safe)


# ------------------------------------------------------------------- driver
def run_dask(
    runner: TaskRunner,
    client: Client,
    initializer: Callable[..., object] | None,
    initargs: tuple[object, ...],
    batch_size: int | None,
) -> None:
    """Run on a Dask cluster: batches of items, per-item outcomes, crash-charged singles.

    ``runner.workers`` batches are kept in flight (the cluster's threads by
    default): not more, so that a task Dask finds on a dead worker was
    running there, not queued (a queued single item would be charged a
    crash it did not cause). The initializer travels to each worker once (scattered);
    a batch whose worker died is re-run item by item, so a crash is
    charged to one item. Dask's own retries are off (``retries=0``).
    """
    from distributed import KilledWorker, as_completed

    n = len(runner.pending)
    size = batch_size or max(1, min(_MAX_BATCH, n // (8 * runner.workers)))
    solo: set[str] = set()  # items to run alone: after a crash of their batch, or a retry
    init = None
    if initializer is not None:
        blob = pickle.dumps((initializer, initargs))
        init = _dask_call(lambda: client.scatter(blob, broadcast=True, hash=False))
    inflight: dict[DaskFuture, list[str]] = {}
    done = as_completed(loop=client.loop)
    try:
        while runner.pending or runner.retry or inflight:
            while len(inflight) < runner.workers and (runner.pending or runner.retry):
                keys = _next_batch(runner, size, solo)
                items = [(k, runner.tasks[k].fn, runner.tasks[k].args) for k in keys]
                try:
                    payload = pickle.dumps(items)
                except Exception as exc:  # a task does not pickle: charge it alone
                    if len(keys) > 1:
                        solo.update(keys)
                        runner.pending.extendleft(reversed(keys))
                    else:
                        runner.emit(
                            keys[0], None, f"cannot send the task: {failure_reason(exc)}", 0.0
                        )
                    continue
                fut = _dask_call(
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
            _collect(runner, fut, keys, solo, KilledWorker)
    finally:
        for fut in inflight:  # interrupted: do not leave our work on the cluster
            with contextlib.suppress(Exception):
                fut.cancel()


def _next_batch(runner: TaskRunner, size: int, solo: set[str]) -> list[str]:
    """Keys of the next batch: one retried or solo item, else up to ``size`` fresh ones."""
    if runner.retry:
        key = runner.retry.popleft()
        solo.add(key)
        return [key]
    keys = [runner.pending.popleft()]
    if keys[0] in solo:
        return keys
    while runner.pending and len(keys) < size and runner.pending[0] not in solo:
        keys.append(runner.pending.popleft())
    return keys


def _collect(
    runner: TaskRunner, fut: DaskFuture, keys: list[str], solo: set[str], killed: type[Exception]
) -> None:
    """Turn a finished Dask batch into outcomes (or solo re-runs after a worker death)."""
    status = fut.status
    if status in ("cancelled", "lost") or (status == "error" and _is_cancel(fut)):
        runner.pending.extendleft(reversed(keys))  # not started or lost with the scheduler
        raise ClusterLostError(f"the Dask scheduler or cluster went away (task {status})")
    died = False
    replies: Any = None
    if status == "error":
        exc = _dask_call(fut.exception)
        if isinstance(exc, killed):
            died = True
        else:  # the batch itself failed (e.g. its payload did not unpickle there)
            for key in keys:
                runner.emit(key, None, failure_reason(exc), 0.0)
            return
    else:
        replies = pickle.loads(_dask_call(fut.result))
        died = replies == _DIED
    if died:
        if len(keys) > 1:  # nothing charged: each item runs alone next
            solo.update(keys)
            runner.pending.extendleft(reversed(keys))
            return
        runner.emit(
            keys[0],
            None,
            "Dask worker died (e.g. a segfault or an out-of-memory kill) while running this item",
            0.0,
        )
        return
    for key, error, value, wall in replies:
        runner.emit(key, value, error, wall)


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
