"""CasADi distances: primitives and pairs against coal, gradients against finite differences."""

from __future__ import annotations

import casadi as ca
import coal
import numpy as np
import pytest

from youbot_opt.collision import Box, Capsule, Cylinder, HalfSpace, Obstacle, Scene
from youbot_opt.collision import distance as dist
from youbot_opt.collision.exact import exact_checker
from youbot_opt.collision.model import CollisionModel, build_collision_model, joint_placements
from youbot_opt.dynamics.symbolic import build_symbolic_model
from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.model import RobotModel

#: coal's GJK/EPA stops at a relative precision of 1e-6 on distances of at most 1 m
COAL_ATOL = 1e-5  # [m]


def _random_q(robot: RobotModel, rng: np.random.Generator) -> np.ndarray:
    lo = np.maximum(robot.model.lowerPositionLimit, -np.pi)
    hi = np.minimum(robot.model.upperPositionLimit, np.pi)
    return rng.uniform(lo, hi)


@pytest.mark.parametrize(
    ("shape", "expr", "solid"),
    [
        (
            Box(size=(0.4, 0.2, 0.1)),
            lambda x: dist.point_box_distance(x, np.array([0.2, 0.1, 0.05])),
            coal.Box(0.4, 0.2, 0.1),
        ),
        (
            Cylinder(radius=0.1, length=0.4),
            lambda x: dist.point_cylinder_distance(x, 0.1, 0.2),
            coal.Cylinder(0.1, 0.4),
        ),
        (
            Capsule(radius=0.1, length=0.4),
            lambda x: dist.point_capsule_distance(x, 0.1, 0.2),
            coal.Capsule(0.1, 0.4),
        ),
        (
            HalfSpace(),
            dist.point_halfspace_distance,
            coal.Halfspace(np.array([0.0, 0.0, 1.0]), 0.0),
        ),
    ],
)
def test_primitive_distance_equals_coal(shape, expr, solid, rng):
    """A point's signed distance to each primitive equals coal's (a point: a 1e-9 m ball)."""
    x = ca.SX.sym("x", 3)
    f = ca.Function("d", [x], [expr(x)])
    point, request = coal.Sphere(1e-9), coal.DistanceRequest()
    for p in rng.uniform(-0.4, 0.4, size=(200, 3)):
        result = coal.DistanceResult()
        exact = coal.distance(
            point, coal.Transform3s(np.eye(3), p), solid, coal.Transform3s(), request, result
        )
        ours = float(f(p))
        if exact > COAL_ATOL:  # outside: ours is at most NORM_EPS below coal's exact distance
            assert exact + 1e-9 - dist.NORM_EPS - COAL_ATOL <= ours <= exact + 1e-9 + COAL_ATOL, (
                p,
                ours,
                exact,
            )
        elif exact < -COAL_ATOL:
            # inside: both negative; coal's EPA depth on curved solids is approximate (it
            # reported 0.066 m for a point 0.029 m below a cylinder's cap), so only the sign
            assert ours < 0.0, (p, ours, exact)


def test_smoothing_bounds():
    """smooth_norm lies in [|x| - eps, |x|]; soft_min in [min - tau log n, min]."""
    for x in ([0.0, 0.0, 0.0], [1e-7, 0.0, 0.0], [0.3, -0.4, 1.2]):
        n = float(dist.smooth_norm(ca.DM(x)))
        assert np.linalg.norm(x) - dist.NORM_EPS <= n <= np.linalg.norm(x)
    values = ca.DM([0.3, 0.1, 0.1002, 2.0])
    s = float(dist.soft_min(values, 1e-3))
    assert 0.1 - 1e-3 * np.log(4) <= s <= 0.1
    assert float(dist.soft_min(values, 0.0)) == 0.1


def _q_function(cm: CollisionModel, robot: RobotModel) -> ca.Function:
    distances = cm.configuration_function(build_symbolic_model(robot).forward_kinematics)
    q = ca.SX.sym("q", robot.nq)
    d = distances(q)
    return ca.Function("d_q", [q], [d, ca.jacobian(d, q)])


