"""The store at scale (#15 item 3): worker-written items, keep_results=False, summary resumes.

References: the same sweep with ``keep_results=True`` and a brute-force
``cluster_optima`` over every full item; the on-disk files themselves (a
payload edited after its worker reported its SHA-256 must be refused).
Items are trivial (a few floats), so every test runs in well under a second
but the process-pool ones.
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

import numpy as np
import pytest

from youbot_opt.exceptions import ParameterError, ResultFileError, YoubotOptWarning
from youbot_opt.sweeps.optima import KeepRule, cluster_optima, select_optima
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.sweeps.pool import Task
from youbot_opt.sweeps.resume import ShardReport, run_resumable
from youbot_opt.sweeps.store import ItemRecord, SweepStore, stored_records

N = 60


def point(i: int) -> list[float]:
    """Item i: a 'solve' that lands on one of three optima (two share an objective), or fails."""
    if i % 7 == 3:
        return [math.nan, float(i)]  # did not converge
    where = i % 3  # optima 0 and 1 share the objective 0.5 (only the distance splits them)
    objective = 1.0 if where == 2 else 0.5
    return [objective + 1e-9 * i, float(where)]


def encode(value: list[float]) -> bytes:
    return json.dumps(value).encode()


def save(value: list[float], path: Path) -> None:
    path.write_bytes(encode(value))


def load_file(path: Path) -> list[float]:
    return [float(x) for x in json.loads(path.read_text())]


def describe(key: str, args: tuple, value: list[float]) -> tuple[list[float], dict]:  # type: ignore[type-arg]
    return value, {"objective": None if math.isnan(value[0]) else value[0]}


def _distance(a: list[float], b: list[float]) -> float:
    return abs(a[1] - b[1])


RULE: KeepRule[list[float]] = KeepRule(
    objective=lambda v: None if math.isnan(v[0]) else v[0],
    distance=_distance,
    obj_tol=1e-6,
    dist_tol=0.5,
)


def _light(key: str, record: ItemRecord) -> list[float]:
    f = record.summary.get("objective")
    return [math.nan if f is None else float(f), math.nan]  # no position: not kept


def _sweep(  # type: ignore[no-untyped-def]
    out: Path,
    *,
    keep: bool,
    executor: str = "serial",
    loads: list[str] | None = None,
    shard: tuple[int, int] | None = None,
):
    store = SweepStore(
        out, kind="points", params={"n": N}, save=save, load=load_file, suffix=".pt", encode=encode
    )

    def load(key: str) -> list[float]:
        if loads is not None:
            loads.append(key)
        return store.load(key)

    tasks = [Task(key=f"p{i:03d}", fn=point, args=(i,)) for i in range(N)]
    return run_resumable(
        tasks,
        store=store,
        options=SweepOptions(executor=executor, out=out, keep_results=keep, workers=2, shard=shard),
        load=load,
        convert=lambda o: o.value,
        payload=lambda key, v: describe(key, (), v),
        describe=describe,
        light=_light,
        keep=RULE,
    )


@pytest.mark.parametrize("keep", [True, False])
def test_a_shard_run_returns_its_report_and_a_plain_run_collects(
    tmp_path: Path, keep: bool
) -> None:
    """A shard returns a ShardReport (it raises nothing); a run without the shard loads all."""
    out = tmp_path / "run"
    first = _sweep(out, keep=keep, shard=(1, 2))
    assert isinstance(first, ShardReport)
    assert (first.shard, first.ran, first.finished, first.total, first.left) == (
        (1, 2),
        30,
        30,
        N,
        30,
    )
    assert first.directory == out
    assert str(first) == (
        f"shard 1/2: ran 30 item(s); 30 of {N} items are finished in {out}; when every shard "
        "is done, run the same sweep without the shard to collect them"
    )
    second = _sweep(out, keep=keep, shard=(2, 2))
    assert isinstance(second, ShardReport) and (second.ran, second.left) == (30, 0)
    collected = _sweep(out, keep=keep)
    reference = _sweep(tmp_path / "reference", keep=keep)
    assert collected.resumed == N and len(collected.items) == N
    assert [list(c) for c in collected.clusters] == [list(c) for c in reference.clusters]


def test_keep_results_false_keeps_the_optima_of_the_full_run(tmp_path: Path) -> None:
    """Best item and distinct optima equal keep_results=True's; only their values are kept."""
    full = _sweep(tmp_path / "full", keep=True)
    lean = _sweep(tmp_path / "lean", keep=False, executor="process")
    reference = cluster_optima(
        [(k, v) for k, v in full.items.items() if RULE.objective(v) is not None],
        objective=lambda kv: kv[1][0],
        distance=lambda a, b: _distance(a[1], b[1]),
        obj_tol=RULE.obj_tol,
        dist_tol=RULE.dist_tol,
    )
    assert [[k for k, _ in c] for c in reference] == [list(c) for c in lean.clusters]
    assert len(lean.clusters) == 3  # two optima share the objective 0.5: the distance splits them
    reps = {c[0] for c in lean.clusters}
    for key, value in lean.items.items():
        if key in reps:
            assert value == full.items[key]  # the kept optima: full values, bit for bit
        else:
            assert math.isnan(value[1])  # light: figures only
            assert value[0] == full.items[key][0] or math.isnan(value[0])
    assert lean.attempts == full.attempts


