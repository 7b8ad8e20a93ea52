"""Tests of the problem spec (trajopt.problem) and the objective terms (trajopt.objectives)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from youbot_opt.exceptions import ParameterError
from youbot_opt.reproduction.study1 import study1_problem
from youbot_opt.trajopt.objectives import objective_value, work
from youbot_opt.trajopt.problem import BoundaryState, TrajOptProblem
from youbot_opt.trajopt.quadrature import quadrature_weights
from youbot_opt.trajopt.solver import TrajOptSolver

# The study's data sheet (spec trajopt.md, "Joint limits"), typed in here
# independently of youbot_opt.robot.params.
SHEET_LOWER_DEG = np.array([-65.0, -151.0, -102.5])
SHEET_UPPER_DEG = np.array([90.0, 146.0, 102.5])
SHEET_SPEED_DEG_S = np.array([90.0, 90.0, 90.0])
SHEET_TORQUE_NM = np.array([9.5, 6.0, 2.0])


@pytest.fixture(scope="module")
def problem(youbot):
    return study1_problem(robot=youbot)


def test_study1_boundary_and_size(problem):
    """study1_problem has the spec's start, goal, rest velocities and 50 knots (no beta)."""
    np.testing.assert_allclose(problem.start.q, [-math.pi / 6, -math.pi / 6, -math.pi / 3], atol=0)
    np.testing.assert_allclose(problem.goal.q, [math.pi / 6, math.pi / 6, math.pi / 3], atol=0)
    np.testing.assert_array_equal(problem.start.v, np.zeros(3))
    np.testing.assert_array_equal(problem.goal.v, np.zeros(3))
    assert problem.n_knots == 50
    assert not hasattr(problem, "objective")  # beta is a solve-time parameter
    assert problem.duration is None


def test_bounds_scale_every_family(problem):
    """bound_scale multiplies the data-sheet position, speed and torque bounds (1e-12 rad)."""
    for s in (1.0, 0.85):
        b = problem.bounds(s)
        # deg -> rad conversion is exact up to rounding: 1e-12 is ~1e4 ulps of 2.6 rad.
        np.testing.assert_allclose(b.q_lower, s * np.radians(SHEET_LOWER_DEG), atol=1e-12)
        np.testing.assert_allclose(b.q_upper, s * np.radians(SHEET_UPPER_DEG), atol=1e-12)
        np.testing.assert_allclose(b.v_upper, s * np.radians(SHEET_SPEED_DEG_S), atol=1e-12)
        np.testing.assert_allclose(b.v_lower, -s * np.radians(SHEET_SPEED_DEG_S), atol=1e-12)
        np.testing.assert_allclose(b.tau_upper, s * SHEET_TORQUE_NM, atol=1e-12)
        np.testing.assert_allclose(b.tau_lower, -s * SHEET_TORQUE_NM, atol=1e-12)


def test_bounds_scale_selected_families(youbot):
    """With scaled_bounds=('torque',), positions and speeds keep the data-sheet values."""
    p = study1_problem(robot=youbot, scaled_bounds=("torque",))
    b = p.bounds(0.5)
    np.testing.assert_allclose(b.q_upper, np.radians(SHEET_UPPER_DEG), atol=1e-12)
    np.testing.assert_allclose(b.v_upper, np.radians(SHEET_SPEED_DEG_S), atol=1e-12)
    np.testing.assert_allclose(b.tau_upper, 0.5 * SHEET_TORQUE_NM, atol=1e-12)


def test_boundary_state_defaults_and_read_only():
    """BoundaryState fills v with zeros and freezes its arrays."""
    s = BoundaryState(q=[0.1, 0.2])
    np.testing.assert_array_equal(s.v, [0.0, 0.0])
    with pytest.raises(ValueError):
        s.q[0] = 1.0


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"q": [0.0, np.nan]}, "finite"),
        ({"q": [[0.0, 1.0]]}, "shape"),
        ({"q": [0.0, 1.0], "v": [0.0]}, r"shape \(2,\)"),
    ],
)
def test_boundary_state_rejects_bad_input(kwargs, match):
    """Non-finite or wrongly shaped boundary states raise ParameterError naming the field."""
    with pytest.raises(ParameterError, match=match):
        BoundaryState(**kwargs)


def test_start_outside_bounds_is_rejected(youbot):
    """A start above joint 1's 90 deg limit raises ParameterError naming value and limit."""
    with pytest.raises(ParameterError, match=r"start\.q\[0\] = 2 rad is outside the bounds"):
        TrajOptProblem(
            robot=youbot,
            start=BoundaryState(q=[2.0, 0.0, 0.0]),
            goal=BoundaryState(q=[0.0, 0.0, 0.0]),
        )


