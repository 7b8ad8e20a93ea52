"""IK multistarts with keep_results=False (#15): the lean run equals the full one.

Reference: the same sweep (same problem, seed, starts, executor) run with
``keep_results=True``, which holds every result in memory. Every comparison is
exact (``==`` on floats, ``array_equal`` on configurations): both runs solve the
same starts with the same deterministic solver, and the lean run reads its
figures back from JSON, which round-trips every float exactly (``repr``).
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
from youbot_opt.cli import main
from youbot_opt.exceptions import ParameterError
from youbot_opt.ikpath.methods.al import ALOptions
from youbot_opt.ikpath.multistart import MultistartResult, run_multistart
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.starts import PlanarStarts, Starts3D, make_starts, make_starts_3d
from youbot_opt.ikpath.stored import StoredResults
from youbot_opt.nlp.status import SolveStatus
from youbot_opt.robot.planar import PlanarChain
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.sweeps.store import stored_records


def _starts(doc: dict) -> list[dict]:
    """The per-start rows of a run: its ``starts.jsonl``, named in the summary."""
    return list(read_json_lines(Path(doc["output_folder"]) / doc["starts_file"]))


N = 24  # planar starts: 14-ish distinct minima, several found more than once


@pytest.fixture(scope="module")
def two_link() -> CyclicIKProblem:
    return CyclicIKProblem(robot=PlanarChain(lengths=[LA, LB]), targets=TARGETS_2)


def _planar(problem, out, *, keep, workers=1, progress=None, **kw) -> MultistartResult:  # type: ignore[no-untyped-def]
    opts = SweepOptions(workers=workers, out=out, keep_results=keep, progress=progress)
    return run_multistart(problem, n_starts=kw.pop("n_starts", N), seed=4, sweep=opts, **kw)


def _minima(minima) -> list[tuple[float, int, tuple[int, ...]]]:  # type: ignore[no-untyped-def]
    return [(m.objective, m.count, tuple(m.start_indices)) for m in minima]


def _assert_same(lean: MultistartResult, full: MultistartResult) -> None:
    """The lean run answers every accessor as the full run does, holding only its minima."""
    assert isinstance(lean.results, StoredResults) and isinstance(full.results, tuple)
    assert lean.results.held == len(lean.minima)
    assert lean.best.objective == full.best.objective  # to the bit
    assert lean.best_index == full.best_index
    assert _minima(lean.minima) == _minima(full.minima)
    assert lean.status_counts() == full.status_counts()
    assert (lean.n_starts, lean.n_converged, lean.best_count) == (
        full.n_starts,
        full.n_converged,
        full.best_count,
    )
    assert list(lean.attempts) == list(full.attempts)
    for i, r in enumerate(full.results):  # loaded from the folder one at a time
        got = lean.results[i]
        assert (got.status, got.objective, got.message) == (r.status, r.objective, r.message)
        np.testing.assert_array_equal(got.configurations, r.configurations)


@pytest.mark.parametrize("workers", [1, 2])
def test_planar_lean_run_equals_the_full_run(two_link, tmp_path, workers, faults):
    """Serial, and a pool of 2 whose start 5 always crashes its worker (failed in both runs)."""
    if workers == 2:
        faults(crash={"start_0005"})
    full = _planar(two_link, tmp_path / "full", keep=True, workers=workers)
    lean = _planar(two_link, tmp_path / "lean", keep=False, workers=workers)
    assert len(full.minima) > 2 and max(m.count for m in full.minima) > 1  # a real clustering
    _assert_same(lean, full)
    if workers == 2:
        assert lean.status_counts()["crashed"] == 1
        crashed = lean.results[5]  # rebuilt from the journal: its start and the last reason
        assert crashed.status is SolveStatus.CRASHED and "worker process crashed" in crashed.message
    # Other tolerances: re-clustered from the folder, equal to the full run's re-clustering.
    # Coarser ones merge distinct minima (14 -> 11 here); finer ones may split one.
    coarse = _minima(full.distinct_optima(obj_tol=0.1, dist_tol=3.0))
    assert len(coarse) < len(full.minima)
    assert _minima(lean.distinct_optima(obj_tol=0.1, dist_tol=3.0)) == coarse
    fine = _minima(full.distinct_optima(obj_tol=1e-12, dist_tol=1e-9))
    assert _minima(lean.distinct_optima(obj_tol=1e-12, dist_tol=1e-9)) == fine
    assert lean.distinct_optima() is lean.minima  # the run's own tolerances
    for bad in ({"obj_tol": 0.0}, {"dist_tol": -1.0}, {"dist_tol": float("nan")}):
        with pytest.raises(ParameterError, match=next(iter(bad))):  # refused before any load
            lean.distinct_optima(**bad)


def test_planar_nothing_succeeded_best_is_the_start_closest_to_the_targets(two_link, tmp_path):
    """One outer AL iteration meets no target: best is the smallest residual, as in the full run."""
    opts = ALOptions(max_outer_iterations=1, newton_final=False, retry_least_squares=False)
    full = _planar(two_link, tmp_path / "full", keep=True, options=opts, n_starts=10)
    lean = _planar(two_link, tmp_path / "lean", keep=False, options=opts, n_starts=10)
    assert full.n_converged == 0 and full.minima == ()  # the case under test
    _assert_same(lean, full)
    assert lean.best.max_position_error() == full.best.max_position_error()


@pytest.mark.parametrize("workers", [1, 2])
def test_spatial_lean_run_equals_the_full_run(ur5_reachable, tmp_path, workers):
    def run(out, keep) -> MultistartResult:  # type: ignore[no-untyped-def]
        sweep = SweepOptions(out=out, keep_results=keep)
        return run_multistart(ur5_reachable, n_starts=8, seed=1, workers=workers, sweep=sweep)

    full, lean = run(tmp_path / "full", True), run(tmp_path / "lean", False)
    assert isinstance(lean.results, StoredResults) and lean.results.held == len(lean.minima)
    assert lean.best.objective == full.best.objective and lean.best_index == full.best_index
    assert _minima(lean.minima) == _minima(full.minima)
    assert any(m.count > 1 for m in full.minima)  # a real clustering
    assert lean.status_counts() == full.status_counts() and lean.n_converged == full.n_converged
    assert list(lean.attempts) == list(full.attempts)
    for i, r in enumerate(full.results):
        np.testing.assert_array_equal(lean.results[i].configurations, r.configurations)


def test_an_interrupted_lean_sweep_resumes_to_the_full_result(two_link, tmp_path):
    """The driver dies after 9 starts (an exception in progress); the rerun completes.

    Then every payload but the kept minima's is deleted: a resume reads only the
    journal and still answers as the full run.
    """
    full = _planar(two_link, tmp_path / "full", keep=True)
    out = tmp_path / "lean"

    class Died(Exception):
        pass

    def die(done: int, total: int, best: float) -> None:
        if done == 9:
            raise Died

    with pytest.raises(Died):
        _planar(two_link, out, keep=False, progress=die)
    lean = _planar(two_link, out, keep=False)
    assert lean.resumed == 9  # the 9th start was recorded before progress heard of it
    _assert_same(lean, full)
    kept = {f"start_{lean.results.index(m.result):04d}" for m in lean.minima}
    for rec in stored_records(out):
        if rec.state == "done" and rec.key not in kept:
            (out / "items" / str(rec.payload)).unlink()
    again = _planar(two_link, out, keep=False)
    assert again.resumed == N
    assert _minima(again.minima) == _minima(full.minima)
    assert again.best.objective == full.best.objective
    assert again.status_counts() == full.status_counts()


def test_lazy_starts_equal_the_drawn_arrays(two_link, ur5_reachable, monkeypatch):
    """Per-index planar starts and checkpointed spatial starts, in any order of access."""
    planar = make_starts(two_link, 7, 3)
    np.testing.assert_array_equal(np.array(list(PlanarStarts(two_link, 7, 3))), planar)
    monkeypatch.setattr("youbot_opt.ikpath.starts.CHECKPOINT", 2)
    drawn = make_starts_3d(ur5_reachable, 9, 5, kind="mixed")
    lazy = Starts3D(ur5_reachable, 9, 5, kind="mixed")
    for k in (3, 8, 0, 1, 6, 2, 7, 5, 4, -1):  # backwards jumps restart from a checkpoint
        np.testing.assert_array_equal(lazy[k], drawn[k])


def test_cli_no_keep_results_runs_end_to_end(tmp_path, capsys):
    """``--no-keep-results`` writes the same summary as ``--keep-results``, but for timings."""
    docs = []
    for flag in ("--keep-results", "--no-keep-results"):
        argv = ["ikpath", "--lengths", str(LA), str(LB), "--starts", "10", "--seed", "4"]
        for x, y in TARGETS_2:
            argv += ["--target", str(x), str(y)]
        argv += [flag, "--out", str(tmp_path / flag), "--json", "--no-replay", "--no-progress"]
        assert main(argv) == 0
        docs.append(json.loads(capsys.readouterr().out))
    full, lean = docs
    for key in ("E", "configurations", "start_index", "n_success", "status_counts", "minima"):
        assert lean[key] == full[key], key
    assert _starts(lean) == _starts(full)
    assert (tmp_path / "--no-keep-results" / "ikpath_minima.png").is_file()


def test_start_rows_of_a_lean_run_are_streamed_from_the_journal(two_link, tmp_path):
    """``write_starts`` of stored results reads the journal: the same starts.jsonl as held ones."""
    from youbot_opt.cli.ikpath_text import write_starts

    lean = _planar(two_link, tmp_path / "lean", keep=False)
    full = _planar(two_link, tmp_path / "full", keep=True)
    streamed = write_starts(tmp_path / "lean", lean.results, lean.attempts)
    held = write_starts(tmp_path / "full", full.results, full.attempts)
    rows = list(read_json_lines(streamed.path))
    assert len(rows) == N and [r["index"] for r in rows] == list(range(N))
    assert rows == list(read_json_lines(held.path))
    assert streamed.retried == held.retried and streamed.crashed == held.crashed


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc")
def test_sigkilled_lean_cli_multistart_resumes_to_the_full_result(two_link, tmp_path):
    """3 SIGKILLs of ``ikpath --no-keep-results`` at seeded random points, then a final run.

    Reference: the same 60 starts run in process with ``keep_results=True``.
    """
    out = tmp_path / "run"
    cmd = [sys.executable, "-m", "youbot_opt", "ikpath", "--lengths", str(LA), str(LB)]
    for x, y in TARGETS_2:
        cmd += ["--target", str(x), str(y)]
    cmd += ["--starts", "60", "--seed", "4", "--workers", "2", "--no-keep-results"]
    cmd += ["--out", str(out), "--json", "--no-replay", "--no-progress"]
    doc = kill_repeatedly(cmd, out, 3, seed=20261124, item_sleep=ITEM_SLEEP)
    assert 0 < doc["resumed"] < 60
    full = _planar(two_link, tmp_path / "full", keep=True, workers=2, n_starts=60)
    assert doc["E"] == full.best.objective and doc["start_index"] == full.best_index
    assert doc["status_counts"] == full.status_counts()
    assert [m["count"] for m in doc["minima"]] == [m.count for m in full.minima]
    got = _starts(doc)
    assert [o["index"] for o in got] == list(range(60))  # every start once, in order
    for o, r in zip(got, full.results, strict=True):
        assert (o["status"], o["E"], o["attempts"]) == (r.status.value, r.objective, 1)
    assert len({r.key for r in stored_records(out)}) == 60  # one record per start