def test_a_resume_reads_summaries_not_the_results(tmp_path: Path) -> None:
    """A finished lean sweep resumes from the journal: it loads the kept optima and nothing else.

    The other payloads are deleted first: the resume completes without them.
    """
    out = tmp_path / "run"
    first = _sweep(out, keep=False)
    reps = [c[0] for c in first.clusters]
    for rec in stored_records(out):
        if rec.state == "done" and rec.key not in reps:
            (out / "items" / str(rec.payload)).unlink()
    loads: list[str] = []
    again = _sweep(out, keep=False, loads=loads)
    assert again.resumed == N and again.clusters == first.clusters
    assert sorted(loads) == sorted(reps)
    assert {k: again.items[k] for k in reps} == {k: first.items[k] for k in reps}


def test_the_first_selection_reads_each_converged_item_once(tmp_path: Path) -> None:
    """Choosing the optima (no saved selection) reads converged payloads once, others never."""
    out = tmp_path / "run"
    first = _sweep(out, keep=False)
    (out / "optima.json").unlink()
    unconverged = [k for k, v in first.items.items() if math.isnan(v[0])]
    converged = [k for k, v in first.items.items() if not math.isnan(v[0])]
    for rec in stored_records(out):
        if rec.key in unconverged:
            (out / "items" / str(rec.payload)).unlink()
    loads: list[str] = []
    again = _sweep(out, keep=False, loads=loads)
    assert again.clusters == first.clusters
    assert sorted(loads) == sorted(converged)  # each once; the unconverged never


def test_a_worker_written_item_with_a_wrong_hash_is_refused_and_recomputed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The driver re-hashes every worker-written file: a mismatch is warned, retried, then right."""
    from youbot_opt.sweeps import store as store_module

    real = store_module.ItemWriter.write
    calls: list[str] = []

    def lying_write(self, key: str, payload):  # type: ignore[no-untyped-def]
        name, checksum = real(self, key, payload)
        calls.append(key)
        if key == "p005" and calls.count(key) == 1:  # first attempt: the file is not what it says
            return name, hashlib.sha256(b"something else").hexdigest()
        return name, checksum

    monkeypatch.setattr(store_module.ItemWriter, "write", lying_write)
    with pytest.warns(YoubotOptWarning, match=r"refused item 'p005'.*checksum its worker reported"):
        got = _sweep(tmp_path / "run", keep=True)
    assert calls.count("p005") == 2 and got.attempts["p005"] == 2
    assert got.items["p005"] == point(5)
    states = [(r.state, r.attempts) for r in stored_records(tmp_path / "run") if r.key == "p005"]
    assert states == [("failed", 1), ("done", 2)]  # the refused file was never recorded as done


def test_a_refused_kept_optimum_is_recomputed(tmp_path: Path) -> None:
    """An optimum whose payload was edited on disk is refused at the selection, rerun, kept."""
    out = tmp_path / "run"
    first = _sweep(out, keep=False)
    best = first.clusters[0][0]
    path = next(out.glob(f"items/*/{best}.pt"))
    path.write_bytes(encode([0.0, 99.0]))  # edited: a "better" optimum that was never computed
    with pytest.warns(YoubotOptWarning, match=rf"refused item '{best}'.*checksum"):
        again = _sweep(out, keep=False)
    assert again.items[best] == first.items[best] and again.clusters == first.clusters


def test_keep_results_false_needs_a_store_and_a_light_form(tmp_path: Path) -> None:
    """Without out= or without the sweep's light items, keep_results=False is refused clearly."""
    with pytest.raises(ParameterError, match="keep_results=False needs out="):
        SweepOptions(keep_results=False)
    store = SweepStore(tmp_path, kind="k", params={}, save=save, load=load_file)
    with pytest.raises(ParameterError, match="not supported by this sweep"):
        run_resumable(
            [Task(key="a", fn=point, args=(0,))],
            store=store,
            options=SweepOptions(executor="serial", out=tmp_path, keep_results=False),
            load=store.load,
            convert=lambda o: o.value,
            payload=lambda key, v: (v, {}),
        )


