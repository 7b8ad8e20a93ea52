"""A problem's start/goal refused inside an obstacle; a plan's clearance certified between knots."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from youbot_opt.collision import (
    Cylinder,
    Obstacle,
    Scene,
    Sphere,
    build_collision_model,
    exact_checker,
)
from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.load import load_model
from youbot_opt.trajopt.clearance import certify_plan_clearance, check_boundary_clearance
from youbot_opt.trajopt.guess import straight_line_guess
from youbot_opt.trajopt.problem import BoundaryState, TrajOptProblem


@pytest.fixture(autouse=True)
def _fit_cache(fit_cache: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Sphere fits are cached in a temporary folder during each test, never the user's."""
    monkeypatch.setenv("YOUBOT_OPT_CACHE", str(fit_cache))


@pytest.fixture(scope="module")
def ur5():
    """The ur5 of example-robot-data."""
    return load_model("ur5")


def _swing(robot, n_knots: int = 4) -> TrajOptProblem:
    """The arm stretched out, its shoulder turning from -60 to 240 degrees."""
    q0 = np.zeros(robot.nq)
    q0[1], q0[2] = -np.pi / 2, np.pi / 2
    q1 = q0.copy()
    q0[0], q1[0] = np.deg2rad(-60.0), np.deg2rad(240.0)
    return TrajOptProblem(
        robot=robot, start=BoundaryState(q=q0), goal=BoundaryState(q=q1), n_knots=n_knots
    )


def test_goal_inside_obstacle_refused_before_solving(ur5):
    """A ball around the goal's wrist refuses the problem, naming the goal, a link and the ball."""
    problem = _swing(ur5)
    robot = problem.robot
    from youbot_opt.robot.model import frame_placement

    wrist = frame_placement(robot, problem.goal.q, "wrist_2_link").translation
    ball = Obstacle(name="ball", shape=Sphere(radius=0.05), xyz=tuple(wrist))
    checker = exact_checker(
        build_collision_model(robot, Scene((ball,)), self_collision=False), robot
    )
    with pytest.raises(
        ParameterError, match=r"goal: link geometry '\w+' penetrates obstacle 'ball'"
    ):
        check_boundary_clearance(problem, checker)


def test_a_goal_given_to_solve_inside_an_obstacle_is_refused_before_ipopt(ur5):
    """solve(goal=...) with a goal inside an obstacle: refused naming the goal and the ball.

    The problem's own start and goal are clear (the solver builds); the override puts the
    wrist (its coal solid) inside a ball. A clear override is accepted and solved.
    """
    from youbot_opt.collision import Clearance
    from youbot_opt.robot.model import frame_placement
    from youbot_opt.trajopt.solver import TrajOptSolver

    problem = _swing(ur5)
    inside = problem.goal.q.copy()
    inside[0] = np.deg2rad(90.0)  # between start and goal, the shoulder turned
    wrist = frame_placement(ur5, inside, "wrist_2_link").translation
    ball = Obstacle(name="ball", shape=Sphere(radius=0.05), xyz=tuple(wrist))
    clear = Clearance(scene=Scene((ball,)), self_collision=False)
    solver = TrajOptSolver(dataclasses.replace(problem, clearance=clear))
    with pytest.raises(
        ParameterError, match=r"goal: link geometry '\w+' penetrates obstacle 'ball'"
    ):
        solver.solve(goal=inside)
    with pytest.raises(ParameterError, match=r"start: link geometry '\w+' penetrates obstacle"):
        solver.solve(start=inside)
    assert solver.solve(goal=problem.goal.q).problem.clearance == clear  # a clear goal runs


def test_knots_clear_but_plan_clips_between_them(ur5):
    """A 4-knot plan (every 100 degrees) clear at its knots but hitting a pillar between fails."""
    problem = _swing(ur5)
    robot = problem.robot
    pillar = Obstacle(name="pillar", shape=Cylinder(radius=0.02, length=2.0), xyz=(0.0, 0.45, 0.5))
    checker = exact_checker(
        build_collision_model(robot, Scene((pillar,)), self_collision=False), robot
    )
    plan = straight_line_guess(problem, duration=2.0)
    check_boundary_clearance(problem, checker)
    knots = [checker.distances(robot, q).min() for q in plan.q]
    assert min(knots) > 0.0  # a knots-only check passes
    cert = certify_plan_clearance(plan, robot, checker, samples_per_interval=1)
    assert not cert.certified
    assert cert.closest_pair[1] == "pillar" and cert.failures
    assert cert.closest_distance < 0.0


def test_clear_plan_is_certified(ur5):
    """The same swing with the pillar far above the arm is certified at a 5 cm margin."""
    problem = _swing(ur5, n_knots=5)
    robot = problem.robot
    pillar = Obstacle(name="pillar", shape=Cylinder(radius=0.02, length=2.0), xyz=(0.0, 0.0, 3.0))
    checker = exact_checker(
        build_collision_model(robot, Scene((pillar,)), self_collision=False), robot
    )
    plan = straight_line_guess(problem, duration=2.0)
    cert = certify_plan_clearance(plan, robot, checker, margin=0.05)
    assert cert.certified and cert.lower_bound >= 0.05 - cert.tolerance
