"""The automatic starts' time budget (issue 25): no new start after it, the rest reported.

``run_multistart(problem)`` without ``n_starts`` (and ``youbot-opt ikpath`` without
``--starts``) begins no new start once ``time_budget`` [s] has passed (default
:data:`~youbot_opt.ikpath.starts.AUTOMATIC_TIME_BUDGET`); starts asked for all run.
"""

from __future__ import annotations

import io
import json
import math

import numpy as np
import pytest

from youbot_opt.cli import main
from youbot_opt.cli.ikpath import StartProgress
from youbot_opt.exceptions import ParameterError
from youbot_opt.ikpath.multistart import run_multistart
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.starts import AUTOMATIC_TIME_BUDGET
from youbot_opt.robot.load import load_model
from youbot_opt.robot.planar import PlanarChain
from youbot_opt.sweeps.options import SweepOptions

PLANAR_ARGS = ["--lengths", "3", "2", "2", "--lower", "-1", "-2", "-2", "--upper", "1", "2", "2"]
PLANAR_ARGS += ["--target", "4", "1", "--target", "3", "-2"]
PLANAR_BEST = 0.5677879142  # rad^2: test_ikpath_defaults.py's, found by the 16 automatic starts
ZERO_START_E = 11.0616432750  # rad^2: start 0 of that example


def _planar_example() -> CyclicIKProblem:
    chain = PlanarChain(lengths=[3, 2, 2]).with_limits([-1, -2, -2], [1, 2, 2])
    return CyclicIKProblem(robot=chain, targets=[(4, 1), (3, -2)])


@pytest.mark.parametrize("budget", [0.0, -1.0, math.inf, -math.inf, math.nan, "soon", True])
def test_a_budget_that_is_no_positive_finite_time_is_refused_naming_it(budget):
    with pytest.raises(ParameterError, match="time_budget must be a positive, finite") as info:
        run_multistart(_planar_example(), time_budget=budget)
    assert info.value.name == "time_budget"
    assert repr(budget) in str(info.value)


@pytest.mark.parametrize(
    "asked", [{"n_starts": 4}, {"starts": "feasible"}, {"n_starts": 4, "starts": "branches"}]
)
def test_a_budget_with_starts_asked_for_is_refused(asked):
    """Starts asked for all run: a budget with them is refused, not silently ignored."""
    with pytest.raises(ParameterError, match="automatic starts only") as info:
        run_multistart(_planar_example(), time_budget=5.0, **asked)
    assert info.value.name == "time_budget"


def test_the_parser_default_is_the_library_default():
    from youbot_opt.cli import parser

    assert parser.AUTOMATIC_TIME_BUDGET_S == AUTOMATIC_TIME_BUDGET == 20.0


@pytest.mark.parametrize(
    ("extra", "match"),
    [
        (["--time-budget", "0"], "--time-budget must be a positive, finite time in [s], got 0.0"),
        (["--time-budget", "-3"], "got -3.0"),
        (["--time-budget", "inf"], "got inf"),
        (["--time-budget", "nan"], "got nan"),
        (["--time-budget", "5", "--starts", "3"], "the starts of --starts 3 all run"),
        (["--time-budget", "5", "--start-kind", "uniform"], "of --start-kind uniform all run"),
    ],
)
def test_cli_refuses_a_bad_budget_or_one_with_starts_asked_for(capsys, tmp_path, extra, match):
    argv = ["ikpath", *PLANAR_ARGS, *extra, "--no-progress", "--no-replay"]
    assert main([*argv, "--out", str(tmp_path / "r")]) == 2
    assert match in capsys.readouterr().err
    assert not (tmp_path / "r").exists()  # refused before any work


@pytest.mark.parametrize(("workers", "begun"), [(1, 1), (2, 2)])
def test_a_budget_of_almost_zero_runs_the_first_starts_and_reports_the_rest(workers, begun):
    """Serial: start 0 only; a pool of 2: the two starts it began. The rest: not run."""
    ms = run_multistart(_planar_example(), workers=workers, time_budget=1e-9)
    assert ms.n_starts == len(ms.results) == begun and ms.not_run == 16 - begun
    assert ms.planned_starts == 16 and ms.budget_reached and ms.time_budget == 1e-9
    assert ms.results[0].objective == pytest.approx(ZERO_START_E, abs=1e-8)
    assert ms.best_index < begun and sum(m.count for m in ms.minima) == ms.n_converged


def test_the_default_budget_keeps_the_quick_examples_result():
    """The planar example's 16 automatic starts take about 0.5 s: all run, E as before."""
    ms = run_multistart(_planar_example(), workers=1)
    assert ms.time_budget == AUTOMATIC_TIME_BUDGET and not ms.budget_reached
    assert ms.n_starts == ms.planned_starts == 16 and ms.not_run == 0
    assert ms.best.objective == pytest.approx(PLANAR_BEST, abs=1e-9)


