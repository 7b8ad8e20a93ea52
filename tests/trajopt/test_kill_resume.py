"""Sweeps that survive: crashing workers, failing items, and SIGKILL of the whole CLI sweep.

The crash and hang tests wrap the function of chosen tasks (``tests/_faults.py``):
those keys SIGSEGV (or hang) their pool worker; the package has no test hooks.
"""

from __future__ import annotations

import json
import os
import signal
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from _faults import faulty
from _sigkill import ITEM_SLEEP, kill_repeatedly
from youbot_opt.exceptions import ParameterError
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.sweeps.pool import Task, TaskOutcome, WorkerPool, run_tasks
from youbot_opt.sweeps.store import stored_record, stored_records


def _square(x: float) -> float:
    return x * x


def _fail_on_three(x: float) -> float:
    if x == 3:
        raise ValueError("three is not allowed")
    return x * x


def _tasks(fn: object, n: int = 6) -> list[Task]:
    return [Task(key=f"k{i}", fn=fn, args=(i,)) for i in range(n)]  # type: ignore[arg-type]


@pytest.mark.parametrize("executor", ["serial", "process", "threads"])
def test_failing_task_is_recorded_and_retried_once(executor: str) -> None:
    """A task that raises is recorded with its reason, retried once; the others all finish."""
    seen: list[TaskOutcome] = []
    ex: object = ThreadPoolExecutor(max_workers=2) if executor == "threads" else executor
    out = run_tasks(_tasks(_fail_on_three), executor=ex, workers=2, on_outcome=seen.append)  # type: ignore[arg-type]
    if isinstance(ex, ThreadPoolExecutor):
        ex.shutdown()
    assert {k: o.value for k, o in out.items() if o.ok} == {
        f"k{i}": i * i for i in range(6) if i != 3
    }
    bad = out["k3"]
    assert not bad.ok and bad.final and bad.attempts == 2
    assert bad.error == "ValueError: three is not allowed"
    assert [o.attempts for o in seen if o.key == "k3"] == [1, 2]  # one retry, both reported
    assert len(seen) == 7  # 5 successes + 2 failed attempts, nothing duplicated


def test_segfaulting_worker_is_recorded_failed_and_retried_once() -> None:
    """A task whose worker always segfaults fails after 2 attempts; the pool is rebuilt."""
    seen: list[TaskOutcome] = []
    tasks = faulty(_tasks(_square, 8), crash={"k2"})
    out = run_tasks(tasks, executor="process", workers=2, on_outcome=seen.append)
    assert {k: o.value for k, o in out.items() if o.ok} == {
        f"k{i}": i * i for i in range(8) if i != 2
    }
    crashed = out["k2"]
    assert not crashed.ok and crashed.final and crashed.attempts == 2
    assert "worker process crashed (killed by signal SIGSEGV" in str(crashed.error)
    # Only the task whose worker died is charged: its neighbours never see a failed attempt.
    assert all(o.ok and o.attempts == 1 for k, o in out.items() if k != "k2")
    assert sum(1 for o in seen if o.key == "k2") == 2
    assert len(seen) == 9  # 7 successes + 2 crashes, nothing duplicated


def test_worker_crashing_once_succeeds_on_retry(tmp_path: Path) -> None:
    """A worker that crashes on the first attempt only: the retry succeeds (attempts = 2)."""
    seen: list[TaskOutcome] = []
    tasks = faulty(_tasks(_square), crash={"k1", "k4"}, once_dir=tmp_path)
    out = run_tasks(tasks, executor="process", workers=2, on_outcome=seen.append)
    assert {k: o.value for k, o in out.items()} == {f"k{i}": i * i for i in range(6)}
    assert out["k1"].attempts == 2 and out["k4"].attempts == 2
    # Exactly the two crashes failed, each with the true reason; no innocent task was blamed.
    failed = sorted((o.key, o.attempts) for o in seen if not o.ok)
    assert failed == [("k1", 1), ("k4", 1)]
    assert all("killed by signal SIGSEGV" in str(o.error) for o in seen if not o.ok)
    assert all(o.attempts == 1 for k, o in out.items() if k not in ("k1", "k4"))


def _sleep_then_square(x: float) -> float:
    time.sleep(0.05)  # [s] keeps the neighbours of a hung task busy while it hangs
    return x * x