def test_select_optima_loads_only_what_it_needs() -> None:
    """The best-only rule loads one item; the clustering rule equals cluster_optima."""
    values = {f"k{i}": point(i) for i in range(30)}
    loaded: list[str] = []

    def load(key: str) -> list[float]:
        loaded.append(key)
        return values[key]

    kept, clusters = select_optima(values, KeepRule(objective=RULE.objective), load)
    best = min((v[0], k) for k, v in values.items() if not math.isnan(v[0]))[1]
    assert list(kept) == [best] and loaded == [best]
    kept, clusters = select_optima(values, RULE, load)
    assert [kept[c[0]] for c in clusters] == [values[c[0]] for c in clusters]


@pytest.fixture(scope="module")
def traj_solver():  # type: ignore[no-untyped-def]
    """A 12-knot study-1 solver (its 9 starts reach 3 optima, two within 1e-13 in objective)."""
    from youbot_opt.reproduction.study1 import study1_problem
    from youbot_opt.trajopt.solver import TrajOptSolver

    return TrajOptSolver(study1_problem(12))


def test_trajectory_multistart_keeps_its_best_and_optima_only(traj_solver, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """keep_results=False (workers write the items): same best and distinct optima, fewer results.

    The reference is the same multistart with keep_results=True; the 12-knot
    problem has two optima 1e-13 apart in objective but far apart in the
    trajectory, so the clusters are only right if the sweep compared the full
    trajectories. A resume of the lean folder loads only the kept results.
    """
    from youbot_opt.trajopt.multistart import StoredStarts, run_multistart

    def run(out: Path, keep: bool, executor: str = "process"):  # type: ignore[no-untyped-def]
        sweep = SweepOptions(executor=executor, workers=2, out=out, keep_results=keep)
        return run_multistart(traj_solver, 8, seed=3, include_straight=True, sweep=sweep)

    full, lean = run(tmp_path / "full", True), run(tmp_path / "lean", False)
    assert isinstance(full.starts, tuple) and isinstance(lean.starts, StoredStarts)
    assert lean.best is not None and full.best is not None
    assert (lean.best.key, lean.best.objective) == (full.best.key, full.best.objective)
    assert lean.best.result is not None
    np.testing.assert_array_equal(lean.best.result.trajectory.q, full.best.result.trajectory.q)

    def optima(ms):  # type: ignore[no-untyped-def]
        return [(o.objective, o.count, o.seeds) for o in ms.distinct_optima()]

    assert optima(lean) == optima(full) and len(optima(full)) >= 2
    kept = {s.key for s in lean.starts if s.result is not None}
    assert kept == {o.best.key for o in lean.distinct_optima()}

    def figures(ms):  # type: ignore[no-untyped-def]  # every start's, wall times aside
        return [{k: v for k, v in s.summary().items() if not k.endswith("time_s")}
                for s in ms.starts]  # fmt: skip

    assert figures(lean) == figures(full)
    again = run(tmp_path / "lean", False, "serial")
    assert again.resumed == lean.n_starts and optima(again) == optima(full)
    assert {s.key for s in again.starts if s.result is not None} == kept


def test_bound_scaling_keeps_the_best_of_each_scale(traj_solver, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """keep_results=False in the bound-scaling study: each scale's row equals the full run's."""
    from youbot_opt.trajopt.bound_scaling import bound_scaling_study

    def run(out: Path, keep: bool):  # type: ignore[no-untyped-def]
        sweep = SweepOptions(executor="serial", out=out, keep_results=keep)
        return bound_scaling_study(traj_solver, (1.0, 0.9), n_starts=3, seed=1, sweep=sweep)

    full, lean = run(tmp_path / "full", True), run(tmp_path / "lean", False)
    for a, b in zip(full.rows, lean.rows, strict=True):
        assert (a.objective, a.active_counts()) == (b.objective, b.active_counts())
        assert len(a.multistart.distinct_optima()) == len(b.multistart.distinct_optima())


def test_a_stored_summary_figure_is_read_as_a_number_or_refused_naming_it() -> None:
    record = ItemRecord(
        key="start_0003",
        state="done",
        attempts=1,
        summary={"solve_time_s": 0.25, "text": "1.5", "null": None, "flag": True, "list": [1]},
    )
    assert record.number("solve_time_s") == 0.25
    assert record.number("text") == 1.5
    assert math.isnan(record.number("null"))
    assert record.number("absent", default=0.0) == 0.0
    for name in ("flag", "list", "absent"):
        with pytest.raises(ResultFileError, match=f"start_0003.*'{name}'"):
            record.number(name)
    with pytest.raises(ResultFileError, match="'word' = 'fast' is not a number"):
        ItemRecord(key="k", state="done", attempts=1, summary={"word": "fast"}).number("word")
