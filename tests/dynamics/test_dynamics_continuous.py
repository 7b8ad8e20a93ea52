"""Continuous joints in angle coordinates vs Pinocchio on the (cos, sin) configuration.

Both backends take one unbounded angle per continuous joint; the reference is
Pinocchio's own ``aba``/``rnea``/``crba`` evaluated at ``(cos θ, sin θ)``.
Tolerances as in ``test_dynamics_symbolic.py`` (same algorithms, rounding
only): ``RTOL = 1e-12`` for direct recursions, ``RTOL_SOLVE = 1e-10`` through
``M^-1``, both relative to ``max(1, max|reference|)``. Angles are drawn in
[-3π, 3π] so that every test crosses ±π.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

from youbot_opt.dynamics import build_dynamics, build_symbolic_model
from youbot_opt.dynamics.coordinates import (
    angle_model,
    continuous_joints,
    from_pin_configuration,
    to_pin_configuration,
)
from youbot_opt.robot.catalogue import example_robot_data_dir

RTOL = 1e-12  # direct recursions, see the module docstring
RTOL_SOLVE = 1e-10  # through M^-1, see the module docstring
URDFS = {
    "double_pendulum_continuous": (
        "double_pendulum_description/urdf/double_pendulum_continuous.urdf"
    ),
    "kinova": "kinova_description/robots/kinova.urdf",
}


def _load(name: str) -> pin.Model:
    path = example_robot_data_dir() / "example-robot-data" / "robots" / URDFS[name]
    model = pin.buildModelFromUrdf(str(path))
    model.damping = np.linspace(0.05, 0.3, model.nv)  # exercise the damping terms too
    return model


def _close(actual: object, desired: np.ndarray, rtol: float) -> None:
    """Assert ``|actual - desired| <= rtol * max(1, max|desired|)`` entrywise."""
    desired = np.asarray(desired, dtype=float)
    actual = np.asarray(actual, dtype=float).reshape(desired.shape)
    scale = max(1.0, float(np.abs(desired).max()))
    np.testing.assert_allclose(actual, desired, rtol=0, atol=rtol * scale)


@pytest.fixture(scope="module", params=sorted(URDFS))
def model(request: pytest.FixtureRequest) -> pin.Model:
    """A model with continuous joints (Pinocchio nq > nv)."""
    m = _load(request.param)
    assert m.nq > m.nv and continuous_joints(m)
    return m


def _states(model: pin.Model, seed: int = 3) -> list[tuple[np.ndarray, ...]]:
    rng = np.random.default_rng(seed)
    return [
        (
            rng.uniform(-3 * np.pi, 3 * np.pi, model.nv),
            rng.normal(size=model.nv),
            rng.normal(size=model.nv),
            rng.normal(size=model.nv),
        )
        for _ in range(8)
    ]


@pytest.mark.parametrize("backend", ["symbolic", "pinocchio"])
def test_dynamics_match_pinocchio_on_cos_sin(model: pin.Model, backend: str) -> None:
    """forward (1e-10) and inverse (1e-12) dynamics in angles equal pin.aba/rnea at (cos, sin)."""
    dyn = build_dynamics(model, backend)
    data = model.createData()
    b = np.asarray(model.damping)
    assert (dyn.nq, dyn.nv) == (model.nv, model.nv)
    for theta, v, tau, a in _states(model):
        q_pin = to_pin_configuration(model, theta)
        _close(dyn.forward(theta, v, tau), pin.aba(model, data, q_pin, v, tau - b * v), RTOL_SOLVE)
        _close(dyn.inverse(theta, v, a), pin.rnea(model, data, q_pin, v, a) + b * v, RTOL)


def test_symbolic_crba_and_kinematics_on_cos_sin(model: pin.Model) -> None:
    """CRBA, gravity (1e-12) and frame placements (1e-12) in angles equal Pinocchio's."""
    sym = build_symbolic_model(model)
    data = model.createData()
    tip = model.frames[len(model.frames) - 1].name
    placement = sym.frame_placement(tip)
    for theta, _, _, _ in _states(model, seed=5):
        q_pin = to_pin_configuration(model, theta)
        mass = pin.crba(model, data, q_pin)
        _close(sym.mass_matrix(theta), np.triu(mass) + np.triu(mass, 1).T, RTOL)
        gravity = pin.computeGeneralizedGravity(model, data, q_pin)
        _close(sym.generalized_gravity(theta), gravity, RTOL)
        pin.framesForwardKinematics(model, data, q_pin)
        rot, pos = placement(theta)
        _close(rot, data.oMf[model.getFrameId(tip)].rotation, RTOL)
        _close(pos, data.oMf[model.getFrameId(tip)].translation, RTOL)


def test_callback_jacobian_is_angle_derivative(model: pin.Model) -> None:
    """The Callback's da/dq (Pinocchio's tangent derivative) equals the symbolic da/dθ (1e-10)."""
    sym = build_dynamics(model, "symbolic")
    cb = build_dynamics(model, "pinocchio")
    q, v, u = (ca.MX.sym(n, model.nv) for n in ("q", "v", "u"))
    jac = {
        name: ca.Function("j", [q, v, u], [ca.jacobian(d.forward_dynamics(q, v, u), q)])
        for name, d in (("symbolic", sym), ("pinocchio", cb))
    }
    for theta, vel, tau, _ in _states(model, seed=7)[:3]:
        ref = np.asarray(jac["symbolic"](theta, vel, tau))
        _close(jac["pinocchio"](theta, vel, tau), ref, RTOL_SOLVE)


def test_angle_model_is_equivalent(model: pin.Model) -> None:
    """angle_model has nq == nv, no position limit on the former continuous joints, and the
    same aba/crba (1e-12 relative, measured 0) and frame placements as the (cos, sin) model."""
    twin = angle_model(model)
    assert twin.nq == twin.nv == model.nv
    assert len(twin.frames) == len(model.frames)
    for j in continuous_joints(model):
        iv = model.joints[j].idx_v
        assert twin.lowerPositionLimit[iv] == -np.inf and twin.upperPositionLimit[iv] == np.inf
    data, twin_data = model.createData(), twin.createData()
    for theta, v, tau, _ in _states(model, seed=11):
        q_pin = to_pin_configuration(model, theta)
        _close(pin.aba(twin, twin_data, theta, v, tau), pin.aba(model, data, q_pin, v, tau), RTOL)
        _close(pin.crba(twin, twin_data, theta), pin.crba(model, data, q_pin), RTOL)
        pin.framesForwardKinematics(model, data, q_pin)
        pin.framesForwardKinematics(twin, twin_data, theta)
        for f in range(len(model.frames)):
            _close(twin_data.oMf[f].homogeneous, data.oMf[f].homogeneous, RTOL)


def test_configuration_round_trip(model: pin.Model) -> None:
    """from_pin(to_pin(θ)) is θ wrapped to (-π, π] on continuous joints, θ elsewhere (1e-12)."""
    rng = np.random.default_rng(1)
    theta = rng.uniform(-3 * np.pi, 3 * np.pi, model.nv)
    back = from_pin_configuration(model, to_pin_configuration(model, theta))
    cont = [model.joints[j].idx_v for j in continuous_joints(model)]
    other = [i for i in range(model.nv) if i not in cont]
    np.testing.assert_allclose(np.cos(back[cont]), np.cos(theta[cont]), atol=1e-12)
    np.testing.assert_allclose(np.sin(back[cont]), np.sin(theta[cont]), atol=1e-12)
    assert np.all(np.abs(back[cont]) <= np.pi)
    np.testing.assert_array_equal(back[other], theta[other])
