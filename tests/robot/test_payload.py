"""Tests of payloads (youbot_opt.robot.payload): known answers, an energy oracle, records."""

from __future__ import annotations

import json

import numpy as np
import pinocchio as pin
import pytest

from youbot_opt.dynamics.base import build_dynamics
from youbot_opt.exceptions import FrameNotFound, ParameterError
from youbot_opt.reproduction.study1 import study1_problem
from youbot_opt.robot.load import load_model
from youbot_opt.robot.payload import Payload
from youbot_opt.robot.planar import PlanarChain
from youbot_opt.robot.source import RobotSource
from youbot_opt.trajopt.io import load_result, save_result
from youbot_opt.trajopt.solver import solve

MASS = 0.75  # [kg]


def _mass_and_gravity(model: pin.Model, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    data = model.createData()
    mass = pin.crba(model, data, q)
    mass = np.triu(mass) + np.triu(mass, 1).T
    gravity = pin.rnea(model, data, q, np.zeros(model.nv), np.zeros(model.nv))
    return mass, gravity


def _linear_jacobian(model: pin.Model, frame: int, q: np.ndarray) -> np.ndarray:
    data = model.createData()
    jac = pin.computeFrameJacobian(model, data, q, frame, pin.LOCAL_WORLD_ALIGNED)
    return np.reshape(jac, (6, model.nv))[:3]


def _configurations(robot, rng, count=10):
    lo, hi = robot.q_lower, robot.q_upper
    return [rng.uniform(lo, hi) for _ in range(count)]


def test_point_mass_at_the_tip_changes_m_and_gravity_by_the_known_answer(youbot, rng):
    """A point mass m at the tip adds m J^T J to M(q) and -m J^T g to the gravity torque (1e-10)."""
    carrying = youbot.with_payload(Payload(mass=MASS))
    assert carrying.payload is not None and carrying.payload.frame == youbot.tip_frame
    frame = youbot.frame_id(youbot.tip_frame)
    g = np.asarray(youbot.model.gravity.linear)
    assert np.linalg.norm(g) > 9.0  # gravity acts in the arm's plane: the test has teeth
    for q in _configurations(youbot, rng):
        m0, g0 = _mass_and_gravity(youbot.model, q)
        m1, g1 = _mass_and_gravity(carrying.model, q)
        jac = _linear_jacobian(youbot.model, frame, q)
        np.testing.assert_allclose(m1 - m0, MASS * jac.T @ jac, atol=1e-10)
        np.testing.assert_allclose(g1 - g0, -MASS * jac.T @ g, atol=1e-10)


def test_the_casadi_dynamics_see_the_payload(youbot, rng):
    """The CasADi inverse dynamics of the carrying arm change by the same known answer (1e-10)."""
    carrying = youbot.with_payload(Payload(mass=MASS))
    frame = youbot.frame_id(youbot.tip_frame)
    g = np.asarray(youbot.model.gravity.linear)
    before = build_dynamics(youbot, damping=False)
    after = build_dynamics(carrying, damping=False)
    nv, zero = youbot.nv, np.zeros(youbot.nv)

    def mass_and_gravity(dyn, q):
        gravity = np.asarray(dyn.inverse(q, zero, zero)).ravel()
        cols = [np.asarray(dyn.inverse(q, zero, e)).ravel() - gravity for e in np.eye(nv)]
        return np.column_stack(cols), gravity

    for q in _configurations(youbot, rng, 5):
        m0, g0 = mass_and_gravity(before, q)
        m1, g1 = mass_and_gravity(after, q)
        jac = _linear_jacobian(youbot.model, frame, q)
        np.testing.assert_allclose(m1 - m0, MASS * jac.T @ jac, atol=1e-10)
        np.testing.assert_allclose(g1 - g0, -MASS * jac.T @ g, atol=1e-10)
        tau = np.array([0.3, -0.2, 0.1])
        expected = pin.aba(carrying.model, carrying.create_data(), q, zero, tau)
        np.testing.assert_allclose(
            np.asarray(after.forward(q, zero, tau)).ravel(), expected, atol=1e-9
        )


def test_massless_planar_chain_gets_exactly_m_jt_j():
    """On a massless planar chain, M(q) of the carrying chain is m J^T J itself (1e-12)."""
    chain = PlanarChain(lengths=[0.5, 0.4, 0.3])
    robot = chain.robot().with_payload(Payload(mass=2.0))
    q = np.array([0.3, -0.7, 1.1])
    mass, _ = _mass_and_gravity(robot.model, q)
    jac = chain.tip_jacobian(q)  # (2, n): x and y, the chain's plane
    np.testing.assert_allclose(mass, 2.0 * jac.T @ jac, atol=1e-12)


def test_a_general_payload_adds_its_kinetic_and_potential_energy(youbot, rng):
    """An offset payload with inertia in another frame adds its kinetic and potential energy."""
    frame_name = youbot.model.frames[youbot.frame_id(youbot.tip_frame)].name
    other = [f.name for f in youbot.model.frames if f.name != frame_name and f.parentJoint > 0][0]
    inertia = np.array([[0.02, 0.003, -0.001], [0.003, 0.015, 0.002], [-0.001, 0.002, 0.01]])
    payload = Payload(mass=MASS, com=[0.03, -0.02, 0.05], inertia=inertia, frame=other)
    carrying = youbot.with_payload(payload)
    fid = youbot.frame_id(other)
    g = np.asarray(youbot.model.gravity.linear)

    def com_at(q):
        data = youbot.create_data()
        pin.framesForwardKinematics(youbot.model, data, q)
        return data.oMf[fid].translation + data.oMf[fid].rotation @ np.array(payload.com)

    for q in _configurations(youbot, rng, 5):
        v = rng.normal(size=youbot.nv)
        data = youbot.create_data()
        pin.forwardKinematics(youbot.model, data, q, v)
        pin.updateFramePlacements(youbot.model, data)
        placement = data.oMf[fid]
        twist = pin.getFrameVelocity(youbot.model, data, fid, pin.LOCAL_WORLD_ALIGNED)
        rot = placement.rotation
        com_world = placement.translation + rot @ np.array(payload.com)
        v_com = twist.linear + np.cross(twist.angular, rot @ np.array(payload.com))
        energy = (
            0.5 * MASS * v_com @ v_com
            + 0.5 * twist.angular @ (rot @ inertia @ rot.T) @ twist.angular
        )
        m0, g0 = _mass_and_gravity(youbot.model, q)
        m1, g1 = _mass_and_gravity(carrying.model, q)
        assert 0.5 * v @ (m1 - m0) @ v == pytest.approx(energy, abs=1e-10)
        # gravity torque = d(potential)/dq, potential = -m g . c(q): central differences
        eps = 1e-6  # [rad]
        grad = [
            -MASS * g @ (com_at(q + eps * e) - com_at(q - eps * e)) / (2 * eps)
            for e in np.eye(youbot.nv)
        ]
        np.testing.assert_allclose(g1 - g0, grad, atol=1e-7)
        np.testing.assert_allclose(com_at(q), com_world, atol=1e-14)


def test_load_model_payload_equals_with_payload(youbot):
    """load_model(payload=) gives the model with_payload gives."""
    payload = Payload(mass=MASS, com=[0.0, 0.0, 0.01])
    loaded = load_model("youbot", payload=payload)
    attached = youbot.with_payload(payload)
    assert loaded.payload == attached.payload
    for a, b in zip(loaded.model.inertias, attached.model.inertias, strict=True):
        np.testing.assert_array_equal(a.toDynamicParameters(), b.toDynamicParameters())


def test_payload_checks(youbot):
    """Bad masses, centres, inertias and frames are refused with the field named."""
    with pytest.raises(ParameterError, match="mass"):
        Payload(mass=-1.0)
    with pytest.raises(ParameterError, match="mass"):
        Payload(mass=float("nan"))
    with pytest.raises(ParameterError, match="com"):
        Payload(mass=1.0, com=[0.0, 1.0])
    with pytest.raises(ParameterError, match="symmetric"):
        Payload(mass=1.0, inertia=[[1.0, 0.5, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    with pytest.raises(ParameterError, match="rigid body"):
        Payload(mass=1.0, inertia=[1.0, 1.0, 3.0])
    with pytest.raises(ParameterError, match="rigid body"):
        Payload(mass=1.0, inertia=[-1.0, 1.0, 1.0])
    np.testing.assert_array_equal(
        Payload(mass=1.0, inertia=[1.0, 0.1, 0.0, 2.0, 0.0, 2.5]).inertia,
        [[1.0, 0.1, 0.0], [0.1, 2.0, 0.0], [0.0, 0.0, 2.5]],
    )
    assert (
        Payload(mass=1.0, inertia=np.eye(3).ravel()).inertia
        == Payload(mass=1.0, inertia=[1.0, 1.0, 1.0]).inertia
    )
    with pytest.raises(ParameterError, match="9 values"):
        Payload(mass=1.0, inertia=[1.0, 2.0])
    with pytest.raises(FrameNotFound):
        youbot.with_payload(Payload(mass=1.0, frame="no_such_frame"))
    with pytest.raises(ParameterError, match="already carries"):
        youbot.with_payload(Payload(mass=1.0)).with_payload(Payload(mass=1.0))


def test_robot_source_records_and_reattaches_the_payload(youbot, tmp_path):
    """RobotSource writes the payload and loads the robot carrying it again."""
    payload = Payload(mass=MASS, com=[0.01, 0.0, 0.0], inertia=[1e-3, 2e-3, 2.5e-3])
    carrying = youbot.with_payload(payload)
    spec = RobotSource.of(carrying)
    data = json.loads(json.dumps(spec.to_json(folder=tmp_path)))
    assert data["payload"]["mass"] == MASS
    again = RobotSource.from_json(data).load(folder=tmp_path)
    assert again.payload == carrying.payload
    assert RobotSource.from_json({**data, "payload": None}).load().payload is None


def test_a_result_records_its_payload_and_is_checked_with_it(youbot, tmp_path):
    """A plan for the carrying arm reloads carrying it; without it the check on load refutes it."""
    carrying = youbot.with_payload(Payload(mass=0.5))  # [kg]; 2 kg is beyond the arm's torques
    result = solve(study1_problem(12, robot=carrying), method="hermite_simpson", seed=0)
    assert result.success
    path = save_result(result, tmp_path / "result.npz")
    loaded = load_result(path)
    assert loaded.success and loaded.problem.robot.payload == carrying.payload
    stripped = load_result(path, robot=youbot)  # the same plan, the arm without its payload
    assert not stripped.success


def test_a_robot_without_a_source_reloads_with_its_payload(youbot, tmp_path):
    """A robot with no file and no catalogue name reloads by its name with its payload."""
    import dataclasses

    bare = dataclasses.replace(youbot, urdf_path=None, catalogue_name=None)  # named "youbot"
    with pytest.raises(ParameterError):
        RobotSource.of(bare)
    carrying = bare.with_payload(Payload(mass=0.3))
    result = solve(study1_problem(10, robot=carrying), method="hermite_simpson", seed=0)
    assert result.success
    loaded = load_result(save_result(result, tmp_path / "mem.npz"))
    assert loaded.success and loaded.problem.robot.payload == carrying.payload
