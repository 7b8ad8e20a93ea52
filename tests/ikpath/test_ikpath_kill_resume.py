"""IK multistarts that survive: resume from disk, crashed workers retried, SIGKILLed CLI runs.

The crash tests wrap chosen tasks (the ``faults`` fixture, ``tests/_faults.py``):
those keys SIGSEGV their pool worker; the package has no test hooks.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
from test_ikpath_solvers import LA, LB, TARGETS_2

from _sigkill import ITEM_SLEEP, kill_repeatedly
from youbot_opt._files import read_json_lines
from youbot_opt.exceptions import ParameterError, ResultFileError, YoubotOptWarning
from youbot_opt.ikpath import sweep as sweep_mod
from youbot_opt.ikpath.examples import example_problem
from youbot_opt.ikpath.io import load_result
from youbot_opt.ikpath.multistart import run_multistart
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.nlp.status import SolveStatus
from youbot_opt.robot.planar import PlanarChain
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.sweeps.store import stored_record, stored_records


def _starts(doc: dict) -> list[dict]:
    """The per-start rows of a run: its ``starts.jsonl``, named in the summary."""
    return list(read_json_lines(Path(doc["output_folder"]) / doc["starts_file"]))


N = 6  # starts of the in-process tests


@pytest.fixture(scope="module")
def two_link():
    return CyclicIKProblem(robot=PlanarChain(lengths=[LA, LB]), targets=TARGETS_2)


@pytest.fixture(scope="module")
def reference(two_link):
    """An uninterrupted serial run without output folder: the independent reference."""
    return run_multistart(two_link, n_starts=N, seed=4, sweep=SweepOptions(workers=1))


@pytest.fixture
def solver_calls(monkeypatch):
    """Count the AL solves made in this process (serial runs)."""
    calls: list[int] = []
    real = sweep_mod.solve_augmented_lagrangian

    def counting(problem, x0, options):
        calls.append(1)
        return real(problem, x0, options)

    monkeypatch.setattr(sweep_mod, "solve_augmented_lagrangian", counting)
    return calls


def _record(out: Path, key: str) -> dict:
    rec = stored_record(out, key)  # the latest journal line of the key
    assert rec is not None
    return rec


def _forget(out: Path, keys: set[str]) -> None:
    """Drop the journal lines of ``keys``, as if the run was killed before recording them."""
    for path in (out / "items" / "journal").glob("*.jsonl"):
        lines = path.read_bytes().splitlines(keepends=True)
        kept = [ln for ln in lines if json.loads(ln.split(b" ", 1)[1])["key"] not in keys]
        path.write_bytes(b"".join(kept))


def _same_results(got, ref) -> None:
    """Same starts and, start by start, the same status and E to 1e-12 and q to 1e-12."""
    assert len(got.results) == len(ref.results)
    for a, b in zip(got.results, ref.results, strict=True):
        # Same start, same deterministic solver; a loaded result is recomputed from its
        # configurations, which JSON round-trips exactly: only rounding can differ.
        assert a.status is b.status
        assert a.objective == pytest.approx(b.objective, rel=0, abs=1e-12)
        np.testing.assert_allclose(a.configurations, b.configurations, rtol=0, atol=1e-12)


def test_resume_loads_finished_starts_instead_of_solving(
    two_link, reference, solver_calls, tmp_path
):
    """A rerun solves only the starts without a record (orphan payloads too), then nothing."""
    first = run_multistart(
        two_link, n_starts=N, seed=4, sweep=SweepOptions(workers=1, out=tmp_path)
    )
    assert len(solver_calls) == N and first.resumed == 0 and first.output == tmp_path
    _same_results(first, reference)
    items = tmp_path / "items"
    assert sorted(p.name for p in items.glob("*/*.ikpath")) == [
        f"start_{i:04d}.ikpath" for i in range(N)
    ]
    assert sorted(r.key for r in stored_records(tmp_path)) == [f"start_{i:04d}" for i in range(N)]
    # As if killed: start 2 before anything was written, start 4 between payload and record.
    _forget(tmp_path, {"start_0002", "start_0004"})
    next(items.glob("*/start_0002.ikpath")).unlink()
    solver_calls.clear()
    progress: list[tuple[int, int, float]] = []
    second = run_multistart(
        two_link,
        n_starts=N,
        seed=4,
        sweep=SweepOptions(workers=1, out=tmp_path, progress=lambda *a: progress.append(a)),
    )
    assert len(solver_calls) == 2 and second.resumed == N - 2
    assert [p[0] for p in progress] == [N - 2, N - 1, N] and all(p[1] == N for p in progress)
    _same_results(second, reference)
    solver_calls.clear()
    third = run_multistart(
        two_link, n_starts=N, seed=4, sweep=SweepOptions(workers=1, out=tmp_path)
    )
    assert solver_calls == [] and third.resumed == N and third.attempts == (1,) * N
    _same_results(third, reference)
    assert [m.count for m in third.minima] == [m.count for m in reference.minima]


def test_resume_refuses_other_parameters(two_link, tmp_path):
    """An output folder of another multistart (seed, method) is refused, naming the difference."""
    run_multistart(two_link, n_starts=2, seed=4, sweep=SweepOptions(workers=1, out=tmp_path))
    with pytest.raises(ParameterError, match=r"seed: stored 4, now 5"):
        run_multistart(two_link, n_starts=2, seed=5, sweep=SweepOptions(workers=1, out=tmp_path))
    with pytest.raises(ParameterError, match=r"method: stored 'al', now 'ipopt'"):
        run_multistart(
            two_link,
            method="ipopt",
            n_starts=2,
            seed=4,
            sweep=SweepOptions(workers=1, out=tmp_path),
        )


@pytest.mark.parametrize("method", ["al", "ipopt"])
def test_worker_crashing_once_is_retried_and_succeeds(two_link, method, faults, tmp_path):
    """One segfault: only that start is charged (2 attempts), every start succeeds, E as serial."""
    faults(crash={"start_0002"}, once_dir=tmp_path)
    out = tmp_path / "out"
    res = run_multistart(
        two_link, method=method, n_starts=N, seed=4, sweep=SweepOptions(workers=2, out=out)
    )
    ref = run_multistart(two_link, method=method, n_starts=N, seed=4, sweep=SweepOptions(workers=1))
    assert (tmp_path / "crashed-start_0002").exists()  # the hook really fired
    assert res.attempts == (1, 1, 2, 1, 1, 1)
    assert res.n_converged == N
    _same_results(res, ref)
    rec = _record(out, "start_0002")
    assert rec["state"] == "done" and rec["attempts"] == 2
    assert len(rec["reasons"]) == 1 and "worker process crashed" in rec["reasons"][0]


def test_worker_crashing_always_is_recorded_failed_after_two_attempts(
    two_link, reference, faults, tmp_path, solver_calls
):
    """A start that always segfaults: failed after 2 attempts with reasons; a rerun keeps it."""
    faults(crash={"start_0001"})
    res = run_multistart(two_link, n_starts=N, seed=4, sweep=SweepOptions(workers=2, out=tmp_path))
    crashed = res.results[1]
    assert crashed.status is SolveStatus.CRASHED and "worker process crashed" in crashed.message
    assert res.attempts == (1, 2, 1, 1, 1, 1)
    assert all(r.success for i, r in enumerate(res.results) if i != 1)
    rec = _record(tmp_path, "start_0001")
    assert rec["state"] == "failed" and rec["attempts"] == 2 and rec["payload"] is None
    assert len(rec["reasons"]) == 2 and all("worker process crashed" in r for r in rec["reasons"])
    assert not list(tmp_path.glob("items/*/start_0001.ikpath"))
    # Out of attempts: a rerun loads everything (no third attempt) and reports the reason.
    faults()  # none any more
    again = run_multistart(
        two_link, n_starts=N, seed=4, sweep=SweepOptions(workers=1, out=tmp_path)
    )
    assert solver_calls == [] and again.resumed == N
    assert again.results[1].status is SolveStatus.CRASHED
    assert again.results[1].message == rec["reasons"][-1]
    for i in (0, 2, 3, 4, 5):
        assert again.results[i].objective == pytest.approx(
            reference.results[i].objective, rel=0, abs=1e-12
        )  # rounding only: same start, same solver


def test_corrupted_or_newer_files_raise_result_file_error(two_link, tmp_path):
    """Torn or edited results and torn journal lines are refused and recomputed; newer raise."""
    first = run_multistart(
        two_link, n_starts=2, seed=4, sweep=SweepOptions(workers=1, out=tmp_path)
    )
    items = tmp_path / "items"

    def rerun():
        return run_multistart(
            two_link, n_starts=2, seed=4, sweep=SweepOptions(workers=1, out=tmp_path)
        )

    payload = next(items.glob("*/start_0000.ikpath"))
    good = payload.read_bytes()
    doc = json.loads(good)
    for bad in (
        good[: len(good) // 2],  # torn, as by a disk fault
        json.dumps({**doc, "schema_version": doc["schema_version"] + 1}).encode(),
        json.dumps({**doc, "sha256": "0" * 64}).encode(),
    ):
        payload.write_bytes(bad)
        with pytest.warns(YoubotOptWarning, match=r"start_0000.*does not match its checksum"):
            again = rerun()
        assert again.resumed == 1  # start_0000 recomputed, start_0001 loaded
        assert [r.objective for r in again.results] == [r.objective for r in first.results]
    manifest = tmp_path / "manifest.json"  # the store's schema is its manifest's
    good_manifest = manifest.read_text()
    manifest.write_text(json.dumps({**json.loads(good_manifest), "schema_version": 99}))
    with pytest.raises(ResultFileError, match="newer"):
        rerun()
    manifest.write_text(good_manifest)
    lines = b"".join(p.read_bytes() for p in (items / "journal").glob("*.jsonl")).splitlines()
    line = [ln for ln in lines if b'"key":"start_0001"' in ln][-1]
    _forget(tmp_path, {"start_0001"})
    with next((items / "journal").glob("*.jsonl")).open("ab") as fh:
        fh.write(line[:-20])  # its line torn, as by a power cut mid-append
    with pytest.warns(YoubotOptWarning, match="1 torn or corrupted journal line"):
        assert rerun().resumed == 1  # its start is recomputed, never half-read
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error", YoubotOptWarning)
        assert rerun().resumed == 2  # healed files resume without complaint


# ------------------------------------------------------- SIGKILL of the CLI sweep
_STARTS, _SEED = 48, 7


def _cli(out: Path) -> list[str]:
    return [
        sys.executable,
        "-m",
        "youbot_opt",
        "ikpath",
        "--example",
        "A",
        "--starts",
        str(_STARTS),
        "--seed",
        str(_SEED),
        "--workers",
        "2",
        "--out",
        str(out),
        "--json",
        "--no-replay",
        "--no-progress",
    ]


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc")
def test_sigkilled_cli_multistart_resumes_to_the_uninterrupted_result(tmp_path):
    """4 SIGKILLs at seeded random points, then a final run: same starts and E, none lost."""
    out = tmp_path / "run"
    doc = kill_repeatedly(_cli(out), out, 4, seed=20240611, item_sleep=ITEM_SLEEP)
    assert 0 < doc["resumed"] < _STARTS

    # Independent reference: one uninterrupted in-process run of the same multistart.
    ref = run_multistart(
        example_problem("A"), n_starts=_STARTS, seed=_SEED, sweep=SweepOptions(workers=1)
    )
    got = _starts(doc)
    assert [o["index"] for o in got] == list(range(_STARTS))  # every start once, in order
    for o, r in zip(got, ref.results, strict=True):
        assert o["status"] == r.status.value and o["attempts"] == 1  # a kill is no attempt
        # Same start, same deterministic solver: only rounding may differ.
        assert o["E"] == pytest.approx(r.objective, rel=0, abs=1e-12)
    assert doc["E"] == pytest.approx(ref.best.objective, rel=0, abs=1e-12)
    assert [m["count"] for m in doc["minima"]] == [m.count for m in ref.minima]
    # On disk: exactly one record and one result per start, no temporaries left.
    items = out / "items"
    keys = [f"start_{i:04d}" for i in range(_STARTS)]
    assert sorted(r.key for r in stored_records(out)) == keys  # one journal line per start
    assert sorted(p.stem for p in items.glob("*/*.ikpath")) == keys
    assert [p.name for p in items.rglob(".*")] == []
    for key, r in zip(keys, ref.results, strict=True):
        saved = load_result(next(items.glob(f"*/{key}.ikpath")))
        assert saved.objective == pytest.approx(r.objective, rel=0, abs=1e-12)
