"""Random feasible polynomial guesses: boundary states, knot limits, inverse-dynamics torques."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.load import load_model
from youbot_opt.trajopt.problem import BoundaryState
from youbot_opt.trajopt.spline_guess import bernstein_matrix, random_spline_guess

Q_START = np.array([-math.pi / 6, -math.pi / 6, -math.pi / 3])
Q_GOAL = -Q_START


@pytest.fixture(scope="module")
def youbot():
    """The planar youBot with the study code's damping (0.1 N m s/rad)."""
    return load_model("youbot", damping=0.1)


def _guess(robot, seed, n=50, **kwargs):
    return random_spline_guess(
        robot, (Q_START, np.zeros(3)), (Q_GOAL, np.zeros(3)), n, seed=seed, **kwargs
    )


def test_boundary_states_met(youbot) -> None:
    """Start/goal positions and (non-zero) velocities are met to 1e-9 [rad], [rad/s]."""
    v0, v1 = np.array([0.3, -0.2, 0.5]), np.array([-0.4, 0.1, 0.0])
    for seed in range(5):
        g = random_spline_guess(youbot, BoundaryState(q=Q_START, v=v0), (Q_GOAL, v1), 30, seed=seed)
        np.testing.assert_allclose(g.q[0], Q_START, atol=1e-9)
        np.testing.assert_allclose(g.q[-1], Q_GOAL, atol=1e-9)
        np.testing.assert_allclose(g.v[0], v0, atol=1e-9)
        np.testing.assert_allclose(g.v[-1], v1, atol=1e-9)


@pytest.mark.parametrize("bound_scale", [1.0, 0.85])
def test_limits_met_at_every_knot(youbot, bound_scale) -> None:
    """Positions and speeds lie inside the scaled limits at every knot (exactly, no tolerance)."""
    lower, upper = bound_scale * youbot.q_lower, bound_scale * youbot.q_upper
    vmax = bound_scale * youbot.velocity_limit
    for seed in range(10):
        # 2 s for a 2.1 rad move of joint 3: speed limits bind (1.57 rad/s at 100 %).
        g = _guess(youbot, seed, n=21, dt=0.1, bound_scale=bound_scale)
        assert np.all(g.q >= lower) and np.all(g.q <= upper)
        assert np.all(np.abs(g.v) <= vmax)


def test_time_grid_and_interpolation(youbot) -> None:
    """Knots at k dt, duration (N - 1) dt, trapezoidal interpolation."""
    g = _guess(youbot, 0, n=50, dt=0.1)
    np.testing.assert_allclose(g.t, 0.1 * np.arange(50), rtol=0, atol=1e-15)
    assert g.duration == pytest.approx(4.9, rel=1e-15)
    assert g.interpolation == "trapezoidal"


def test_velocity_acceleration_torque_consistent(youbot) -> None:
    """v, a are the derivatives of the knot polynomial; tau = RNEA(q, v, a) + b v."""
    g = _guess(youbot, 3, n=30)
    model, data = youbot.model, youbot.model.createData()
    for j in range(3):
        # Degree <= 6 through 30 knots: a least-squares fit of degree 6 recovers the
        # polynomial (residual at rounding level; conditioning of t in [0, 2.9] s
        # costs ~1e-9 on the derivatives).
        coef = np.polynomial.polynomial.polyfit(g.t, g.q[:, j], 6)
        np.testing.assert_allclose(
            np.polynomial.polynomial.polyval(g.t, coef), g.q[:, j], atol=1e-10
        )
        dcoef = np.polynomial.polynomial.polyder(coef)
        np.testing.assert_allclose(
            np.polynomial.polynomial.polyval(g.t, dcoef), g.v[:, j], atol=1e-7
        )
        np.testing.assert_allclose(
            np.polynomial.polynomial.polyval(g.t, np.polynomial.polynomial.polyder(dcoef)),
            g.a[:, j],
            atol=1e-6,
        )
    expected = np.array(
        [pin.rnea(model, data, q, v, a) + 0.1 * v for q, v, a in zip(g.q, g.v, g.a, strict=True)]
    )
    np.testing.assert_allclose(g.tau, expected, rtol=0, atol=1e-12)


def test_orders_are_polynomial_degrees(youbot) -> None:
    """orders=(4,) gives quartics (degree-4 fits exact, degree-3 fits not)."""
    g = _guess(youbot, 5, n=30, orders=(4,))
    s = g.t / g.duration
    for j in range(3):
        res4 = g.q[:, j] - np.polynomial.polynomial.polyval(
            s, np.polynomial.polynomial.polyfit(s, g.q[:, j], 4)
        )
        res3 = g.q[:, j] - np.polynomial.polynomial.polyval(
            s, np.polynomial.polynomial.polyfit(s, g.q[:, j], 3)
        )
        assert np.max(np.abs(res4)) < 1e-12
        assert np.max(np.abs(res3)) > 1e-6


def test_reproducible_and_seed_dependent(youbot) -> None:
    """The same seed gives identical guesses; different seeds give different ones."""
    a, b = _guess(youbot, 7), _guess(youbot, 7)
    np.testing.assert_array_equal(a.q, b.q)
    np.testing.assert_array_equal(a.tau, b.tau)
    c = _guess(youbot, np.random.default_rng(7))
    np.testing.assert_array_equal(a.q, c.q)
    others = [_guess(youbot, seed) for seed in (8, 9)]
    for other in others:
        assert np.max(np.abs(other.q - a.q)) > 1e-3


def test_bernstein_basis_is_a_partition_of_unity() -> None:
    """Bernstein polynomials sum to one and reproduce s (linear precision), to 1e-15."""
    s = np.linspace(0.0, 1.0, 11)
    basis = bernstein_matrix(5, s)
    np.testing.assert_allclose(basis.sum(axis=1), 1.0, atol=1e-15)
    np.testing.assert_allclose(basis @ (np.arange(6) / 5), s, atol=1e-15)


