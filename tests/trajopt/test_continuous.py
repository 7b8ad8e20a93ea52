"""Trajectories of a robot with continuous joints, planned in angle coordinates.

The double pendulum of example-robot-data with two continuous joints (Pinocchio
nq = 4, nv = 2) is asked to turn its first joint from 0 to 4 rad, past +π,
which a (cos, sin) decision variable bounded like Pinocchio's [-1.01, 1.01]
could not express as one coordinate.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.catalogue import example_robot_data_dir
from youbot_opt.robot.model import RobotModel
from youbot_opt.trajopt.certify import certify
from youbot_opt.trajopt.problem import BoundaryState, TrajOptProblem
from youbot_opt.trajopt.solver import TrajOptSolver

GOAL = np.array([4.0, -1.0])  # [rad]; joint 0 ends past +pi
N_KNOTS = 30


@pytest.fixture(scope="module")
def pendulum() -> RobotModel:
    """double_pendulum_continuous with torque and speed limits (its URDF has none)."""
    path = (
        example_robot_data_dir()
        / "example-robot-data/robots/double_pendulum_description/urdf"
        / "double_pendulum_continuous.urdf"
    )
    model = pin.buildModelFromUrdf(str(path))
    assert (model.nq, model.nv) == (4, 2)
    model.effortLimit = np.array([20.0, 10.0])  # [N m]
    model.velocityLimit = np.array([8.0, 8.0])  # [rad/s]
    return RobotModel.from_pin_model(model)


def _problem(robot: RobotModel) -> TrajOptProblem:
    return TrajOptProblem(
        robot=robot, start=BoundaryState(q=[0.0, 0.0]), goal=BoundaryState(q=GOAL), n_knots=N_KNOTS
    )


def test_problem_uses_angle_coordinates(pendulum: RobotModel) -> None:
    """The problem has nv = 2 unbounded angles; Pinocchio's 4-entry (cos, sin) q is refused."""
    problem = _problem(pendulum)
    assert problem.robot.nq == problem.nv == 2
    bounds = problem.bounds()
    assert np.all(np.isinf(bounds.q_lower)) and np.all(np.isinf(bounds.q_upper))
    with pytest.raises(ParameterError, match=r"start.q must have shape \(2,\)"):
        TrajOptProblem(
            robot=pendulum, start=BoundaryState(q=[1.0, 0.0, 1.0, 0.0]), goal=BoundaryState(q=GOAL)
        )


@pytest.mark.parametrize("backend", ["symbolic", "pinocchio"])
def test_turn_past_pi_solves_and_certifies(pendulum: RobotModel, backend: str) -> None:
    """Hermite-Simpson plans the turn past +pi with both backends; pin.aba certifies it."""
    result = TrajOptSolver(_problem(pendulum), "hermite_simpson", backend=backend).solve(beta=0.5)
    assert result.success, result.status
    q = result.trajectory.q
    np.testing.assert_allclose(q[-1], GOAL, atol=1e-8)  # boundary equality, IPOPT tol
    assert q[:, 0].max() > math.pi  # the joint really passed +pi in one coordinate
    certificate = certify(result)
    assert certificate.ok, certificate.failures()


def test_transcriptions_agree(pendulum: RobotModel) -> None:
    """Trapezoidal and Hermite-Simpson optima agree within 2 % (measured 0.45 % at 30 knots:
    the two discretisation errors of the same continuous optimum)."""
    problem = _problem(pendulum)
    objectives = [
        TrajOptSolver(problem, method).solve(beta=0.5).raise_for_status().objective
        for method in ("trapezoidal", "hermite_simpson")
    ]
    assert abs(objectives[0] - objectives[1]) <= 0.02 * abs(objectives[1])
