"""Cyclic IK-path problem: E, its gradient, constraints and input validation."""

from __future__ import annotations

import numpy as np
import pytest

from youbot_opt.exceptions import ParameterError
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.robot.planar import PlanarChain

TARGETS = [(5.0, 0.0), (4.0, 2.0), (6.0, 0.5), (4.0, -2.0)]


@pytest.fixture()
def problem() -> CyclicIKProblem:
    return CyclicIKProblem(
        robot=PlanarChain(lengths=[3.0, 2.0, 2.0], q_lower=-2.0, q_upper=2.0), targets=TARGETS
    )


def test_objective_is_half_the_cyclic_sum_of_squares(problem, rng):
    """E equals 1/2 sum |q_{j+1} - q_j|^2 including the closing term (1e-12)."""
    q = rng.uniform(-2, 2, (4, 3))
    expected = 0.5 * sum(np.sum((q[(j + 1) % 4] - q[j]) ** 2) for j in range(4))
    assert problem.objective(q) == pytest.approx(expected, abs=1e-12)


def test_gradients_match_finite_differences(problem, rng):
    """dE/dx and the constraint Jacobian blocks equal central differences (1e-7)."""
    x = rng.uniform(-2, 2, problem.n_variables)
    ev = problem.evaluate(x)
    h = 1e-6
    fd_e = [
        (problem.objective(x + h * e) - problem.objective(x - h * e)) / (2 * h)
        for e in np.eye(x.size)
    ]
    # E is quadratic: the central difference is exact up to rounding ~ eps * E / h ~ 1e-9
    np.testing.assert_allclose(ev.gradient, fd_e, atol=1e-7)
    jac = np.zeros((2 * problem.n_targets, x.size))
    for j in range(problem.n_targets):
        jac[2 * j : 2 * j + 2, 3 * j : 3 * j + 3] = ev.jacobian_blocks[j]
    fd_c = np.column_stack(
        [
            (problem.constraints(x + h * e) - problem.constraints(x - h * e)) / (2 * h)
            for e in np.eye(x.size)
        ]
    )
    # truncation h^2 * |F'''| <= 1e-12 * 7, rounding ~ 1e-10
    np.testing.assert_allclose(jac, fd_c, atol=1e-7)


def test_constraints_and_residuals(problem):
    """c stacks F(q_j) - p_j; residuals are their norms (1e-12)."""
    q = np.zeros((4, 3))  # straight arm along x: tip (7, 0)
    c = problem.constraints(q).reshape(4, 2)
    np.testing.assert_allclose(c, np.array([(7.0, 0.0)] * 4) - np.array(TARGETS), atol=1e-12)
    np.testing.assert_allclose(problem.residuals(q), np.linalg.norm(c, axis=1), atol=1e-12)


def test_limits_and_start_checks(problem):
    """Bounds tile the chain limits; a start outside them is rejected naming the value."""
    np.testing.assert_array_equal(problem.lower, np.full(12, -2.0))
    assert problem.limit_violation(np.full(12, 2.5)) == pytest.approx(0.5)
    with pytest.raises(ParameterError, match=r"configuration 1, joint 2 is 2\.5 rad"):
        problem.check_start(np.r_[np.zeros(5), 2.5, np.zeros(6)])
    free = CyclicIKProblem(robot=problem.chain, targets=TARGETS, use_limits=False)
    assert not free.bounded
    np.testing.assert_array_equal(free.check_start(np.full(12, 2.5)), np.full(12, 2.5))


def test_default_start_is_clipped_zero():
    """The zero start is clipped into limits that exclude zero."""
    chain = PlanarChain(lengths=[1.0, 1.0], q_lower=[0.5, -1.0], q_upper=[1.0, 1.0])
    prob = CyclicIKProblem(robot=chain, targets=[(1.0, 1.0), (0.5, 1.2)])
    np.testing.assert_array_equal(prob.default_start(), [0.5, 0.0, 0.5, 0.0])


@pytest.mark.parametrize(
    ("targets", "match"),
    [
        ([(1.0, 0.0)], "at least 2 targets"),
        ([(1.0, 0.0, 0.5), (0.0, 1.0, 0.0)], "lies 0.5 m off it"),
        ([1.0, 2.0], r"shape \(s, 2\)"),
        ([(1.0, np.nan), (0.0, 1.0)], "finite"),
    ],
)
def test_bad_targets_raise(targets, match):
    """Fewer than 2 targets, wrong shapes and NaN are ParameterErrors."""
    with pytest.raises(ParameterError, match=match):
        CyclicIKProblem(robot=PlanarChain(lengths=[1.0, 1.0]), targets=targets)


def test_wrong_x_size_raises(problem):
    """An iterate of the wrong size names the expected shapes."""
    with pytest.raises(ParameterError, match=r"\(12,\) or \(4, 3\)"):
        problem.objective(np.zeros(11))


def test_default_start_is_finite_with_one_sided_limits():
    """Limits with -inf/+inf sides give a finite clipped zero start (no 'x must be finite')."""
    chain = PlanarChain(lengths=[1.0, 1.0], q_lower=[0.2, -np.inf], q_upper=[np.inf, -0.1])
    prob = CyclicIKProblem(robot=chain, targets=[(1.0, 1.0), (0.5, 1.2)])
    np.testing.assert_array_equal(prob.default_start(), [0.2, -0.1, 0.2, -0.1])
