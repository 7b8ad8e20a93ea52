"""The youBot arm as a planar chain: same tip as the robot model, IK paths of the real arm."""

from __future__ import annotations

import numpy as np
import pytest

from youbot_opt.exceptions import ModelError
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.solve import solve
from youbot_opt.robot.load import load_model
from youbot_opt.robot.model import tip_pose
from youbot_opt.robot.planar import chain_from_robot


@pytest.fixture(scope="module")
def robot(youbot):
    """The session's youBot model (conftest)."""
    return youbot


@pytest.fixture(scope="module")
def chain(robot):
    return chain_from_robot(robot)


def test_chain_matches_the_spec_table(chain):
    """The four tip poses of the spec table (a = 0.184, h = 0.147) are reproduced (1e-12 m)."""
    a, h, l1, l2, l3 = 0.184, 0.147, 0.155, 0.135, 0.2175
    table = {
        (0, 0, 0): (a, h + l1 + l2 + l3),
        (0, np.pi / 2, 0): (a - l2 - l3, h + l1),
        (-np.pi / 2, np.pi / 2, -np.pi / 2): (a + l1 + l3, h + l2),
        (np.pi, -np.pi, np.pi): (a, h - l1 + l2 - l3),
    }
    for q, p in table.items():
        np.testing.assert_allclose(chain.tip_position(q), p, atol=1e-12)
    np.testing.assert_allclose(chain.angle_offset, [np.pi / 2, 0, 0], atol=1e-12)


def test_chain_matches_robot_tip_pose(chain, robot, rng):
    """At 30 random configurations the chain's tip equals model.tip_pose (1e-12 m)."""
    for q in rng.uniform(robot.q_lower, robot.q_upper, (30, 3)):
        np.testing.assert_allclose(chain.tip_position(q), tip_pose(robot, q).position, atol=1e-12)
    np.testing.assert_array_equal(chain.q_lower, robot.q_lower)


def test_youbot_ik_path_through_tool_tip_targets(chain, robot):
    """A joint path of the real arm reaches the targets (robot FK, 1.5e-10 m) within its limits."""
    targets = [(0.30, 0.30), (0.10, 0.50), (0.35, 0.10), (0.25, 0.45)]
    res = solve(CyclicIKProblem(robot=chain, targets=targets), method="al").raise_for_status()
    # AL accepts |c|_inf <= 1e-10 m, so |c_j|_2 <= sqrt(2) 1e-10 m; the robot's FK
    # differs from the chain's by <= 1e-12 m (test above): 1.5e-10 m covers both
    for q, p in zip(res.configurations, targets, strict=True):
        assert np.linalg.norm(tip_pose(robot, q).position - p) < 1.5e-10
    assert np.all(res.configurations >= robot.q_lower) and np.all(
        res.configurations <= robot.q_upper
    )
    ipopt = solve(
        CyclicIKProblem(robot=chain, targets=targets), method="ipopt", x0=res.configurations
    )
    assert ipopt.success, ipopt.message
    # Not double-precision FK but two optimisers' E, so not tightened: both stop at
    # stationarity 1e-8 (E error second order), and the AL's |c_j| <= sqrt(2) 1e-10 m
    # with |lambda_j| <= 6.8 [rad^2/m] here allow a first-order E error up to
    # 4 * 6.8 * 1.4e-10 = 3.8e-9; 1e-8 covers it (measured 1.3e-12)
    assert ipopt.objective == pytest.approx(res.objective, abs=1e-8)


def test_non_planar_robot_is_refused():
    """A spatial arm (UR5) is not a planar x-z chain: ModelError."""
    with pytest.raises(ModelError, match="not a"):
        chain_from_robot(load_model("ur5"))
