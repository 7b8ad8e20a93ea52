"""keep_results=False with bounded driver memory (#15 item 3): lazy tasks, chunks, the lazy reader.

References: the same sweep run with ``keep_results=True`` on a plain list of
tasks (everything in memory), and the records the store wrote. Equalities are
exact: the items are deterministic functions of their index.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from youbot_opt.sweeps import resume
from youbot_opt.sweeps.optima import KeepRule
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.sweeps.pool import Task
from youbot_opt.sweeps.resume import StoredItems, run_resumable
from youbot_opt.sweeps.store import ItemRecord, SweepStore
from youbot_opt.sweeps.tasks import TaskSequence

N = 45


def point(i: int) -> list[float]:
    """Item i lands on one of three optima (two share an objective), or does not converge."""
    if i % 7 == 3:
        return [math.nan, float(i)]
    where = i % 3
    return [(1.0 if where == 2 else 0.5) + 1e-9 * i, float(where)]


def encode(value: list[float]) -> bytes:
    return json.dumps(value).encode()


def save(value: list[float], path: Path) -> None:
    path.write_bytes(encode(value))


def load_file(path: Path) -> list[float]:
    return [float(x) for x in json.loads(path.read_text())]


def describe(key: str, args: tuple, value: list[float]) -> tuple[list[float], dict]:  # type: ignore[type-arg]
    return value, {"objective": None if math.isnan(value[0]) else value[0]}


def _light(key: str, record: ItemRecord) -> list[float]:
    f = record.summary.get("objective")
    return [math.nan if f is None else float(f), math.nan]  # no position: not kept


RULE: KeepRule[list[float]] = KeepRule(
    objective=lambda v: None if math.isnan(v[0]) else v[0],
    distance=lambda a, b: abs(a[1] - b[1]),
    obj_tol=1e-6,
    dist_tol=0.5,
)


def flaky_point(i: int) -> list[float]:
    """point(i), except that every 11th item always raises (a failure used up)."""
    if i % 11 == 5:
        raise RuntimeError(f"item {i} cannot be solved")
    return point(i)


def _task(i: int) -> Task:
    return Task(key=f"p{i:03d}", fn=flaky_point, args=(i,))


def _run(out: Path, tasks, *, keep: bool, executor: str = "serial"):  # type: ignore[no-untyped-def]
    store = SweepStore(
        out, kind="points", params={"n": N}, save=save, load=load_file, suffix=".pt", encode=encode
    )
    finals: list[tuple[str, int]] = []
    resumed: list[dict[str, list[float]]] = []
    got = run_resumable(
        tasks,
        store=store,
        options=SweepOptions(
            executor=executor, out=out, keep_results=keep, workers=2, max_attempts=2
        ),
        load=store.load,
        convert=lambda o: o.value if o.ok else [math.nan, math.nan],
        payload=lambda key, v: describe(key, (), v),
        on_final=lambda key, item, n: finals.append((key, n)),
        on_resumed=lambda done: resumed.append(dict(done)),
        describe=describe,
        light=_light,
        keep=RULE,
    )
    assert len(resumed) == 1 and len(resumed[0]) == got.resumed
    return got, store, finals


@pytest.mark.parametrize("executor", ["serial", "process"])
def test_lazy_tasks_in_chunks_equal_a_list_kept_in_memory(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, executor: str
) -> None:
    """A TaskSequence run 8 tasks at a time gives what a list with keep_results=True gives.

    Same distinct optima, same kept values, same attempts (failures retried
    across chunks), every item final once, and records equal item by item.
    """
    monkeypatch.setattr(resume, "CHUNK", 8)  # several chunks, one pool for all of them
    full, full_store, _ = _run(tmp_path / "full", [_task(i) for i in range(N)], keep=True)
    lean, lean_store, finals = _run(
        tmp_path / "lean", TaskSequence(N, _task), keep=False, executor=executor
    )
    assert isinstance(lean.items, StoredItems)
    assert list(lean.items) == list(full.items) == [f"p{i:03d}" for i in range(N)]
    assert dict(lean.attempts) == full.attempts
    assert sorted(k for k, _ in finals) == sorted(full.items)  # each item final exactly once
    assert sorted(n for _, n in finals) == list(range(1, N + 1))
    for c in lean.clusters:  # the kept optima: full values, bit for bit
        assert lean.items[c[0]] == full.items[c[0]]
    lean_records, full_records = lean_store.records(), full_store.records()
    assert {k: (r.state, r.attempts, r.summary, r.checksum) for k, r in lean_records.items()} == {
        k: (r.state, r.attempts, r.summary, r.checksum) for k, r in full_records.items()
    }
    assert lean_records["p005"].state == "failed" and lean_records["p005"].attempts == 2


def test_the_lazy_reader_equals_the_summaries_of_a_kept_run(tmp_path: Path) -> None:
    """StoredItems reads each item from its journal line: equal to the light form of the
    keep_results=True items, also after reopening the store (the compact index)."""
    full, _, _ = _run(tmp_path / "full", [_task(i) for i in range(N)], keep=True)
    lean, _, _ = _run(tmp_path / "lean", TaskSequence(N, _task), keep=False)
    reps = {c[0] for c in lean.clusters}

    def summary_form(v: list[float]) -> list[float]:
        return _light(
            "", ItemRecord(key="x", state="done", attempts=1, summary=describe("", (), v)[1])
        )

    for key in full.items:
        want = full.items[key] if key in reps else summary_form(full.items[key])
        got = lean.items[key]
        assert got == want or (math.isnan(got[0]) and math.isnan(want[0]))
    again, store, finals = _run(tmp_path / "lean", TaskSequence(N, _task), keep=False)
    assert again.resumed == N and again.clusters == lean.clusters and finals == []
    assert "p999" not in again.items and "p003" in again.items
    with pytest.raises(KeyError):
        again.items["p999"]
    assert [store.record(k) for k in full.items] == [
        SweepStore(
            tmp_path / "lean", kind="points", params={"n": N}, save=save, load=load_file,
            suffix=".pt", encode=encode,
        ).record(k)
        for k in full.items
    ]  # fmt: skip


def test_many_journal_files_merge_and_the_last_line_of_a_key_wins(tmp_path: Path) -> None:
    """40 runs (40 journal files; a key failed in one run, done in a later one) reopen as one file.

    The index keeps each key's last line across files, before and after the merge.
    """

    def open_store() -> SweepStore:
        return SweepStore(
            tmp_path, kind="points", params={"n": 1}, save=save, load=load_file, suffix=".pt"
        )

    for run in range(40):
        store = open_store()
        store.write_failed(f"k{run:02d}", f"run {run}", attempts=1)
        if run:  # the previous run's failure is done now
            store.write_done(f"k{run - 1:02d}", [float(run), 0.0], {"run": run}, attempts=2)
        store.close()
    journals = tmp_path / "items" / "journal"
    files = sorted(p.name for p in journals.glob("*.jsonl"))
    # the 34th run found 33 files and merged them into one; runs 34-40 added one each
    assert len(files) == 8 and sum(f.startswith("compact-") for f in files) == 1
    store = open_store()
    records = store.records()
    assert len(records) == 40
    for run in range(39):
        rec = records[f"k{run:02d}"]
        assert (rec.state, rec.attempts, dict(rec.summary)) == ("done", 2, {"run": run + 1})
        assert rec.reasons == (f"run {run}",)
        assert store.load(f"k{run:02d}") == [float(run + 1), 0.0]
    assert records["k39"].state == "failed"


def test_a_resume_makes_only_the_tasks_it_runs(tmp_path: Path) -> None:
    """Given ``key=``, a TaskSequence is walked by keys: a finished sweep makes no task.

    (IK starts are drawn when their task is made, so a resume draws none.) The
    clusters' members also read back sorted by key, representative included.
    """
    made: list[int] = []

    def make(i: int) -> Task:
        made.append(i)
        return _task(i)

    def key(i: int) -> str:
        return f"p{i:03d}"

    first, _, _ = _run(tmp_path / "run", TaskSequence(N, make, key=key), keep=False)
    assert sorted(made) == list(range(N))  # each task made once, as it ran
    made.clear()
    again, _, _ = _run(tmp_path / "run", TaskSequence(N, make, key=key), keep=False)
    assert made == [] and again.resumed == N
    assert list(again.items) == [key(i) for i in range(N)]
    assert again.clusters == first.clusters
    for number, members in enumerate(first.clusters):
        assert list(first.clusters.members_in_key_order(number)) == sorted(members)