def test_hung_task_is_killed_at_the_timeout_and_retried_once() -> None:
    """A task that hangs is killed after `timeout`, twice, and marked final; others finish."""
    seen: list[TaskOutcome] = []
    tic = time.monotonic()
    out = run_tasks(
        faulty(_tasks(_sleep_then_square), hang={"k3"}),
        executor="process",
        workers=2,
        timeout=0.5,
        on_outcome=seen.append,
    )
    elapsed = time.monotonic() - tic
    assert {k: o.value for k, o in out.items() if o.ok} == {
        f"k{i}": i * i for i in range(6) if i != 3
    }
    hung = [o for o in seen if o.key == "k3"]
    assert [(o.attempts, o.final, o.error) for o in hung] == [
        (1, False, "timeout after 0.5 s"),
        (2, True, "timeout after 0.5 s"),
    ]
    assert all(o.attempts == 1 for k, o in out.items() if k != "k3")
    # Two 0.5 s time-outs in a row (the retry starts after the first); the hour-long sleep was cut
    # short. 10 s of slack covers worker start-up on a loaded 2-core machine.
    assert 1.0 <= elapsed < 11.0


def test_task_hanging_once_succeeds_on_retry(tmp_path: Path) -> None:
    """A task that hangs on its first attempt only: killed at the timeout, the retry succeeds."""
    seen: list[TaskOutcome] = []
    tasks = faulty(_tasks(_square, 3), hang={"k0"}, once_dir=tmp_path)
    out = run_tasks(tasks, executor="process", workers=1, timeout=0.3, on_outcome=seen.append)
    assert {k: o.value for k, o in out.items()} == {"k0": 0, "k1": 1, "k2": 4}
    assert out["k0"].attempts == 2
    assert [o.error for o in seen if not o.ok] == ["timeout after 0.3 s"]


def test_timeout_needs_a_worker_pool() -> None:
    """A timeout with serial execution, or a non-positive timeout, is refused with its value."""
    with pytest.raises(ParameterError, match="executor='serial'"):
        run_tasks(_tasks(_square, 1), executor="serial", timeout=1.0)
    with pytest.raises(ParameterError, match="got -1"):
        run_tasks(_tasks(_square, 1), executor="process", timeout=-1)


def test_worker_pool_is_reused_across_calls() -> None:
    """A WorkerPool keeps its worker process between run_tasks calls, and replaces a dead one."""
    with WorkerPool(1) as pool:
        pids = [
            run_tasks([Task(key="p", fn=os.getpid)], executor=pool)["p"].value for _ in range(3)
        ]
        assert len(set(pids)) == 1 and pids[0] != os.getpid()
        os.kill(pids[0], signal.SIGKILL)  # dies while idle: the next call gets a new worker
        time.sleep(0.1)
        again = run_tasks([Task(key="p", fn=os.getpid)], executor=pool)["p"]
        assert again.ok and again.attempts == 1 and again.value != pids[0]


def test_test_crash_is_inert_in_serial_mode() -> None:
    """The tests' injected crash never fires outside pool workers (serial runs are safe)."""
    out = run_tasks(faulty(_tasks(_square, 2), crash={"k0"}), executor="serial")
    assert out["k0"].value == 0 and out["k0"].attempts == 1


# ------------------------------------------------------- SIGKILL of the CLI sweep
_STARTS, _KNOTS, _SEED = 40, 15, 5
_PARETO_BETAS = "0.02:0.98:0.02"  # 49 warm-started points, ~30 ms each at 15 knots
_SCALES, _SCALE_STARTS = (1.0, 0.95, 0.9), 10  # 3 x (10 splines + straight line) = 33 starts


def _cli(out: Path, command: str = "multistart") -> list[str]:
    # --no-refine: what is under test is the sweep store; refining the reported plans after
    # the sweep (49 Pareto points, about 1 s each) is tested in tests/cli/test_cli_runs.py.
    common = ["--knots", str(_KNOTS), "--seed", str(_SEED), "--out", str(out), "--json", "--quiet"]
    common += ["--no-refine"]
    if command == "multistart":
        extra = ["--starts", str(_STARTS), "--workers", "2", "--straight"]
    elif command == "pareto":
        extra = ["--betas", _PARETO_BETAS, "--workers", "1"]
    else:
        scales = ",".join(str(x) for x in _SCALES)
        extra = ["--scales", scales, "--starts", str(_SCALE_STARTS), "--workers", "2"]
    return [sys.executable, "-m", "youbot_opt", command, *extra, *common]


def _check_store(out: Path, keys: list[str]) -> None:
    """Nothing lost or duplicated on disk: one record and one result per item, no temporaries."""
    items = out / "items"
    records = stored_records(out)  # the journal: one line per recorded attempt
    assert sorted(r.key for r in records) == sorted(keys)
    assert sorted(p.stem for p in items.glob("*/*.npz")) == sorted(keys)
    assert [p.name for p in items.rglob(".*")] == []
    # A kill is not a failure of the item: every item was computed once, successfully.
    for r in records:
        assert (r.state, r.attempts, r.reasons) == ("done", 1, ())


