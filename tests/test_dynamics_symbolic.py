"""Symbolic (CasADi SX) dynamics vs Pinocchio's own algorithms.

Tolerances: both sides evaluate the same recursive algorithms in IEEE double
precision, only with different operation order, so they agree to a few ulps
times the condition of the computation (errors measured ~1e-14 relative). A
relative tolerance of 1e-9 (with an absolute floor of 1e-9 times the size of
the reference) is therefore tight enough to catch any modelling error (a wrong
axis, lever or sign changes results at the 1e-3 level or more) while leaving
room for the conditioning of M^-1 on the 9-dof panda (cond(M) ~ 1e4).
"""

from __future__ import annotations

import importlib.metadata
from pathlib import Path

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

from youbot_opt.dynamics import (
    SUPPORTED_JOINTS,
    available_backends,
    build_dynamics,
    build_symbolic_model,
)
from youbot_opt.exceptions import FrameNotFound, ModelError, ParameterError

RTOL = 1e-9  # machine-precision scale, see module docstring
N_STATES = 4

PLANAR_3R_URDF = """<?xml version="1.0"?>
<robot name="planar_3r">
  <link name="base"/>
  <link name="l1"><inertial><origin xyz="0 0 0.0775"/><mass value="1.318"/>
    <inertia ixx="0.0031145" ixy="0" ixz="0" iyy="0.0031145" iyz="0" izz="0.0005"/>
  </inertial></link>
  <link name="l2"><inertial><origin xyz="0.001 0.002 0.0675"/><mass value="0.821"/>
    <inertia ixx="0.0017" ixy="0.0001" ixz="0" iyy="0.00172767" iyz="0" izz="0.0003"/>
  </inertial></link>
  <link name="l3"><inertial><origin xyz="0 0 0.10875"/><mass value="0.769"/>
    <inertia ixx="0.0006764" ixy="0" ixz="0" iyy="0.0006764" iyz="0" izz="0.0001"/>
  </inertial></link>
  <link name="tip"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <origin xyz="0.184 0 0.147"/><axis xyz="0 -1 0"/>
    <limit lower="-1.134" upper="1.571" effort="9.5" velocity="1.571"/>
    <dynamics damping="0.1"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="0 0 0.155"/><axis xyz="0 -1 0"/>
    <limit lower="-2.635" upper="2.548" effort="6" velocity="1.571"/>
    <dynamics damping="0.1"/></joint>
  <joint name="j3" type="revolute"><parent link="l2"/><child link="l3"/>
    <origin xyz="0 0 0.135" rpy="0.1 0 0"/><axis xyz="0 -1 0"/>
    <limit lower="-1.789" upper="1.789" effort="2" velocity="1.571"/>
    <dynamics damping="0.1"/></joint>
  <joint name="tip_joint" type="fixed"><parent link="l3"/><child link="tip"/>
    <origin xyz="0 0 0.2175" rpy="0 1.5708 0"/></joint>
</robot>
"""

ERD_URDFS = {
    "double_pendulum": "double_pendulum_description/urdf/double_pendulum.urdf",
    "ur5": "ur_description/urdf/ur5_robot.urdf",
    "panda": "panda_description/urdf/panda.urdf",
}


def _erd_path(name: str) -> Path:
    dist = importlib.metadata.distribution("example-robot-data")
    root = Path(str(dist.locate_file("cmeel.prefix/share/example-robot-data/robots")))
    return root / ERD_URDFS[name]


def _load(name: str) -> pin.Model:
    if name == "youbot":
        # The committed youBot URDF via the model loader, with the study's
        # 0.1 N m s/rad damping so that the damping paths are exercised.
        model_module = pytest.importorskip("youbot_opt.model")
        return model_module.load_model("youbot", damping=0.1).model
    if name == "planar_3r":
        return pin.buildModelFromXML(PLANAR_3R_URDF)
    return pin.buildModelFromUrdf(str(_erd_path(name)))


def _random_states(model: pin.Model, seed: int, n: int = N_STATES) -> list[tuple[np.ndarray, ...]]:
    """Seeded (q, v, tau, a): q within the limits where they are finite and non-empty."""
    rng = np.random.default_rng(seed)
    lo, hi = model.lowerPositionLimit.copy(), model.upperPositionLimit.copy()
    bad = ~(np.isfinite(lo) & np.isfinite(hi) & (hi > lo))
    lo[bad], hi[bad] = -np.pi, np.pi
    return [
        (
            rng.uniform(lo, hi),
            rng.normal(size=model.nv),
            rng.normal(size=model.nv) * 5.0,
            rng.normal(size=model.nv),
        )
        for _ in range(n)
    ]


