"""Planar chain: Pinocchio kinematics against the study's formula, validation, pickling."""

from __future__ import annotations

import pickle

import numpy as np
import pinocchio as pin
import pytest

from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.planar import PlanarChain


def _fk_formula(lengths, base, offset, q):
    """The study's F(theta) = b + sum_i l_i (cos phi_i, sin phi_i), phi = cumsum(q + offset)."""
    phi = np.cumsum(np.asarray(q) + offset)
    return base + np.array([np.sum(lengths * np.cos(phi)), np.sum(lengths * np.sin(phi))])


@pytest.mark.parametrize(
    ("lengths", "base", "offset"),
    [
        ([3.0, 2.0, 2.0], [0.0, 0.0], [0.0, 0.0, 0.0]),
        ([0.155, 0.135, 0.2175], [0.184, 0.147], [np.pi / 2, 0.0, 0.0]),
        ([1.0, 0.5, 0.7, 0.2, 0.9, 1.3, 0.4], [1.0, -2.0], [0.3, -0.1, 0.0, 0.2, 0.0, 0.0, 1.0]),
    ],
)
def test_tip_matches_study_formula(lengths, base, offset, rng):
    """Pinocchio's tip position equals the closed-form planar FK at 20 random q (1e-12 m)."""
    chain = PlanarChain(lengths=lengths, base=base, angle_offset=offset)
    for _ in range(20):
        q = rng.uniform(-4.0, 4.0, chain.n)
        # sums of a few O(1) terms: rounding is ~1e-15, 1e-12 leaves room but catches any error
        np.testing.assert_allclose(
            chain.tip_position(q), _fk_formula(np.array(lengths), base, offset, q), atol=1e-12
        )


def test_jacobian_matches_finite_differences(rng):
    """The Pinocchio tip Jacobian equals central differences of the formula (1e-8)."""
    lengths = np.array([3.0, 2.0, 2.0, 1.0])
    chain = PlanarChain(lengths=lengths, base=[0.5, 0.2], angle_offset=[0.1, 0.0, -0.2, 0.0])
    h = 1e-6
    for _ in range(10):
        q = rng.uniform(-np.pi, np.pi, chain.n)
        fd = np.column_stack(
            [
                (
                    _fk_formula(lengths, chain.base, chain.angle_offset, q + h * e)
                    - _fk_formula(lengths, chain.base, chain.angle_offset, q - h * e)
                )
                / (2 * h)
                for e in np.eye(chain.n)
            ]
        )
        # central-difference truncation error ~ h^2 |F'''| ~ 1e-11 and rounding ~ eps/h ~ 1e-10
        np.testing.assert_allclose(chain.tip_jacobian(q), fd, atol=1e-8)


def test_joint_positions_are_segment_ends():
    """Joint positions are the partial sums of the segments; the last row is the tip (1e-12)."""
    chain = PlanarChain(lengths=[3.0, 2.0, 2.0])
    pts = chain.joint_positions([np.pi / 2, -np.pi / 2, np.pi / 2])
    expected = [[0, 0], [0, 3], [2, 3], [2, 5]]
    np.testing.assert_allclose(pts, expected, atol=1e-12)


def test_reach_is_the_annulus():
    """Reach radii: (0, sum) normally, (l_max - rest, sum) when one link dominates."""
    assert PlanarChain(lengths=[3.0, 2.0, 2.0]).reach == (0.0, 7.0)
    assert PlanarChain(lengths=[5.0, 1.0, 1.5]).reach == (2.5, 7.5)


def test_limits_broadcast_and_reach_the_model():
    """Scalar limits broadcast to every joint and are the Pinocchio model's limits."""
    chain = PlanarChain(lengths=[1.0, 1.0], q_lower=-1.0, q_upper=[1.0, 2.0])
    np.testing.assert_array_equal(chain.q_lower, [-1.0, -1.0])
    np.testing.assert_array_equal(chain.model.upperPositionLimit, [1.0, 2.0])
    assert chain.bounded
    assert not PlanarChain(lengths=[1.0, 1.0]).bounded


def test_pickle_round_trip_rebuilds_the_model():
    """A pickled chain (sent to worker processes) computes the same kinematics."""
    chain = PlanarChain(lengths=[3.0, 2.0, 2.0], q_lower=-1.5, q_upper=1.5, base=[1.0, 2.0])
    copy = pickle.loads(pickle.dumps(chain))
    q = [0.3, -0.2, 0.9]
    np.testing.assert_array_equal(copy.tip_position(q), chain.tip_position(q))
    np.testing.assert_array_equal(copy.q_upper, chain.q_upper)


