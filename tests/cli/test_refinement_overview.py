"""A study that refines more than a few plans draws one overview, not a figure each (#27).

:func:`youbot_opt.cli.refinement.refinement_figures` draws each refined plan's
rounds for 1 to ``PER_PLAN_FIGURES`` plans (``refinement.png`` for one,
``refinement_<k>.png`` for a few) and ONE ``refinement.png`` overview of all
of them beyond; ``summary.json["files"]`` lists what was written.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from youbot_opt.cli import main
from youbot_opt.cli.refinement import PER_PLAN_FIGURES, refinement_figures
from youbot_opt.trajopt.refine import Refinement, RefinementBudget, RefinementRound

BASE = ["--knots", "15", "--workers", "0", "--quiet", "--json"]  # small: the files are tested


def _record(certified: bool, knots: tuple[int, ...]) -> Refinement:
    """A hand-made refinement: one round per entry of ``knots`` on a 2 s uniform grid."""
    rounds = tuple(
        RefinementRound(
            index=i,
            n_knots=n,
            status="solved",
            objective=8.0,
            duration=2.0,
            max_error=5e-4,
            t=np.linspace(0.0, 2.0, n),
            errors=np.full(n - 1, 5e-4),
            certificate_passed=True,
            failures=(),
            feedback_rms=0.01,
            feedback_peak=0.02,
            local_position=1e-3,
            iterations=5,
            solve_time=0.1,
            check_time=0.1,
        )  # fmt: skip
        for i, n in enumerate(knots)
    )
    reason = "certified" if certified else "at most 2 rounds"
    return Refinement(certified, reason, RefinementBudget(tolerance=1e-3), rounds, elapsed=1.0)


def test_refinement_figures_of_hand_made_records(tmp_path: Path) -> None:
    """1 plan: its rounds; a few: one each; more: one overview; no record: skipped."""
    good, bad = _record(True, (5, 9, 17)), _record(False, (5, 9))
    plans = [(None, good), (None, bad), (None, None)]  # type: ignore[list-item]
    names = ["a", "b", "c"]
    for name in ("one", "few", "many"):
        (tmp_path / name).mkdir()
    assert refinement_figures(tmp_path / "one", plans[:1], names[:1]) == [  # type: ignore[arg-type]
        tmp_path / "one" / "refinement.png"
    ]
    few = refinement_figures(tmp_path / "few", plans, names)  # type: ignore[arg-type]
    assert few == [tmp_path / "few" / f"refinement_{k}.png" for k in (1, 2)]
    many = [(None, good if k % 2 else bad) for k in range(PER_PLAN_FIGURES + 1)]
    folder = tmp_path / "many"
    paths = refinement_figures(folder, many, [f"p{k}" for k in range(len(many))])  # type: ignore[arg-type]
    assert paths == [folder / "refinement.png"]
    assert sorted(p.name for p in folder.iterdir()) == ["refinement.png"]
    assert refinement_figures(tmp_path / "none", [], []) == []


def _run(argv: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> tuple[Path, dict]:
    assert main([*argv, *BASE, "--out", str(tmp_path / "run")]) == 0
    summary = json.loads(capsys.readouterr().out)
    return Path(summary["output_folder"]), summary


def test_a_five_plan_pareto_draws_one_overview(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """5 refined plans: the overview ``refinement.png`` is written and listed, no per-plan file."""
    folder, summary = _run(["pareto", "--betas", "0.1,0.3,0.5,0.7,0.9"], tmp_path, capsys)
    assert len(summary["refinement"]) == 5 > PER_PLAN_FIGURES
    assert "refinement.png" in summary["files"] and (folder / "refinement.png").stat().st_size
    assert not list(folder.glob("refinement_*.png"))
    assert not [f for f in summary["files"] if f.startswith("refinement_")]
    assert all(len(r["rounds"]) >= 1 for r in summary["refinement"])  # each plan's rounds


def test_a_one_plan_pareto_draws_its_rounds(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """1 refined plan: ``refinement.png`` of its rounds, as before the overview."""
    folder, summary = _run(["pareto", "--betas", "0.5"], tmp_path, capsys)
    assert len(summary["refinement"]) == 1
    assert "refinement.png" in summary["files"] and (folder / "refinement.png").stat().st_size
    assert not list(folder.glob("refinement_*.png"))