def _cli_solver():  # type: ignore[no-untyped-def]
    """The solver the CLI builds (trapezoidal, symbolic, IPOPT max_iter 3000)."""
    from youbot_opt.nlp.ipopt import IpoptOptions
    from youbot_opt.reproduction.study1 import study1_problem
    from youbot_opt.trajopt.solver import TrajOptSolver

    return TrajOptSolver(study1_problem(_KNOTS), "trapezoidal", IpoptOptions(max_iter=3000))


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc")
def test_sigkilled_cli_sweep_resumes_to_the_uninterrupted_result(tmp_path: Path) -> None:
    """4 SIGKILLs at seeded random points, then a final run: same items and f, none lost."""
    from youbot_opt.trajopt.multistart import run_multistart

    out = tmp_path / "sweep"
    resumed = kill_repeatedly(_cli(out), out, 4, seed=20240603, item_sleep=ITEM_SLEEP)
    assert 0 < resumed["resumed"] < _STARTS + 1  # the kills really left work to do

    # Independent reference: an uninterrupted in-process run with the same seeds.
    ref = run_multistart(
        _cli_solver(),
        _STARTS,
        beta=0.5,
        seed=_SEED,
        include_straight=True,
        sweep=SweepOptions(executor="serial"),
    )
    got = {s["key"]: s for s in resumed["starts"]}
    assert list(got) == [s.key for s in ref.starts]  # same set of items, in order, no duplicates
    for s in ref.starts:
        assert got[s.key]["seed"] == s.seed and got[s.key]["status"] == s.status
        # Same seeds, same deterministic IPOPT run: objectives agree to 1e-9.
        assert got[s.key]["objective"] == pytest.approx(s.objective, rel=0, abs=1e-9)
    _check_store(out, list(got))


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc")
def test_sigkilled_pareto_cli_resumes_to_the_uninterrupted_front(tmp_path: Path) -> None:
    """4 SIGKILLs of `youbot-opt pareto`, then a final run: the same 49 points, none lost."""
    from youbot_opt.cli.studies import parse_values
    from youbot_opt.trajopt.pareto import pareto_sweep

    out = tmp_path / "pareto"
    betas = parse_values(_PARETO_BETAS, "betas")
    resumed = kill_repeatedly(_cli(out, "pareto"), out, 4, seed=20240604, item_sleep=ITEM_SLEEP)
    assert 0 < resumed["resumed"] < len(betas)  # the kills really left work to do

    # Independent reference: the uninterrupted sweep in this process (no worker, no store).
    ref = pareto_sweep(_cli_solver(), betas, sweep=SweepOptions(executor="serial"))
    got = resumed["points"]
    assert [p["beta"] for p in got] == [p.beta for p in ref.points]  # none lost or repeated
    for g, r in zip(got, ref.points, strict=True):
        assert (g["status"], g["start"], g["iterations"]) == (r.status, r.start, r.iterations)
        assert g["dominated"] == r.dominated
        # Each point warm-starts from the previous one as read back from disk, which is
        # bit-exact, so the same deterministic IPOPT run: objectives agree to 1e-9.
        assert g["objective"] == pytest.approx(r.objective, rel=0, abs=1e-9)
    _check_store(out, [f"point_{k:03d}" for k in range(len(betas))])


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc")
def test_sigkilled_bounds_cli_resumes_to_the_uninterrupted_study(tmp_path: Path) -> None:
    """4 SIGKILLs of `youbot-opt bounds`, then a final run: the same 33 starts, none lost."""
    from youbot_opt.trajopt.bound_scaling import bound_scaling_study

    out = tmp_path / "bounds"
    resumed = kill_repeatedly(_cli(out, "bounds"), out, 4, seed=20240605, item_sleep=ITEM_SLEEP)

    ref = bound_scaling_study(
        _cli_solver(),
        _SCALES,
        n_starts=_SCALE_STARTS,
        seed=_SEED,
        sweep=SweepOptions(executor="serial"),
    )
    for g, r in zip(resumed["rows"], ref.rows, strict=True):
        assert g["bound_scale"] == r.bound_scale and g["success_rate"] == r.multistart.success_rate
        assert g["objective"] == pytest.approx(r.objective, rel=0, abs=1e-9)  # as above
        assert g["active_counts"] == r.active_counts()
    starts = [s for row in ref.rows for s in row.multistart.starts]
    _check_store(out, [s.key for s in starts])
    for s in starts:  # every start, not only each scale's best, equals the reference
        summary = stored_record(out, s.key)["summary"]  # type: ignore[index]
        assert (summary["seed"], summary["status"]) == (s.seed, s.status)
        assert summary["objective"] == pytest.approx(s.objective, rel=0, abs=1e-9)


# ------------------------------------------------- store + multistart, in process
@pytest.fixture(scope="module")
def small_solver():  # type: ignore[no-untyped-def]
    """A 15-knot study-1 solver, built once for the tests below."""
    from youbot_opt.reproduction.study1 import study1_problem
    from youbot_opt.trajopt.solver import TrajOptSolver

    return TrajOptSolver(study1_problem(_KNOTS))