def test_visual_model_has_a_cylinder_per_link():
    """The replay geometry holds one cylinder per link plus joint and tip spheres."""
    chain = PlanarChain(lengths=[3.0, 2.0, 2.0])
    names = [g.name for g in chain.visual_model.geometryObjects]
    assert [n for n in names if n.startswith("link_")] == ["link_1", "link_2", "link_3"]
    assert "tip_ball" in names


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"lengths": [1.0, 0.0]}, "lengths must be finite and > 0"),
        ({"lengths": [1.0, -2.0]}, "lengths must be finite and > 0"),
        ({"lengths": [1.0, np.inf]}, "lengths must be finite and > 0"),
        ({"lengths": [1.0, np.nan]}, "lengths must be finite and > 0"),
        ({"lengths": []}, "non-empty"),
        ({"lengths": [1.0, 1.0], "q_lower": 1.0, "q_upper": 0.5}, r"q_lower\[0\] = 1.0 > q_upper"),
        ({"lengths": [1.0, 1.0], "q_lower": [0, 0, 0]}, r"shape \(2,\)"),
        ({"lengths": [1.0, 1.0], "base": [0.0]}, "base must be a finite 2-vector"),
    ],
)
def test_bad_chains_raise_parameter_error(kwargs, match):
    """Non-positive, non-finite lengths, crossed limits and bad shapes are rejected by name."""
    with pytest.raises(ParameterError, match=match):
        PlanarChain(**kwargs)


def test_bad_configuration_shape_raises():
    """A configuration of the wrong length or with NaN is a ParameterError."""
    chain = PlanarChain(lengths=[1.0, 1.0])
    with pytest.raises(ParameterError, match=r"shape \(2,\)"):
        chain.tip_position([0.0, 0.0, 0.0])
    with pytest.raises(ParameterError, match="finite"):
        chain.tip_position([0.0, np.nan])


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"q_lower": np.inf, "q_upper": np.inf}, r"q_lower\[0\] = inf leaves joint 0 no value"),
        ({"q_lower": -np.inf, "q_upper": -np.inf}, r"q_upper\[0\] = -inf leaves joint 0"),
        ({"q_lower": [0.0, np.inf], "q_upper": 1.0}, r"q_lower\[1\] = inf"),
        ({"q_lower": [0.0, np.nan]}, "q_lower contains NaN"),
    ],
)
def test_infinite_limits_that_leave_no_value_are_rejected(kwargs, match):
    """+inf as a lower or -inf as an upper limit is an empty range: ParameterError naming it."""
    with pytest.raises(ParameterError, match=match):
        PlanarChain(lengths=[1.0, 1.0], **kwargs)


def test_infinite_limits_on_their_own_side_mean_no_limit():
    """-inf lower / +inf upper equal None: unbounded joint, Pinocchio's max-float limit."""
    chain = PlanarChain(lengths=[1.0, 1.0], q_lower=[-np.inf, -1.0], q_upper=[np.inf, 1.0])
    assert chain.bounded  # joint 2 is limited
    free = PlanarChain(lengths=[1.0, 1.0], q_lower=-np.inf, q_upper=np.inf)
    assert not free.bounded
    assert free.model.upperPositionLimit[0] == np.finfo(float).max
    np.testing.assert_array_equal(chain.model.lowerPositionLimit, [-np.finfo(float).max, -1.0])


def test_chain_as_robot_model_has_the_chain_kinematics():
    """PlanarChain.robot() is a RobotModel on the chain's own model: same tip (exactly)."""
    chain = PlanarChain(lengths=[3, 2, 2], q_lower=-1.5, q_upper=1.5, base=(0.5, -1.0))
    robot = chain.robot()
    assert robot.model is chain.model and robot.tip_frame == chain.tip_frame
    np.testing.assert_array_equal(robot.q_lower, chain.q_lower)
    q = np.array([0.3, -0.7, 1.1])
    data = robot.create_data()

    pin.framesForwardKinematics(robot.model, data, q)
    np.testing.assert_array_equal(
        data.oMf[robot.frame_id(robot.tip_frame)].translation[:2], chain.tip_position(q)
    )
