"""``plot_tool``: each tool constraint over the plan with its limit (#30 item 2)."""

from __future__ import annotations

import numpy as np
import pytest

from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.load import load_model
from youbot_opt.trajopt.problem import BoundaryState, TrajOptProblem
from youbot_opt.trajopt.solver import TrajOptSolver
from youbot_opt.trajopt.tool import KeepAxis, ToolSpeed
from youbot_opt.viz.plots.tool import plot_tool


def test_one_axes_per_constraint_with_its_limit() -> None:
    """Two constraints: two axes, each with the limit line (the tilt in degrees)."""
    q = np.deg2rad([-30.0, -30.0, 60.0])
    tool = (
        KeepAxis(axis=(1, 0, 0), direction=(0, 0, 1), max_angle=np.deg2rad(3.0)),
        ToolSpeed(max_speed=0.5),
    )
    problem = TrajOptProblem(
        robot=load_model("youbot"),
        start=BoundaryState(q=q),
        goal=BoundaryState(q=-q),
        n_knots=10,
        tool=tool,
    )
    result = TrajOptSolver(problem, "hermite_simpson").solve(beta=0.5)
    fig = plot_tool(result, samples=50)
    axes = fig.get_axes()
    assert len(axes) == 2
    limits = [line.get_ydata()[0] for ax in axes for line in ax.get_lines()[-1:]]
    assert limits == pytest.approx([3.0, 0.5])
    assert "deg" in axes[0].get_ylabel() and "m/s" in axes[1].get_ylabel()
    free = TrajOptSolver(TrajOptProblem(robot=problem.robot, start=problem.start,
                                        goal=problem.goal, n_knots=6)).solve()  # fmt: skip
    with pytest.raises(ParameterError, match="plot_tool needs"):
        plot_tool(free)
