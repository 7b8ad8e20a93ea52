"""IK-path result: joint path for replay, status handling, summary."""

from __future__ import annotations

import numpy as np
import pytest

from youbot_opt.exceptions import ParameterError, SolveFailed
from youbot_opt.ikpath.examples import example_problem
from youbot_opt.ikpath.result import IKStatus
from youbot_opt.ikpath.solve import solve


@pytest.fixture(scope="module")
def result():
    return solve(example_problem("B"), method="al")


def test_joint_path_interpolates_and_closes_the_cycle(result):
    """The path passes through every configuration at s = j and ends at the first one."""
    path = result.joint_path(samples_per_segment=4)
    s_targets = result.problem.n_targets
    assert path.s.shape == (4 * s_targets + 1,) and path.q.shape == (4 * s_targets + 1, 3)
    np.testing.assert_array_equal(path.q[::4][:-1], result.configurations)
    np.testing.assert_array_equal(path.q[-1], result.configurations[0])
    mid = 0.5 * (result.configurations[0] + result.configurations[1])
    np.testing.assert_allclose(path.q[2], mid, atol=1e-15)
    with pytest.raises(ParameterError, match="samples_per_segment"):
        result.joint_path(0)


def test_result_is_read_only_and_verified(result):
    """Arrays are read-only; residuals are recomputed by Pinocchio; E alias and model exist."""
    with pytest.raises(ValueError):
        result.configurations[0, 0] = 1.0
    np.testing.assert_allclose(result.tip_positions(), result.problem.targets, atol=1e-9)
    assert result.E == result.objective
    assert result.model.nq == 3 and result.visual_model.ngeoms >= 3
    assert "E = 15.60589" in result.summary()


def test_raise_for_status(result):
    """Success returns the result; a failure raises SolveFailed carrying the result."""
    assert result.raise_for_status() is result
    failed = solve(example_problem("A"), method="ipopt", options=None, x0=None)
    assert failed.status is IKStatus.SUCCESS  # zero start converges (to a poor minimum) for IPOPT
    from youbot_opt.ikpath.augmented_lagrangian import ALOptions

    capped = solve(example_problem("A"), options=ALOptions(max_outer_iterations=1))
    assert capped.status is IKStatus.MAX_ITERATIONS
    with pytest.raises(SolveFailed, match="max_iterations") as info:
        capped.raise_for_status()
    assert info.value.result is capped