def test_goal_velocity_outside_bounds_is_rejected(youbot):
    """A goal speed above 90 deg/s raises ParameterError."""
    with pytest.raises(ParameterError, match=r"goal\.v\[1\]"):
        TrajOptProblem(
            robot=youbot,
            start=BoundaryState(q=[0.0, 0.0, 0.0]),
            goal=BoundaryState(q=[0.0, 0.0, 0.0], v=[0.0, 2.0, 0.0]),
        )


def test_scaled_bounds_can_exclude_the_start(problem):
    """At bound_scale 0.5 the study's joint-3 start (-60 deg) lies outside +-51.25 deg."""
    with pytest.raises(ParameterError, match=r"start\.q\[2\].*bound_scale = 0\.5"):
        problem.check_boundary(0.5)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"n_knots": 1}, "n_knots must be >= 2"),
        ({"n_knots": 2.5}, "n_knots must be an int"),
        ({"duration": -1.0}, "duration must be finite and > 0"),
        ({"duration": math.inf}, "duration must be finite and > 0"),
        ({"scaled_bounds": ("speed",)}, "scaled_bounds entries"),
        ({"dt_min": 0.0}, "dt_min"),
    ],
)
def test_problem_rejects_bad_fields(youbot, kwargs, match):
    """Bad problem fields raise ParameterError saying what is valid."""
    with pytest.raises(ParameterError, match=match):
        study1_problem(robot=youbot, **kwargs)


def test_wrong_joint_count_is_rejected(youbot):
    """A 2-vector start for the 3-joint youBot raises ParameterError naming the shape."""
    with pytest.raises(ParameterError, match=r"start\.q must have shape \(3,\)"):
        TrajOptProblem(robot=youbot, start=BoundaryState(q=[0, 0]), goal=BoundaryState(q=[0, 0]))


@pytest.mark.parametrize("scale", [0.0, -1.0, math.nan, math.inf])
def test_bad_bound_scale(problem, scale):
    """bound_scale <= 0 or non-finite raises ParameterError."""
    with pytest.raises(ParameterError, match="bound_scale"):
        problem.bounds(scale)


@pytest.mark.parametrize("beta", [-0.1, 1.5, math.nan, "x"])
def test_bad_beta(beta, problem):
    """beta outside [0, 1] or not a number raises ParameterError where it enters: solve()."""
    solver = TrajOptSolver(dataclasses.replace(problem, n_knots=4))
    with pytest.raises(ParameterError, match="beta"):
        solver.solve(beta=beta)


def test_objective_value_weighs_the_terms():
    """objective_value(T, W, beta) is beta T + (1 - beta) W; beta = 1 is T, beta = 0 is W."""
    assert objective_value(2.0, 10.0, 1.0) == 2.0
    assert objective_value(2.0, 10.0, 0.0) == 10.0
    assert objective_value(2.0, 10.0, 0.25) == pytest.approx(0.25 * 2.0 + 0.75 * 10.0)


def test_trapezoidal_work_is_the_study_formula(rng):
    """work(rule='trapezoidal') equals sum_k dt (w_k + w_k+1) / 2 written out (1e-12 rel)."""
    tau = rng.normal(size=(7, 3))
    dt = 0.05
    w = np.sum(tau**2, axis=1)
    expected = sum(dt * (w[k] + w[k + 1]) / 2 for k in range(6))
    assert work(dt, tau) == pytest.approx(expected, rel=1e-12)


def test_simpson_work_is_exact_for_linear_torque():
    """Simpson's rule integrates tau . tau exactly when tau is linear in time (1e-12 rel)."""
    dt, n = 0.3, 5
    t = dt * np.arange(n)
    tm = t[:-1] + dt / 2
    c0, c1 = np.array([1.0, -2.0]), np.array([0.5, 3.0])
    tau, tau_mid = c0 + np.outer(t, c1), c0 + np.outer(tm, c1)
    total = t[-1]
    # integral of |c0 + c1 t|^2 over [0, T], by hand
    exact = c0 @ c0 * total + c0 @ c1 * total**2 + c1 @ c1 * total**3 / 3
    assert work(dt, tau, tau_mid, rule="simpson") == pytest.approx(exact, rel=1e-12)
    w_knots, w_mid = quadrature_weights("simpson", n)
    assert w_knots.sum() + w_mid.sum() == pytest.approx(n - 1, rel=1e-12)