def test_impossible_requests_raise(youbot) -> None:
    """Start outside limits, a move too fast for the speed limit, bad sizes: ParameterError."""
    outside = Q_START.copy()
    outside[0] = youbot.q_upper[0] + 0.1
    with pytest.raises(ParameterError, match=r"start\.q\[0\]"):
        random_spline_guess(youbot, (outside, np.zeros(3)), (Q_GOAL, np.zeros(3)), 20, seed=0)
    with pytest.raises(ParameterError, match=r"goal\.v\[1\]"):
        random_spline_guess(youbot, Q_START, (Q_GOAL, np.array([0.0, 2.0, 0.0])), 20, seed=0)
    # 2.1 rad for joint 3 in 0.4 s needs 5.2 rad/s on average, above 1.57 rad/s.
    with pytest.raises(ParameterError, match="no polynomial of degree"):
        random_spline_guess(
            youbot, (Q_START, np.zeros(3)), (Q_GOAL, np.zeros(3)), 5, seed=0, dt=0.1
        )
    with pytest.raises(ParameterError, match="n_knots"):
        random_spline_guess(youbot, Q_START, Q_GOAL, 1, seed=0)
    with pytest.raises(ParameterError, match="orders"):
        random_spline_guess(youbot, Q_START, Q_GOAL, 20, seed=0, orders=(2,))
    with pytest.raises(ParameterError, match=r"start\.q must"):
        random_spline_guess(youbot, Q_START[:2], Q_GOAL, 20, seed=0)


@pytest.mark.parametrize("n", [5, 50])
def test_default_time_step_is_the_multistart_one(youbot, n) -> None:
    """Default dt = default_dt0 (4.9 s in all): 5 knots now get a feasible, slow guess."""
    from youbot_opt.reproduction.study1 import study1_problem
    from youbot_opt.trajopt.sweep import default_dt0

    g = _guess(youbot, 0, n=n)
    dt0 = default_dt0(study1_problem(n))
    # Same arithmetic (4.9 / (n - 1)) on both sides: equal to round-off of k * dt.
    np.testing.assert_allclose(g.t, dt0 * np.arange(n), rtol=1e-15, atol=1e-15)
    assert g.duration == pytest.approx(4.9, rel=1e-15)
    assert np.all(np.abs(g.v) <= youbot.velocity_limit)  # the LP's knot limits, exactly


@pytest.mark.parametrize("degree", [4, 5, 6])
def test_bernstein_derivative_matrix_matches_the_power_basis(degree) -> None:
    """Derivative matrices of orders 0-2 equal the derivatives of the expanded polynomial."""
    from numpy.polynomial import Polynomial

    from youbot_opt.trajopt.spline_guess import bernstein_derivative_matrix

    rng = np.random.default_rng(degree)
    points, duration = rng.normal(size=degree + 1), 4.9  # [rad], [s]
    s = np.linspace(0.0, 1.0, 17)
    # q(t) = sum_j b_j C(p, j) s^j (1 - s)^(p - j), s = t / T, expanded in powers of t.
    t = Polynomial([0.0, 1.0 / duration])
    q = sum(
        (b * math.comb(degree, j) * t**j * (1 - t) ** (degree - j) for j, b in enumerate(points)),
        Polynomial([0.0]),
    )
    for order in range(3):
        expected = q.deriv(order)(s * duration) if order else q(s * duration)
        got = bernstein_derivative_matrix(degree, duration, order, s) @ points
        # Values below 10 (rad, rad/s, rad/s^2) here: 1e-12 bounds the rounding of a few
        # dozen products, far below any wrong coefficient (>= 1e-2).
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12)


def test_spline_constraints_rows_margins_and_boundary() -> None:
    """The LP rows: exact boundary states, margins inside the limits, infinite limits omitted."""
    from youbot_opt.trajopt.spline_guess import bernstein_derivative_matrix, spline_constraints

    degree, n, duration = 5, 11, 2.0
    s = np.linspace(0.0, 1.0, n)
    points = np.array([0.1, 0.3, -0.2, 0.4, 0.0, -0.1])
    ends = np.array([0.0, 1.0])
    q_end = bernstein_derivative_matrix(degree, duration, 0, ends) @ points
    v_end = bernstein_derivative_matrix(degree, duration, 1, ends) @ points
    boundary = (q_end[0], v_end[0], q_end[1], v_end[1])
    lp = spline_constraints(degree, s, duration, boundary, (-1.0, 2.0, 3.0))
    np.testing.assert_allclose(lp.a_eq @ points, lp.b_eq, rtol=0, atol=1e-12)
    # Positions at the N - 2 interior knots, both sides; speeds at all N knots, both sides.
    assert lp.a_ub.shape == (2 * (n - 2) + 2 * n, degree + 1)
    # Margins: 1e-7 of the half range (1.5 rad) and of vmax (3 rad/s).
    assert lp.b_ub[0] == pytest.approx(2.0 - 1.5e-7, rel=0, abs=1e-15)
    assert lp.b_ub[n - 2] == pytest.approx(1.0 - 1.5e-7, rel=0, abs=1e-15)
    assert lp.b_ub[-1] == pytest.approx(3.0 - 3e-7, rel=0, abs=1e-15)
    unlimited = spline_constraints(degree, s, duration, boundary, (-math.inf, math.inf, 3.0))
    assert unlimited.a_ub.shape == (2 * n, degree + 1)
    free = spline_constraints(degree, s, duration, boundary, (-math.inf, math.inf, math.inf))
    assert free.a_ub.shape == (0, degree + 1) and free.b_ub.shape == (0,)
