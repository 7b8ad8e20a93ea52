"""The refined plans of a study are stored in its run folder and reused, never trusted (#27).

A small pareto (2 betas, 15 knots) is refined once into a folder; each test
copies that folder, reruns the command into it and counts the calls of
``refine`` (the study's refinement loop): a rerun reuses the stored plans bit
for bit, a tampered stored plan (torques edited, every checksum recomputed
by the library's own writers) is refined again, and so is every plan when the
budget (``--max-rounds``) changes.
"""

from __future__ import annotations

import dataclasses
import json
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

import youbot_opt.cli.refinement as refinement
from youbot_opt.cli import main
from youbot_opt.sweeps.store import SweepStore
from youbot_opt.trajopt.io import load_refined, load_result, save_result
from youbot_opt.trajopt.refine import Refined
from youbot_opt.trajopt.sweep_store import check_refined

ARGV = ["pareto", "--betas", "0.3,0.7", "--knots", "15", "--workers", "0", "--quiet", "--json"]


def _counting(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """Count the calls of ``refine`` made by the study's refinement (one list entry each)."""
    calls: list[int] = []
    real = refinement.refine

    def counted(*args: object, **kwargs: object) -> Refined:
        calls.append(1)
        return real(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(refinement, "refine", counted)
    return calls


def _plans(summary: dict) -> list[tuple[str, bool, int, float, float, int]]:
    """Label, verdict, knots, f, T and rounds of each refined plan, as the summary says."""
    return [
        (
            r["label"],
            r["certified"],
            r["rounds"][-1]["n_knots"],
            r["rounds"][-1]["objective"],
            r["rounds"][-1]["duration_s"],
            len(r["rounds"]),
        )
        for r in summary["refinement"]
    ]


@pytest.fixture(scope="module")
def first_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    """The study refined once into a folder: the folder and its summary."""
    folder = tmp_path_factory.mktemp("refined") / "run"
    with pytest.MonkeyPatch.context() as mp:
        calls = _counting(mp)
        assert main([*ARGV, "--out", str(folder)]) == 0
    assert len(calls) == 2  # both points are non-dominated: each refined once
    summary = json.loads((folder / "summary.json").read_text())
    assert [r["stored"] for r in summary["refinement"]] == [False, False]
    assert "refined/" in summary["files"]
    return folder, summary


@pytest.fixture
def rerun(
    first_run: tuple[Path, dict],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> Callable[..., tuple[int, dict, str]]:
    """Copy the first run's folder; return a rerun into it: (refine calls, summary, stderr)."""
    folder = tmp_path / "run"
    shutil.copytree(first_run[0], folder)
    calls = _counting(monkeypatch)

    def run(*extra: str) -> tuple[int, dict, str]:
        before = len(calls)
        capsys.readouterr()
        assert main([*ARGV, *extra, "--out", str(folder)]) == 0
        captured = capsys.readouterr()
        return len(calls) - before, json.loads(captured.out), captured.err

    run.folder = folder  # type: ignore[attr-defined]
    return run


def test_a_rerun_reuses_the_stored_refined_plans(
    first_run: tuple[Path, dict], rerun: Callable[..., tuple[int, dict, str]]
) -> None:
    """Run twice into one --out: no refine call the second time; the same plans to the bit."""
    calls, summary, _ = rerun()
    assert calls == 0
    assert [r["stored"] for r in summary["refinement"]] == [True, True]
    assert _plans(summary) == _plans(first_run[1])  # f, T, knots, rounds: bit-equal
    replay = (rerun.folder / "replay.html").read_text()  # type: ignore[attr-defined]
    for label, *_, duration, _ in _plans(summary):  # the stored (refined) plans are replayed
        assert f"{label}: T = {duration:.3f} s" in replay


def _save(refined: Refined, path: Path) -> Path:
    return save_result(refined.result, path, refinement=refined.refinement)


def _store(folder: Path) -> SweepStore[Refined]:
    """The run folder's store of refined plans, opened as the library opens it (no checks)."""
    manifest = json.loads((folder / "refined" / "manifest.json").read_text())
    return SweepStore(
        folder / "refined", kind="refined", params=manifest["params"], save=_save, load=load_refined
    )


def _key(store: SweepStore[Refined], item: str) -> str:
    (key,) = [k for k in store.keys() if k.startswith(f"{item}.")]
    return key


def test_a_tampered_stored_plan_is_refined_again(
    first_run: tuple[Path, dict], rerun: Callable[..., tuple[int, dict, str]]
) -> None:
    """A stored plan with edited torques (checksums recomputed) is refused and refined again."""
    store = _store(rerun.folder)  # type: ignore[attr-defined]
    key = _key(store, "point_001")  # beta = 0.7
    result, record = load_refined(store.payload_path(key))
    assert record.certified
    tau = np.array(result.variables["tau"], dtype=float)
    tau[np.argmax(np.abs(tau).max(axis=1))] *= 1.05  # 5 % more of the largest torque
    tampered = dataclasses.replace(result, variables={**result.variables, "tau": tau})
    store.write_done(key, Refined(tampered, record), {"label": "beta = 0.7"})  # new checksums
    store.close()
    calls, summary, err = rerun()
    assert calls == 1  # the tampered one only
    assert "beta = 0.7: stored refined plan not reused" in err and "refining it again" in err
    assert [r["stored"] for r in summary["refinement"]] == [False, True]  # 0.7 first (shorter T)
    assert _plans(summary) == _plans(first_run[1])  # refined again: the same plan


def test_another_points_plan_under_this_key_is_refined_again(
    first_run: tuple[Path, dict], rerun: Callable[..., tuple[int, dict, str]]
) -> None:
    """Beta 0.3's refined plan (a sound plan) re-bound as beta 0.7's is refused: not its plan."""
    store = _store(rerun.folder)  # type: ignore[attr-defined]
    other = load_refined(store.payload_path(_key(store, "point_000")))
    store.write_done(_key(store, "point_001"), other, {"label": "beta = 0.7"})
    store.close()
    calls, summary, err = rerun()
    assert calls == 1
    assert "beta = 0.3, the grid plan's is 0.7" in err and "refining it again" in err
    assert _plans(summary) == _plans(first_run[1])


def test_a_certified_claim_is_checked_against_the_budgets_tolerance(
    first_run: tuple[Path, dict], tmp_path: Path
) -> None:
    """A plan stored as certified under a tolerance its errors exceed is refused (check_refined)."""
    folder = tmp_path / "run"
    shutil.copytree(first_run[0], folder)
    store = _store(folder)
    key = _key(store, "point_001")
    (grid_file,) = (folder / "items").glob("*/point_001.npz")
    grid = load_result(grid_file)
    refined = load_refined(store.payload_path(key), robot=grid.problem.robot)
    store.close()
    budget = refined.refinement.budget
    assert check_refined({key: grid}, budget, folder, key, refined) is None
    tight = dataclasses.replace(budget, tolerance=1e-12)  # claimed: all errors within 1e-12
    forged = Refined(refined.result, dataclasses.replace(refined.refinement, budget=tight))
    why = check_refined({key: grid}, tight, folder, key, forged)
    assert why is not None and "stored as certified, but its max error" in why
    assert "another budget" in str(check_refined({key: grid}, tight, folder, key, refined))
    assert "no refined plan" in str(check_refined({}, budget, folder, key, refined))


def test_a_changed_budget_refines_again(
    first_run: tuple[Path, dict], rerun: Callable[..., tuple[int, dict, str]]
) -> None:
    """--max-rounds 7 is another budget: every plan refined again; both budgets' plans kept."""
    calls, summary, _ = rerun("--max-rounds", "7")
    assert calls == 2
    assert [r["stored"] for r in summary["refinement"]] == [False, False]
    assert all("at most 7 rounds" in r["budget"] for r in summary["refinement"])
    calls, summary, _ = rerun()  # the first budget again: its plans are still stored
    assert calls == 0 and _plans(summary) == _plans(first_run[1])


def test_a_kill_while_refining_loses_only_the_plan_in_progress(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Stopped in the second refinement, the rerun refines only the second plan."""
    calls = _counting(monkeypatch)
    counted = refinement.refine

    def dies_second(*args: object, **kwargs: object) -> Refined:
        if len(calls) == 1:
            raise KeyboardInterrupt  # as a kill would: nothing after the first plan is made
        return counted(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(refinement, "refine", dies_second)
    with pytest.raises(KeyboardInterrupt):
        main([*ARGV, "--out", str(tmp_path / "run")])
    assert len(calls) == 1
    monkeypatch.setattr(refinement, "refine", counted)
    capsys.readouterr()
    assert main([*ARGV, "--out", str(tmp_path / "run")]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert len(calls) == 2  # one more: the plan in progress when stopped
    assert [r["stored"] for r in summary["refinement"]] == [True, False]


def test_plans_refined_in_worker_processes_are_the_same_and_stored(
    first_run: tuple[Path, dict], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--workers 2: the plans are refined in worker processes, bit-equal to in-process, stored."""
    argv = [*ARGV, "--workers", "2", "--out", str(tmp_path / "run")]  # the last --workers wins
    assert main(argv) == 0
    summary = json.loads(capsys.readouterr().out)
    assert [r["stored"] for r in summary["refinement"]] == [False, False]
    assert _plans(summary) == _plans(first_run[1])
    assert main(argv) == 0
    again = json.loads(capsys.readouterr().out)
    assert [r["stored"] for r in again["refinement"]] == [True, True]
    assert _plans(again) == _plans(first_run[1])