def _sym_mat(m: np.ndarray) -> np.ndarray:
    return np.triu(m) + np.triu(m, 1).T


def _close(actual: object, desired: np.ndarray, rtol: float = RTOL) -> None:
    desired = np.asarray(desired, dtype=float)
    actual = np.asarray(actual, dtype=float).reshape(desired.shape)
    scale = max(1.0, float(np.abs(desired).max()))
    np.testing.assert_allclose(actual, desired, rtol=rtol, atol=rtol * scale)


MODEL_NAMES = ["double_pendulum", "ur5", "panda", "planar_3r", "youbot"]


@pytest.fixture(scope="module", params=MODEL_NAMES)
def case(request: pytest.FixtureRequest) -> tuple[str, pin.Model, object]:
    model = _load(request.param)
    return request.param, model, build_symbolic_model(model)


@pytest.fixture(scope="module")
def panda_dyn() -> tuple[pin.Model, object]:
    model = _load("panda")
    return model, build_dynamics(model, "symbolic")


def test_planar_3r_uses_unaligned_axis() -> None:
    """The youBot-like test arm really exercises RevoluteUnaligned with axis (0, -1, 0)."""
    model = _load("planar_3r")
    joint = model.joints[1]
    assert joint.shortname() == "JointModelRevoluteUnaligned"
    np.testing.assert_array_equal(joint.extract().axis, [0.0, -1.0, 0.0])


def test_algorithms_match_pinocchio(case: tuple[str, pin.Model, object]) -> None:
    """ABA, RNEA, CRBA, gravity, NLE and CRBA forward dynamics equal Pinocchio's (1e-9 rel)."""
    name, model, sym = case
    data = model.createData()
    for q, v, tau, a in _random_states(model, seed=len(name)):
        _close(sym.aba(q, v, tau), pin.aba(model, data, q, v, tau))
        _close(sym.forward_dynamics_crba(q, v, tau), pin.aba(model, data, q, v, tau))
        _close(sym.rnea(q, v, a), pin.rnea(model, data, q, v, a))
        _close(sym.mass_matrix(q), _sym_mat(pin.crba(model, data, q)))
        _close(sym.generalized_gravity(q), pin.computeGeneralizedGravity(model, data, q))
        _close(sym.nonlinear_effects(q, v), pin.nonLinearEffects(model, data, q, v))


def test_kinematics_match_pinocchio(case: tuple[str, pin.Model, object]) -> None:
    """Joint and frame placements equal Pinocchio's oMi / oMf (1e-9 rel, unit-size data)."""
    name, model, sym = case
    data = model.createData()
    frame_fns = {f.name: sym.frame_placement(f.name) for f in model.frames}
    for q, *_ in _random_states(model, seed=7):
        pin.framesForwardKinematics(model, data, q)
        rotations, translations = sym.forward_kinematics(q)
        for i in range(1, model.njoints):
            _close(rotations[:, 3 * (i - 1) : 3 * i], data.oMi[i].rotation)
            _close(translations[:, i - 1], data.oMi[i].translation)
        for fid, frame in enumerate(model.frames):
            rot, pos = frame_fns[frame.name](q)
            _close(rot, data.oMf[fid].rotation)
            _close(pos, data.oMf[fid].translation)


def test_armature_matches_pinocchio() -> None:
    """Nonzero armature enters M, ABA and RNEA exactly as in Pinocchio (1e-9 rel)."""
    model = _load("ur5")
    model.armature = np.linspace(0.05, 0.3, model.nv)
    sym = build_symbolic_model(model)
    data = model.createData()
    for q, v, tau, a in _random_states(model, seed=3, n=2):
        _close(sym.mass_matrix(q), _sym_mat(pin.crba(model, data, q)))
        _close(sym.aba(q, v, tau), pin.aba(model, data, q, v, tau))
        _close(sym.rnea(q, v, a), pin.rnea(model, data, q, v, a))


@pytest.mark.parametrize("name", ["planar_3r", "panda", "youbot"])
def test_dynamics_include_damping(name: str) -> None:
    """forward/inverse_dynamics equal pin.aba(tau - b v) / pin.rnea + b v (1e-9 rel)."""
    model = _load(name)
    assert np.any(model.damping > 0)
    dyn = build_dynamics(model, "symbolic")
    data = model.createData()
    b = model.damping
    np.testing.assert_array_equal(dyn.damping, b)
    for q, v, tau, a in _random_states(model, seed=11):
        _close(dyn.forward_dynamics(q, v, tau), pin.aba(model, data, q, v, tau - b * v))
        _close(dyn.inverse_dynamics(q, v, a), pin.rnea(model, data, q, v, a) + b * v)


