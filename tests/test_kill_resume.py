"""Sweeps that survive: crashing workers, failing items, and SIGKILL of the whole CLI sweep.

The crash tests use the private hook of :mod:`youbot_opt.parallel`
(``YOUBOT_OPT_TEST_CRASH``): listed keys SIGSEGV their pool worker.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest

from youbot_opt.parallel import Task, TaskOutcome, run_tasks


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


def test_segfaulting_worker_is_recorded_failed_and_retried_once(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A task whose worker always segfaults fails after 2 attempts; the pool is rebuilt."""
    monkeypatch.setenv("YOUBOT_OPT_TEST_CRASH", "k2")
    seen: list[TaskOutcome] = []
    out = run_tasks(_tasks(_square, 8), executor="process", workers=2, on_outcome=seen.append)
    assert {k: o.value for k, o in out.items() if o.ok} == {
        f"k{i}": i * i for i in range(8) if i != 2
    }
    crashed = out["k2"]
    assert not crashed.ok and crashed.final and crashed.attempts == 2
    assert "worker process crashed" in str(crashed.error)
    # Innocent tasks that shared the broken pool may have one failed attempt, never a final failure.
    assert all(o.ok for k, o in out.items() if k != "k2")
    assert sum(1 for o in seen if o.key == "k2") == 2