@pytest.mark.parametrize("keep_results", [True, False])
def test_a_rerun_on_the_output_folder_goes_on_with_the_starts_not_run(tmp_path, keep_results):
    """Two budget-stopped runs, then one in the default budget: an uninterrupted run's starts."""
    problem = _planar_example()
    sweep = SweepOptions(workers=1, out=tmp_path / "ik", keep_results=keep_results)
    first = run_multistart(problem, time_budget=1e-9, sweep=sweep)
    assert (first.n_starts, first.resumed, first.not_run) == (1, 0, 15)
    second = run_multistart(problem, time_budget=1e-9, sweep=sweep)
    assert (second.n_starts, second.resumed, second.not_run) == (2, 1, 14)
    assert second.n_converged == 2 and second.status_counts() == {"solved": 2}
    last = run_multistart(problem, sweep=sweep)
    assert (last.n_starts, last.resumed, last.not_run) == (16, 2, 0)
    whole = run_multistart(problem, workers=1)
    assert [r.objective for r in last.results] == [r.objective for r in whole.results]
    assert last.best.objective == pytest.approx(PLANAR_BEST, abs=1e-9)
    assert [m.count for m in last.minima] == [m.count for m in whole.minima]


def test_spatial_automatic_starts_stop_at_the_budget_too():
    """ur5, IPOPT, a pool of 2: the two starts begun run, the rest are reported as not run."""
    robot = load_model("ur5")
    base = CyclicIKProblem(robot=robot, targets=[(0.4, 0.2, 0.3), (0.3, -0.3, 0.4)])
    ms = run_multistart(base, method="ipopt", workers=2, time_budget=1e-9)
    assert ms.n_starts == 2 and ms.planned_starts == 2 + ms.not_run > 2 and ms.budget_reached
    assert all(np.isfinite(r.objective) for r in ms.results)


def test_cli_says_how_many_planned_starts_ran(capsys, tmp_path):
    """summary.json: starts, planned_starts, time_budget, budget_reached; the text says it too."""
    argv = ["ikpath", *PLANAR_ARGS, "--time-budget", "1e-9", "--no-progress", "--no-replay"]
    assert main([*argv, "--json", "--out", str(tmp_path / "a")]) == 0  # start 0 solves
    doc = json.loads(capsys.readouterr().out)
    assert doc["starts"] == doc["certainty"]["starts"] == 1
    assert doc["planned_starts"] == 16 and doc["budget_reached"] is True
    assert doc["time_budget"] == 1e-9 and doc["E"] == pytest.approx(ZERO_START_E, abs=1e-8)
    rows = (tmp_path / "a" / "starts.jsonl").read_text().splitlines()
    assert [json.loads(r)["index"] for r in rows] == [0]
    assert main([*argv, "--out", str(tmp_path / "b")]) == 0
    out = capsys.readouterr().out
    assert "multistart: 1 starts (seed 0, branches)" in out
    assert "time budget 1e-09 s reached: 1 of 16 automatic starts ran, 15 not run (rerun " in out
    assert f"--out {(tmp_path / 'b').resolve()} to go on with them" in out
    assert "certainty: one start ran within the time budget, nothing to compare with" in out
    assert (
        main([*argv[:-4], "--no-progress", "--no-replay", "--json", "--out", str(tmp_path / "c")])
        == 0
    )
    doc = json.loads(capsys.readouterr().out)  # the default budget: every start ran
    assert doc["starts"] == doc["planned_starts"] == 16 and doc["budget_reached"] is False
    assert doc["time_budget"] == AUTOMATIC_TIME_BUDGET


def test_cli_starts_asked_for_have_no_budget(capsys, tmp_path):
    argv = ["ikpath", *PLANAR_ARGS, "--starts", "3", "--no-progress", "--no-replay", "--json"]
    assert main([*argv, "--out", str(tmp_path / "r")]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["starts"] == doc["planned_starts"] == 3
    assert doc["time_budget"] is None and doc["budget_reached"] is False


@pytest.mark.slow
def test_the_stalled_straight_arm_case_stops_at_its_budget():
    """(0, 7) under |theta| <= pi/2: every AL start stalls (about 1.5-4 s each, 16 planned)."""
    chain = PlanarChain(lengths=[3, 2, 2]).with_limits(-1.5708, 1.5708)
    problem = CyclicIKProblem(robot=chain, targets=[(0, 7), (5, 0)])
    ms = run_multistart(problem, workers=1, time_budget=2.0)
    assert ms.budget_reached and 1 <= ms.n_starts < 16 and ms.planned_starts == 16
    assert not ms.best.success and ms.best.status.value == "stalled"
    assert ms.wall_time < 20.0  # wide slack: 2 s, the start running then, drawing the starts


def test_a_progress_bar_stopped_by_the_budget_ends_its_line():
    """On a terminal the bar ends its line at the last start, or at end() if the budget stops."""

    class Tty(io.StringIO):
        def isatty(self) -> bool:
            return True

    stream = Tty()
    bar = StartProgress(stream)
    bar(1, 16, math.inf)
    assert not stream.getvalue().endswith("\n")
    bar.end()
    bar.end()  # once only
    assert stream.getvalue().count("\n") == 1 and "1/16 starts" in stream.getvalue()
    stream = Tty()
    bar = StartProgress(stream)
    bar(16, 16, 1.0)
    bar.end()
    assert stream.getvalue().count("\n") == 1