def test_damping_false_is_plain_pinocchio() -> None:
    """With damping=False the Functions reduce to Pinocchio's aba/rnea (1e-9 rel)."""
    model = _load("panda")
    dyn = build_dynamics(model, "symbolic", damping=False)
    data = model.createData()
    np.testing.assert_array_equal(dyn.damping, np.zeros(model.nv))
    for q, v, tau, a in _random_states(model, seed=5, n=2):
        _close(dyn.forward_dynamics(q, v, tau), pin.aba(model, data, q, v, tau))
        _close(dyn.inverse_dynamics(q, v, a), pin.rnea(model, data, q, v, a))


def test_forward_inverse_roundtrip(panda_dyn: tuple[pin.Model, object]) -> None:
    """inverse(forward(tau)) = tau with damping on (1e-9 rel; cond(M) ~ 1e4 leaves margin)."""
    model, dyn = panda_dyn
    for q, v, tau, _ in _random_states(model, seed=2):
        acc = dyn.forward(q, v, tau)
        _close(dyn.inverse(q, v, acc), tau)


def test_jacobians_match_pinocchio_and_fd(panda_dyn: tuple[pin.Model, object]) -> None:
    """CasADi Jacobians equal Pinocchio's analytic derivatives (1e-8) and central FD (1e-6)."""
    model, dyn = panda_dyn
    data = model.createData()
    b = model.damping
    nv = model.nv
    q_s, v_s, u_s = ca.SX.sym("q", nv), ca.SX.sym("v", nv), ca.SX.sym("u", nv)
    x = ca.vertcat(q_s, v_s, u_s)
    jac_fd = ca.Function(
        "jf", [q_s, v_s, u_s], [ca.jacobian(dyn.forward_dynamics(q_s, v_s, u_s), x)]
    )
    jac_id = ca.Function(
        "ji", [q_s, v_s, u_s], [ca.jacobian(dyn.inverse_dynamics(q_s, v_s, u_s), x)]
    )
    for q, v, tau, a in _random_states(model, seed=13, n=2):
        da_dq, da_dv, minv = pin.computeABADerivatives(model, data, q, v, tau - b * v)
        ref_fd = np.hstack([da_dq, da_dv - minv @ np.diag(b), minv])
        # Pinocchio's derivatives are exact up to rounding (~1e-12 on O(100) entries).
        _close(jac_fd(q, v, tau), ref_fd, rtol=1e-8)
        dt_dq, dt_dv, dt_da = pin.computeRNEADerivatives(model, data, q, v, a)
        ref_id = np.hstack([dt_dq, dt_dv + np.diag(b), dt_da])
        _close(jac_id(q, v, a), ref_id, rtol=1e-8)
        # Third, independent check: central differences of Pinocchio itself.
        # Step 1e-6 gives truncation O(h^2 |a'''|) ~ 1e-10 and rounding
        # O(eps |a| / h) ~ 1e-9, so 1e-6 (relative to the Jacobian's size) is safe.
        h = 1e-6
        z0 = np.concatenate([q, v, tau])
        cols = []
        for k in range(3 * nv):
            dz = np.zeros(3 * nv)
            dz[k] = h
            zp, zm = z0 + dz, z0 - dz
            fp = pin.aba(model, data, zp[:nv], zp[nv : 2 * nv], zp[2 * nv :] - b * zp[nv : 2 * nv])
            fm = pin.aba(model, data, zm[:nv], zm[nv : 2 * nv], zm[2 * nv :] - b * zm[nv : 2 * nv])
            cols.append((fp - fm) / (2 * h))
        _close(jac_fd(q, v, tau), np.column_stack(cols), rtol=1e-6)


def test_second_derivatives_exact() -> None:
    """Hessian of a scalar of the forward dynamics equals central FD of its gradient (1e-6)."""
    model = _load("planar_3r")
    dyn = build_dynamics(model, "symbolic")
    nv = model.nv
    z = ca.SX.sym("z", 3 * nv)
    weights = np.array([1.0, -2.0, 0.5])
    scalar = ca.dot(weights, dyn.forward_dynamics(z[:nv], z[nv : 2 * nv], z[2 * nv :]))
    hess, grad = ca.hessian(scalar, z)
    hess_fn = ca.Function("h", [z], [hess])
    grad_fn = ca.Function("g", [z], [grad])
    q, v, tau, _ = _random_states(model, seed=17, n=1)[0]
    z0 = np.concatenate([q, v, tau])
    h = 1e-6  # central differences of an exact gradient: error ~1e-9, see test above
    fd = np.column_stack(
        [
            (np.asarray(grad_fn(z0 + h * e)) - np.asarray(grad_fn(z0 - h * e))).ravel() / (2 * h)
            for e in np.eye(3 * nv)
        ]
    )
    _close(hess_fn(z0), fd, rtol=1e-6)