def test_configuration_function_refuses_another_layout(ur5_cell: CollisionModel):
    """A kinematics Function of another robot's size is refused, naming both layouts."""
    q = ca.SX.sym("q", 2)
    other = ca.Function("fk", [q], [ca.SX.zeros(3, 6), ca.SX.zeros(3, 2)])
    with pytest.raises(ParameterError, match=r"must return rotations \(3, 18\)"):
        ur5_cell.configuration_function(other)


def test_gradients_match_finite_differences(ur5: RobotModel, ur5_cell: CollisionModel, rng):
    """dd/dq of every pair (via the symbolic kinematics) matches central differences (10 q)."""
    f = _q_function(ur5_cell, ur5)
    h = 1e-6  # [rad]
    for _ in range(10):
        q = _random_q(ur5, rng)
        d, jac = (np.asarray(v) for v in f(q))
        np.testing.assert_allclose(d.ravel(), ur5_cell.distances(ur5, q), atol=1e-12)
        fd = np.column_stack(
            [
                (np.asarray(f(q + h * e)[0]) - np.asarray(f(q - h * e)[0])).ravel() / (2 * h)
                for e in np.eye(ur5.nq)
            ]
        )
        # central differences: O(h^2) truncation and 1e-16/h round-off; 1e-6 [m/rad] covers both
        np.testing.assert_allclose(jac, fd, atol=1e-6)


def _check_against_coal(cm: CollisionModel, robot: RobotModel, rng, n: int) -> int:
    checker = exact_checker(cm, robot)
    function = cm.distance_function()
    tol = cm.tolerance
    separated = 0
    for _ in range(n):
        q = _random_q(robot, rng)
        model = np.asarray(function(*joint_placements(robot, q))).ravel()
        exact = checker.distances(robot, q)
        apart = exact > COAL_ATOL
        separated += int(apart.sum())
        # conservative: never above the exact distance for separated pairs ...
        assert np.all(model[apart] <= exact[apart] + COAL_ATOL), cm.pair_names
        # ... and within the reported tolerance (overshoots, smoothing) of it
        assert np.all(exact[apart] - model[apart] <= tol[apart] + COAL_ATOL)
        # a touching or penetrating pair is never called free
        assert np.all(model[exact < -COAL_ATOL] < 0.0)
    return separated


def test_ur5_conservative_against_coal(ur5: RobotModel, ur5_cell: CollisionModel, rng):
    """ur5 in the cell at 30 random q: model <= coal and coal - model <= tolerance, pair by pair."""
    assert ur5_cell.n_pairs == 16 + 5 * 7  # 16 self pairs, 5 obstacles x 7 moving geometries
    assert _check_against_coal(ur5_cell, ur5, rng, 30) > 500


def test_panda_conservative_against_coal(panda: RobotModel, cell: Scene, rng):
    """panda in the cell with a box carried by its hand, (20 q): conservative, within tolerance."""
    held = Obstacle(
        name="held", shape=Box(size=(0.05, 0.05, 0.05)), xyz=(0.0, 0.0, 0.15), frame="panda_hand"
    )
    cm = build_collision_model(panda, cell + held)
    assert any(name == ("panda_link5_0", "held") for name in cm.pair_names)
    assert not any(name == ("panda_hand_0", "held") for name in cm.pair_names)  # it holds it
    assert _check_against_coal(cm, panda, rng, 20) > 500


def test_joint_placements_layout_is_the_symbolic_kinematics(ur5: RobotModel, rng):
    """joint_placements(q) is SymbolicModel.forward_kinematics(q): the Function's input layout."""
    symbolic = build_symbolic_model(ur5)
    for _ in range(5):
        q = _random_q(ur5, rng)
        rotations, translations = joint_placements(ur5, q)
        sym_rot, sym_pos = symbolic.forward_kinematics(q)
        np.testing.assert_allclose(rotations, np.asarray(sym_rot), atol=1e-12)
        np.testing.assert_allclose(translations, np.asarray(sym_pos), atol=1e-12)
