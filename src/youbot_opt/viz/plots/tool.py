"""The figure of a plan's tool constraints (#30): each measure over time with its limit.

One axes per constraint of the problem (``problem.tool``): the measure (angle
[deg], distance [m] or speed [m/s]) sampled along the plan, the knots marked,
the limit dashed. ``youbot-opt solve`` writes it as ``tool.png``.

>>> plot_tool(result).savefig("tool.png")  # doctest: +SKIP
"""

from __future__ import annotations

import math

import numpy as np
from matplotlib.figure import Figure

from youbot_opt.exceptions import ParameterError
from youbot_opt.trajopt.result import TrajOptResult
from youbot_opt.trajopt.tool import KeepAxis, tool_measures
from youbot_opt.viz.plots.trajopt import joint_colour, new_figure, plan_times

__all__ = ["plot_tool"]


def plot_tool(result: TrajOptResult, *, samples: int = 400) -> Figure:
    """Plot each tool constraint's measure over the plan, with its limit.

    Parameters
    ----------
    result : TrajOptResult
        A result with a trajectory and a problem with tool constraints.
    samples : int
        Sample times over the plan (>= 2).

    Returns
    -------
    Figure
        One row of axes per constraint: measure over time [s]; angles in [deg].

    Raises
    ------
    ParameterError
        The result has no trajectory, or its problem no tool constraint.
    """
    tool = result.problem.tool
    traj = result.trajectory
    if not tool or traj is None:
        raise ParameterError(
            "plot_tool needs a result with a trajectory and tool constraints", name="result"
        )
    robot = result.problem.robot
    t = plan_times(traj, samples)
    q = np.asarray(traj(t), dtype=float)
    v = np.asarray(traj.velocity(t), dtype=float)
    m = tool_measures(robot, tool, q, v)
    mk = tool_measures(robot, tool, traj.q, traj.v)
    fig, axes = new_figure(len(tool), 1, (7.0, 2.4 * len(tool) + 0.6))
    for i, c in enumerate(tool):
        ax = axes[i, 0]
        scale, unit = (180.0 / math.pi, "deg") if isinstance(c, KeepAxis) else (1.0, c.unit)
        ax.plot(t, scale * m[:, i], color=joint_colour(i), label=c.label)
        ax.plot(traj.t, scale * mk[:, i], "o", color=joint_colour(i), markersize=3)
        ax.axhline(scale * c.limit, color="k", linestyle="--", linewidth=1.0, label="limit")
        ax.set_ylabel(f"{c.label} [{unit}]")
        ax.legend(loc="best", fontsize="small")
    axes[-1, 0].set_xlabel("t [s]")
    axes[0, 0].set_title("tool constraints along the plan (knots marked)")
    return fig