def test_mx_map_over_knots(panda_dyn: tuple[pin.Model, object]) -> None:
    """forward_dynamics.map(N) on MX symbols gives the per-knot values (1e-12: same code)."""
    model, dyn = panda_dyn
    n_knots, nv = 5, model.nv
    states = _random_states(model, seed=19, n=n_knots)
    q_m, v_m, u_m = (ca.MX.sym(s, nv, n_knots) for s in ("q", "v", "u"))
    mapped = ca.Function("m", [q_m, v_m, u_m], [dyn.forward_dynamics.map(n_knots)(q_m, v_m, u_m)])
    out = np.asarray(mapped(*(np.column_stack([s[k] for s in states]) for k in range(3))))
    for j, (q, v, tau, _) in enumerate(states):
        np.testing.assert_allclose(out[:, j], dyn.forward(q, v, tau), rtol=1e-12, atol=1e-12)


def test_function_io_names(panda_dyn: tuple[pin.Model, object]) -> None:
    """The Functions carry the names and I/O names other modules rely on."""
    _, dyn = panda_dyn
    fd, inv = dyn.forward_dynamics, dyn.inverse_dynamics
    assert (fd.name(), fd.name_in(), fd.name_out()) == (
        "forward_dynamics",
        ["q", "v", "tau"],
        ["a"],
    )
    assert (inv.name(), inv.name_in(), inv.name_out()) == (
        "inverse_dynamics",
        ["q", "v", "a"],
        ["tau"],
    )
    assert fd.size_in(0) == (9, 1) and fd.size_out(0) == (9, 1)


def test_accepts_robot_model_wrapper() -> None:
    """Anything holding the pin.Model in `.model` (RobotModel) is accepted."""

    class Wrapper:
        model = _load("double_pendulum")

    dyn = build_dynamics(Wrapper(), "symbolic")
    assert (dyn.nq, dyn.nv) == (2, 2)
    with pytest.raises(ParameterError, match="pin.Model"):
        build_dynamics(object(), "symbolic")


def test_unsupported_joint_raises() -> None:
    """A free-flyer or spherical joint raises ModelError naming the joint and supported types."""
    free = pin.buildModelFromUrdf(str(_erd_path("ur5")), pin.JointModelFreeFlyer())
    with pytest.raises(ModelError, match=r"root_joint.*JointModelFreeFlyer.*JointModelRX"):
        build_dynamics(free, "symbolic")
    ball = pin.Model()
    jid = ball.addJoint(0, pin.JointModelSpherical(), pin.SE3.Identity(), "ball")
    ball.appendBodyToJoint(jid, pin.Inertia.Random(), pin.SE3.Identity())
    for backend in ("symbolic", "pinocchio"):
        with pytest.raises(ModelError, match="'ball' has type JointModelSpherical"):
            build_dynamics(ball, backend)
    assert "JointModelRevoluteUnaligned" in SUPPORTED_JOINTS


def test_backend_errors() -> None:
    """Unknown backend lists the available ones; pinocchio_casadi says why it is missing;
    a float damping (a coefficient, not a switch) is refused."""
    model = _load("double_pendulum")
    assert available_backends()[:2] == ("symbolic", "pinocchio")
    with pytest.raises(
        ParameterError, match="unknown dynamics backend 'casadi'.*symbolic, pinocchio"
    ):
        build_dynamics(model, "casadi")
    with pytest.raises(ParameterError, match="damping must be True .* or False, got 0.1"):
        build_dynamics(model, "symbolic", damping=0.1)  # type: ignore[arg-type]
    if "pinocchio_casadi" not in available_backends():
        with pytest.raises(ParameterError, match="unavailable.*conda-forge"):
            build_dynamics(model, "pinocchio_casadi")


def test_numeric_wrapper_validates(panda_dyn: tuple[pin.Model, object]) -> None:
    """Wrong-shaped or non-finite inputs to forward()/inverse() raise ParameterError."""
    _, dyn = panda_dyn
    z = np.zeros(9)
    with pytest.raises(ParameterError, match=r"q must have shape \(9,\)"):
        dyn.forward(np.zeros(8), z, z)
    with pytest.raises(ParameterError, match="tau must be finite"):
        dyn.forward(z, z, np.full(9, np.nan))
    with pytest.raises(ParameterError, match="a must be finite"):
        dyn.inverse(z, z, np.full(9, np.inf))


def test_frame_not_found() -> None:
    """An unknown frame name raises FrameNotFound listing the model's frames."""
    sym = build_symbolic_model(_load("planar_3r"))
    with pytest.raises(FrameNotFound, match="'nope' not found.*tip"):
        sym.frame_placement("nope")
