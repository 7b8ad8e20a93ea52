"""Joint values printed and plotted in their joint's unit: panda's prismatic finger in m, m/s, N."""

from __future__ import annotations

import numpy as np
import pytest

from youbot_opt.cli.advice import gripper_note
from youbot_opt.cli.trajopt_text import format_result
from youbot_opt.robot.load import load_model
from youbot_opt.trajopt.certify import certify
from youbot_opt.trajopt.problem import BoundaryState, TrajOptProblem
from youbot_opt.trajopt.solver import TrajOptSolver

Q0 = np.array([0.0, 0.0, 0.0, -1.5, 0.0, 1.5, 0.0, 0.01])  # [rad] x 7, finger [m]
Q1 = np.array([1.0, 0.5, 0.0, -1.0, 0.0, 2.0, 0.5, 0.02])


@pytest.fixture(scope="module")
def panda_plan():
    """A 12-knot Radau plan of example-robot-data's panda; its free finger moves 0.01 -> 0.02 m."""
    robot = load_model("panda")
    problem = TrajOptProblem(
        robot=robot, start=BoundaryState(q=Q0), goal=BoundaryState(q=Q1), n_knots=12
    )
    result = TrajOptSolver(problem, "radau", compile=False).solve(beta=0.5)
    assert result.success
    return result


def test_the_certificate_gives_each_bound_its_joints_unit(panda_plan):
    """Bound excesses of the finger (joint 7) in m, m/s, N; maxima over all joints 'rad or m'."""
    cert = certify(panda_plan)
    text = str(cert)
    assert "local error, position [rad or m]" in text
    for c in cert.bounds:
        line = next(x for x in text.splitlines() if f"bound {c.quantity}, " in x and
                    ("at knots" if c.where == "knots" else "between") in x)  # fmt: skip
        unit = cert.joint_units[c.joint]
        expected = {"position": unit.position, "velocity": unit.velocity, "torque": unit.effort}
        unit_text = expected[c.quantity]
        assert (
            f" {unit_text} over the bound at t = " in line
            or f" {unit_text} to the bound at t = " in line
        ), line


def test_the_solve_table_names_the_unit_of_each_active_bound(panda_plan):
    """The active-bounds table has a unit column: m for the finger, rad for the arm."""
    text = format_result(panda_plan)
    rows = [x.split() for x in text.split("active bounds")[1].splitlines()[2:] if "..." not in x]
    assert rows
    for row in rows:
        joint, unit = int(row[2]), row[4]
        family = row[0].split("_")[0]
        units = panda_plan.problem.robot.joint_units()[joint]
        assert unit == {"position": units.position, "velocity": units.velocity}.get(
            family, units.effort
        )


def test_a_moving_finger_is_noted_with_the_lock_that_plans_the_arm_alone(panda_plan):
    """gripper_note: names the finger, its motion in m, the work in N^2 s, and the --lock."""
    note = gripper_note(panda_plan)
    assert note.startswith("note: the panda_finger_joint1 (prismatic: a finger or gripper)")
    assert "0.01 -> 0.02 m" in note and "N^2 s" in note
    assert "--lock panda_finger_joint1=0.02" in note
    assert note in format_result(panda_plan)


def test_the_trajectory_figure_labels_the_finger_in_metres(panda_plan):
    """plot_trajectory: rad/rad/s/N m axes, the prismatic finger named with m, m/s, N."""
    from youbot_opt.viz.plots.trajopt import plot_trajectory

    fig = plot_trajectory(panda_plan)
    labels = [ax.get_ylabel() for ax in fig.axes[:3]]
    assert "[rad]" in labels[0] and "panda_finger_joint1 in [m]" in labels[0]
    assert "[rad/s]" in labels[1] and "in [m/s]" in labels[1]
    assert "[N m]" in labels[2] and "in [N]" in labels[2]
