"""Tests of the payload-mass sweep (youbot_opt.trajopt.payload_sweep)."""

from __future__ import annotations

import numpy as np
import pytest

from youbot_opt.exceptions import ParameterError
from youbot_opt.reproduction.study1 import study1_problem
from youbot_opt.robot.payload import Payload
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.trajopt.multistart import run_multistart
from youbot_opt.trajopt.payload_sweep import payload_sweep
from youbot_opt.trajopt.solver import TrajOptSolver

SERIAL = SweepOptions(executor="serial")


@pytest.fixture(scope="module")
def problem(youbot):
    return study1_problem(12, robot=youbot)


@pytest.fixture(scope="module")
def sweep(problem):
    """Two masses, the straight start and one spline start each, Hermite-Simpson."""
    return payload_sweep(problem, [0.0, 0.5], method="hermite_simpson", n_starts=1, sweep=SERIAL)


def test_each_point_is_solved_with_its_payload(sweep):
    """Every point's best result is for the robot carrying that mass at the tip, and converged."""
    np.testing.assert_array_equal(sweep.masses, [0.0, 0.5])
    for point in sweep.points:
        assert point.n_converged >= 1 and point.result is not None and point.result.success
        robot = point.result.problem.robot
        assert robot.payload == Payload(mass=point.mass, frame=robot.tip_frame)
        assert point.duration == point.result.duration and point.work == point.result.work


def test_a_heavier_payload_costs_work(sweep):
    """Half a kilogram at the tip of the youBot costs more work W (gravity torques grow)."""
    assert sweep.works[1] > sweep.works[0]
    assert "mass [kg]" in sweep.table() and len(sweep.table().splitlines()) == 3


def test_zero_mass_is_the_bare_robot(sweep, problem):
    """A payload of 0 kg gives the bare robot's multistart optimum exactly."""
    bare = run_multistart(
        TrajOptSolver(problem, method="hermite_simpson"), 1, include_straight=True, sweep=SERIAL
    )
    assert sweep.points[0].objective == bare.best.objective


def test_bad_masses_are_refused(problem):
    """Negative, non-finite or no masses are a ParameterError naming masses."""
    for bad in ([], [-0.1], [float("nan")]):
        with pytest.raises(ParameterError, match="masses"):
            payload_sweep(problem, bad, sweep=SERIAL)