def test_worker_crashing_once_succeeds_on_retry(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """A worker that crashes on the first attempt only: the retry succeeds (attempts = 2)."""
    monkeypatch.setenv("YOUBOT_OPT_TEST_CRASH", "k1,k4")
    monkeypatch.setenv("YOUBOT_OPT_TEST_CRASH_ONCE_DIR", str(tmp_path))
    out = run_tasks(_tasks(_square), executor="process", workers=2)
    assert {k: o.value for k, o in out.items()} == {f"k{i}": i * i for i in range(6)}
    assert out["k1"].attempts == 2 and out["k4"].attempts == 2


def test_crash_hook_is_inert_in_serial_mode(monkeypatch: pytest.MonkeyPatch) -> None:
    """The private crash hook never fires outside pool workers (serial runs are safe)."""
    monkeypatch.setenv("YOUBOT_OPT_TEST_CRASH", "k0")
    out = run_tasks(_tasks(_square, 2), executor="serial")
    assert out["k0"].value == 0 and out["k0"].attempts == 1


# ------------------------------------------------------- SIGKILL of the CLI sweep
_STARTS, _KNOTS, _SEED = 24, 15, 5


def _cli(out: Path) -> list[str]:
    return [
        sys.executable,
        "-m",
        "youbot_opt",
        "multistart",
        "--starts",
        str(_STARTS),
        "--knots",
        str(_KNOTS),
        "--seed",
        str(_SEED),
        "--workers",
        "2",
        "--straight",
        "--out",
        str(out),
        "--json",
        "--quiet",
    ]


def _records(out: Path) -> int:
    items = out / "items"
    return (
        len([p for p in items.glob("*.json") if not p.name.startswith(".")])
        if items.is_dir()
        else 0
    )


def _session_pids(sid: int) -> list[int]:
    """Live processes of session ``sid`` (the CLI and its pool workers)."""
    pids = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[3]) == sid and fields[0] != "Z":
            pids.append(int(stat.parent.name))
    return pids


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc")
def test_sigkilled_cli_sweep_resumes_to_the_uninterrupted_result(tmp_path: Path) -> None:
    """4 SIGKILLs at seeded random points, then a final run: same items and f, none lost."""
    from youbot_opt.multistart import run_multistart
    from youbot_opt.problem import study1_problem
    from youbot_opt.solve import TrajOptSolver

    rng = np.random.default_rng(20240603)
    out = tmp_path / "sweep"
    kills = 0
    for _ in range(4):
        before = _records(out)
        target = before + int(rng.integers(1, 4))  # kill after 1-3 more finished items ...
        delay = float(rng.uniform(0.0, 0.03))  # ... plus 0-30 ms, to land anywhere in a write
        proc = subprocess.Popen(
            _cli(out), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True
        )
        try:
            deadline = time.monotonic() + 120.0
            while _records(out) < target and proc.poll() is None and time.monotonic() < deadline:
                time.sleep(0.005)
            time.sleep(delay)
            if proc.poll() is None:
                os.kill(proc.pid, signal.SIGKILL)
                kills += 1
            proc.wait(timeout=30)
            # The orphaned pool workers notice the dead parent and exit by themselves.
            deadline = time.monotonic() + 5.0
            while _session_pids(proc.pid) and time.monotonic() < deadline:
                time.sleep(0.05)
            assert _session_pids(proc.pid) == [], "pool workers outlived the killed sweep"
        finally:
            try:
                os.killpg(proc.pid, signal.SIGKILL)  # only our own session; normally empty by now
            except ProcessLookupError:
                pass
    assert kills == 4, "the sweep finished before all kills; make it longer"
    assert _records(out) < _STARTS + 1  # the kills really left work to do

    done = subprocess.run(_cli(out), capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    resumed = json.loads(done.stdout)
    assert 0 < resumed["resumed"] < _STARTS + 1

    # Independent reference: an uninterrupted in-process run with the same seeds.
    ref = run_multistart(
        TrajOptSolver(study1_problem(_KNOTS)),
        _STARTS,
        beta=0.5,
        seed=_SEED,
        include_straight=True,
        executor="serial",
    )
    got = {s["key"]: s for s in resumed["starts"]}
    assert list(got) == [s.key for s in ref.starts]  # same set of items, in order, no duplicates
    for s in ref.starts:
        assert got[s.key]["seed"] == s.seed and got[s.key]["status"] == s.status
        # Same seeds, same deterministic IPOPT run: objectives agree to 1e-9.
        assert got[s.key]["objective"] == pytest.approx(s.objective, rel=0, abs=1e-9)
    # Nothing lost or duplicated on disk: one record and one result per item, no temporaries.
    items = out / "items"
    assert sorted(p.stem for p in items.glob("*.json")) == sorted(got)
    assert sorted(p.stem for p in items.glob("*.npz")) == sorted(got)
    assert [p.name for p in items.iterdir() if p.name.startswith(".")] == []
    assert all(json.loads((items / f"{k}.json").read_text())["attempts"] == 1 for k in got)


# ------------------------------------------------- store + multistart, in process
@pytest.fixture(scope="module")
def small_solver():  # type: ignore[no-untyped-def]
    """A 15-knot study-1 solver, built once for the tests below."""
    from youbot_opt.problem import study1_problem
    from youbot_opt.solve import TrajOptSolver

    return TrajOptSolver(study1_problem(_KNOTS))


def test_segfaulting_start_is_stored_failed_and_retried_once(
    small_solver,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,  # type: ignore[no-untyped-def]
) -> None:
    """A start whose worker segfaults is stored as failed (2 attempts, 2 reasons); the rest done."""
    from youbot_opt.multistart import run_multistart

    monkeypatch.setenv("YOUBOT_OPT_TEST_CRASH", "start_0001")
    res = run_multistart(small_solver, 4, seed=1, executor="process", workers=2, out=tmp_path)
    by_key = {s.key: s for s in res.starts}
    assert by_key["start_0001"].status == "error" and by_key["start_0001"].attempts == 2
    assert all(s.success for k, s in by_key.items() if k != "start_0001")
    record = json.loads((tmp_path / "items" / "start_0001.json").read_text())
    assert record["state"] == "failed" and record["attempts"] == 2
    assert len(record["reasons"]) == 2 and "crashed" in record["reasons"][0]
    # A rerun does not try it a third time: failures with attempts used up are final.
    monkeypatch.delenv("YOUBOT_OPT_TEST_CRASH")
    again = run_multistart(small_solver, 4, seed=1, executor="serial", out=tmp_path)
    assert again.resumed == 4 and again.starts[1].status == "error"


def test_resume_refuses_corrupted_and_newer_files(small_solver, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """A corrupted result file or a newer-schema record in the output stops the resume."""
    from youbot_opt.exceptions import ResultFileError
    from youbot_opt.multistart import run_multistart

    first = run_multistart(small_solver, 2, seed=2, executor="serial", out=tmp_path)
    again = run_multistart(small_solver, 2, seed=2, executor="serial", out=tmp_path)
    assert again.resumed == 2
    assert [s.objective for s in again.starts] == [s.objective for s in first.starts]  # exact
    npz = tmp_path / "items" / "start_0000.npz"
    npz.write_bytes(npz.read_bytes()[:-100])  # truncated, as by a disk fault
    with pytest.raises(ResultFileError, match="start_0000"):
        run_multistart(small_solver, 2, seed=2, executor="serial", out=tmp_path)
    rec = tmp_path / "items" / "start_0001.json"
    rec.write_text(json.dumps({**json.loads(rec.read_text()), "schema_version": 99}))
    npz.unlink()
    (tmp_path / "items" / "start_0000.json").unlink()  # start_0000 will simply be recomputed
    with pytest.raises(ResultFileError, match="newer"):
        run_multistart(small_solver, 2, seed=2, executor="serial", out=tmp_path)