def test_segfaulting_start_is_stored_failed_and_retried_once(
    small_solver,
    tmp_path: Path,
    faults,  # type: ignore[no-untyped-def]
) -> None:
    """A start whose worker segfaults is stored as failed (2 attempts, 2 reasons); the rest done."""
    from youbot_opt.trajopt.multistart import run_multistart

    faults(crash={"start_0001"})
    sweep = SweepOptions(executor="process", workers=2, out=tmp_path)
    res = run_multistart(small_solver, 4, seed=1, sweep=sweep)
    by_key = {s.key: s for s in res.starts}
    assert by_key["start_0001"].status == "error" and by_key["start_0001"].attempts == 2
    assert all(s.success for k, s in by_key.items() if k != "start_0001")
    record = stored_record(tmp_path, "start_0001")
    assert record is not None
    assert record["state"] == "failed" and record["attempts"] == 2
    assert len(record["reasons"]) == 2 and "crashed" in record["reasons"][0]
    # A rerun does not try it a third time: failures with attempts used up are final.
    faults()  # none any more
    again = run_multistart(
        small_solver, 4, seed=1, sweep=SweepOptions(executor="serial", out=tmp_path)
    )
    assert again.resumed == 4 and again.starts[1].status == "error"


def test_resume_refuses_corrupted_and_newer_files(small_solver, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """A torn result file is refused and recomputed; a newer-schema record stops the resume."""
    from youbot_opt.exceptions import ResultFileError, YoubotOptWarning
    from youbot_opt.trajopt.multistart import run_multistart

    first = run_multistart(
        small_solver, 2, seed=2, sweep=SweepOptions(executor="serial", out=tmp_path)
    )
    again = run_multistart(
        small_solver, 2, seed=2, sweep=SweepOptions(executor="serial", out=tmp_path)
    )
    assert again.resumed == 2
    assert [s.objective for s in again.starts] == [s.objective for s in first.starts]  # exact
    npz = next(tmp_path.glob("items/*/start_0000.npz"))
    npz.write_bytes(npz.read_bytes()[:-100])  # truncated, as by a disk fault
    with pytest.warns(YoubotOptWarning, match=r"start_0000.*does not match its checksum"):
        healed = run_multistart(
            small_solver, 2, seed=2, sweep=SweepOptions(executor="serial", out=tmp_path)
        )
    assert healed.resumed == 1  # the torn start was refused and recomputed, the other loaded
    assert [s.objective for s in healed.starts] == [s.objective for s in first.starts]
    manifest = tmp_path / "manifest.json"  # the store's schema is the manifest's
    manifest.write_text(json.dumps({**json.loads(manifest.read_text()), "schema_version": 99}))
    with pytest.raises(ResultFileError, match="newer"):
        run_multistart(small_solver, 2, seed=2, sweep=SweepOptions(executor="serial", out=tmp_path))


def test_a_foreign_item_is_refused_and_recomputed(small_solver, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """#16's scenario: an item copied from a beta=0.9 sweep into a beta=0.5 one is refused.

    Its files are the beta=0.9 start's, so without the binding the resume would
    report the beta=0.9 objective as the beta=0.5 result; refused, the start is
    recomputed and the result equals the uninterrupted beta=0.5 run exactly
    (same start, same deterministic solve in this process).
    """
    import shutil

    from youbot_opt.exceptions import YoubotOptWarning
    from youbot_opt.trajopt.multistart import run_multistart

    def sweep(beta: float, out: Path):  # type: ignore[no-untyped-def]
        return run_multistart(
            small_solver, 1, beta=beta, seed=5, sweep=SweepOptions(executor="serial", out=out)
        )

    other, mine = sweep(0.9, tmp_path / "b09"), sweep(0.5, tmp_path / "b05")
    assert other.starts[0].objective != mine.starts[0].objective
    # b05's records replaced by b09's journal, b09's result file copied over b05's
    shutil.rmtree(tmp_path / "b05" / "items" / "journal")
    shutil.copytree(tmp_path / "b09" / "items" / "journal", tmp_path / "b05" / "items" / "journal")
    payload = next((tmp_path / "b09").glob("items/*/start_0000.npz"))
    shutil.copyfile(payload, tmp_path / "b05" / payload.relative_to(tmp_path / "b09"))
    with pytest.warns(YoubotOptWarning, match=r"'start_0000'.*written by another sweep"):
        again = sweep(0.5, tmp_path / "b05")
    assert again.resumed == 0
    assert again.starts[0].objective == mine.starts[0].objective
    # The recomputed item is bound again: the next resume loads it without a word.
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error", YoubotOptWarning)
        assert sweep(0.5, tmp_path / "b05").resumed == 1
