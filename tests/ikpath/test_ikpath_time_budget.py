"""The automatic starts' time budget (issue 25): no new start after it, the rest reported.

``run_multistart(problem)`` without ``n_starts`` (and ``youbot-opt ikpath`` without
``--starts``) begins no new start once ``time_budget`` [s] has passed (default
:data:`~youbot_opt.ikpath.starts.AUTOMATIC_TIME_BUDGET`); starts asked for all run.
"""

from __future__ import annotations

import math

import pytest

from youbot_opt.cli import main
from youbot_opt.exceptions import ParameterError
from youbot_opt.ikpath.multistart import run_multistart
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.starts import AUTOMATIC_TIME_BUDGET
from youbot_opt.robot.planar import PlanarChain

PLANAR_ARGS = ["--lengths", "3", "2", "2", "--lower", "-1", "-2", "-2", "--upper", "1", "2", "2"]
PLANAR_ARGS += ["--target", "4", "1", "--target", "3", "-2"]


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
