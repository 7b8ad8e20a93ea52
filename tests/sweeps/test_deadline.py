"""A sweep's deadline (#25's time budget): no task begins after it; the result is a prefix.

``run_tasks(deadline=)`` begins no new task once the :func:`time.monotonic` instant
has passed (checked as attempts end, so the first wave always begins; retries of
begun tasks still run). ``run_resumable(deadline=)`` then ends the sweep at its first
unfinished task: the items before it, ``not_run`` for the rest, and a rerun goes on.
Verdicts are deterministic: the deadlines are long past or far away.
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import pytest

from youbot_opt.sweeps.optima import KeepRule
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.sweeps.pool import Task, run_tasks
from youbot_opt.sweeps.resume import run_resumable
from youbot_opt.sweeps.store import ItemRecord, SweepStore
from youbot_opt.sweeps.tasks import TaskSequence

N = 8
_CALLS: dict[str, int] = {}


def square(i: int) -> float:
    return float(i * i)


def fails_once(key: str) -> str:
    """Raise on the first call per key in this process, then return the key."""
    _CALLS[key] = _CALLS.get(key, 0) + 1
    if _CALLS[key] == 1:
        raise RuntimeError(f"{key} fails once")
    return key


def _tasks(n: int = N) -> list[Task]:
    return [Task(key=f"t{i}", fn=square, args=(i,)) for i in range(n)]


PAST = 0.0  # a time.monotonic() instant long gone


@pytest.mark.parametrize(("executor", "workers", "begun"), [("serial", 1, 1), ("process", 2, 2)])
def test_past_deadline_begins_only_the_first_wave(executor, workers, begun):
    out = run_tasks(_tasks(), executor=executor, workers=workers, deadline=PAST)
    assert sorted(out) == [f"t{i}" for i in range(begun)]
    assert all(o.ok and o.final for o in out.values())


@pytest.mark.parametrize("deadline", [None, math.inf, "soon"])
def test_no_or_far_deadline_runs_every_task(deadline):
    far = time.monotonic() + 3600.0 if deadline == "soon" else deadline
    out = run_tasks(_tasks(), executor="serial", deadline=far)
    assert sorted(out) == sorted(f"t{i}" for i in range(N))


def test_a_begun_task_is_retried_after_the_deadline():
    """The first task fails once: its retry runs though no new task begins."""
    _CALLS.clear()
    tasks = [Task(key=f"r{i}", fn=fails_once, args=(f"r{i}",)) for i in range(3)]
    out = run_tasks(tasks, executor="serial", max_attempts=2, deadline=PAST)
    assert list(out) == ["r0"] and out["r0"].ok and out["r0"].attempts == 2


# ------------------------------------------------------------------ run_resumable
def _encode(value: float) -> bytes:
    return json.dumps(value).encode()


def _save(value: float, path: Path) -> None:
    path.write_bytes(_encode(value))


def _load(path: Path) -> float:
    return float(json.loads(path.read_text()))


def _light(key: str, record: ItemRecord) -> float:
    return float(record.summary["objective"])  # type: ignore[arg-type]


RULE: KeepRule[float] = KeepRule(
    objective=lambda v: v, distance=lambda a, b: abs(a - b), obj_tol=1e-9, dist_tol=0.5
)


def _resume(out: Path, tasks, *, keep: bool = True, deadline: float | None = PAST):  # type: ignore[no-untyped-def]
    store = SweepStore(
        out, kind="squares", params={"n": N}, save=_save, load=_load, suffix=".sq", encode=_encode
    )
    return run_resumable(
        tasks,
        store=store,
        options=SweepOptions(executor="serial", out=out, keep_results=keep),
        load=store.load,
        convert=lambda o: o.value if o.ok else math.nan,
        payload=lambda key, v: (v, {"objective": v}),
        light=_light,
        keep=RULE,
        deadline=deadline,
    )


@pytest.mark.parametrize("keep", [True, False])
def test_a_deadline_ends_the_sweep_at_its_first_unfinished_task_and_a_rerun_goes_on(tmp_path, keep):
    """Items 0 and 5 are in the store: a past deadline runs item 1, the result is 0-1.

    Item 5 stays in the store (not in this result) until item 4 has run; each rerun
    goes on with one item, then one without a deadline finishes every item.
    """
    tasks = _tasks() if keep else TaskSequence(N, lambda i: _tasks()[i])
    _resume(tmp_path, [_tasks()[0], _tasks()[5]], deadline=None)
    got = _resume(tmp_path, tasks, keep=keep)
    assert list(got.items) == ["t0", "t1"] and [got.items[k] for k in got.items] == [0.0, 1.0]
    assert dict(got.attempts) == {"t0": 1, "t1": 1}
    assert got.resumed == 1 and got.not_run == N - 2
    if not keep:
        assert [list(c) for c in got.clusters] == [["t0"], ["t1"]]  # the optima of the head
    got = _resume(tmp_path, tasks, keep=keep)
    assert list(got.items) == ["t0", "t1", "t2"] and got.resumed == 2 and got.not_run == N - 3
    got = _resume(tmp_path, tasks, keep=keep)
    assert list(got.items) == [f"t{i}" for i in range(4)] and got.not_run == N - 4
    got = _resume(tmp_path, tasks, keep=keep)  # runs item 4, so item 5 joins the result
    assert list(got.items) == [f"t{i}" for i in range(6)] and got.not_run == N - 6
    assert got.resumed == 5
    got = _resume(tmp_path, tasks, keep=keep, deadline=None)
    assert got.not_run == 0 and got.resumed == 6
    assert [got.items[f"t{i}"] for i in range(N)] == [float(i * i) for i in range(N)]


def test_dask_begins_no_new_batch_after_the_deadline():
    """One batch of one task in flight: it runs, the deadline stops the others."""
    distributed = pytest.importorskip("distributed")
    with (
        distributed.LocalCluster(
            n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None
        ) as cluster,
        distributed.Client(cluster, set_as_default=False) as client,
    ):
        out = run_tasks(_tasks(), executor=client, workers=1, batch_size=1, deadline=PAST)
        assert list(out) == ["t0"] and out["t0"].value == 0.0
        out = run_tasks(_tasks(), executor=client, workers=1, batch_size=1)
        assert sorted(out) == sorted(f"t{i}" for i in range(N))
