"""Symbolic (CasADi SX) dynamics vs Pinocchio's own algorithms.

Tolerances. Both sides evaluate the same recursive algorithms in IEEE double
precision (eps = 2.2e-16), only with a different operation order, so they
differ by rounding alone. Every comparison is made relative to the largest
entry of the reference, ``|actual - desired| <= tol * max(1, max|desired|)``,
because the quantities span O(1e-2) (double-pendulum M) to O(1e4) (its
accelerations at unit torques), and rounding scales with the largest term:

* ``RTOL = 1e-12`` for what forward recursions give directly (placements,
  RNEA, CRBA, gravity, nonlinear effects, inverse dynamics and its
  Jacobian): each entry is a sum of O(100) rounded products, error
  ~100 eps ~ 2e-14 of the largest entry; measured <= 2e-15 on all five robots.
* ``RTOL_SOLVE = 1e-10`` for what goes through M^-1 (ABA, the CRBA linear
  solve, forward dynamics and its Jacobian, round trips): rounding is
  amplified by cond(M) (~1e4 on the panda), a bound of ~1e-12..1e-11;
  measured <= 1.0e-13 (panda, forward-dynamics Jacobian).

Both are >= 100x above the measured error and many orders below any modelling
error (a wrong axis, lever, sign or damping term changes results by 1e-3 or more).
"""

from __future__ import annotations

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
from youbot_opt.robot.catalogue import example_robot_data_dir

RTOL = 1e-12  # direct recursions: O(100) roundings of the largest term, see module docstring
RTOL_SOLVE = 1e-10  # through M^-1: rounding times cond(M) ~ 1e4, see module docstring
N_STATES = 10

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
    """URDF of an example-robot-data robot, located by the package's own locator."""
    return example_robot_data_dir() / "example-robot-data" / "robots" / ERD_URDFS[name]


def _load(name: str) -> pin.Model:
    if name == "youbot":
        # The committed youBot URDF via the model loader, with the study's
        # 0.1 N m s/rad damping so that the damping paths are exercised.
        model_module = pytest.importorskip("youbot_opt.robot.load")
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


def _close(actual: object, desired: np.ndarray, rtol: float) -> None:
    """Assert ``|actual - desired| <= rtol * max(1, max|desired|)`` entrywise."""
    desired = np.asarray(desired, dtype=float)
    actual = np.asarray(actual, dtype=float).reshape(desired.shape)
    scale = max(1.0, float(np.abs(desired).max()))
    np.testing.assert_allclose(actual, desired, rtol=0, atol=rtol * scale)


def _with_damping(model: pin.Model) -> pin.Model:
    """The model itself, given damping b = 0.05..0.2 [N m s/rad] if it has none.

    So that the damping terms of the Jacobians (-M^-1 diag(b), +diag(b)) are
    exercised on every robot, not only on those whose URDF declares damping.
    """
    if not np.any(model.damping > 0):
        model.damping = np.linspace(0.05, 0.2, model.nv)
    return model


MODEL_NAMES = ["double_pendulum", "ur5", "panda", "planar_3r", "youbot"]


@pytest.fixture(scope="module", params=MODEL_NAMES)
def case(request: pytest.FixtureRequest) -> tuple[str, pin.Model, object]:
    model = _load(request.param)
    return request.param, model, build_symbolic_model(model)


@pytest.fixture(scope="module")
def panda_dyn() -> tuple[pin.Model, object]:
    model = _load("panda")
    return model, build_dynamics(model, "symbolic")


JACOBIAN_MODELS = ["youbot", "double_pendulum", "ur5", "panda", "planar_3r"]


@pytest.fixture(scope="module", params=JACOBIAN_MODELS)
def jacobian_case(
    request: pytest.FixtureRequest,
) -> tuple[pin.Model, ca.Function, ca.Function]:
    """(damped model, d forward_dynamics / d(q, v, tau), d inverse_dynamics / d(q, v, a))."""
    model = _with_damping(_load(request.param))
    dyn = build_dynamics(model, "symbolic")
    nv = model.nv
    q_s, v_s, u_s = ca.SX.sym("q", nv), ca.SX.sym("v", nv), ca.SX.sym("u", nv)
    x = ca.vertcat(q_s, v_s, u_s)
    jac_fd = ca.Function(
        "jacobian_forward_dynamics",
        [q_s, v_s, u_s],
        [ca.jacobian(dyn.forward_dynamics(q_s, v_s, u_s), x)],
    )
    jac_id = ca.Function(
        "jacobian_inverse_dynamics",
        [q_s, v_s, u_s],
        [ca.jacobian(dyn.inverse_dynamics(q_s, v_s, u_s), x)],
    )
    return model, jac_fd, jac_id


def test_planar_3r_uses_unaligned_axis() -> None:
    """The youBot-like test arm really exercises RevoluteUnaligned with axis (0, -1, 0)."""
    model = _load("planar_3r")
    joint = model.joints[1]
    assert joint.shortname() == "JointModelRevoluteUnaligned"
    np.testing.assert_array_equal(joint.extract().axis, [0.0, -1.0, 0.0])


def test_algorithms_match_pinocchio(case: tuple[str, pin.Model, object]) -> None:
    """ABA, CRBA forward dynamics (1e-10), RNEA, CRBA, gravity, NLE (1e-12) equal Pinocchio's."""
    name, model, sym = case
    data = model.createData()
    for q, v, tau, a in _random_states(model, seed=len(name)):
        _close(sym.aba(q, v, tau), pin.aba(model, data, q, v, tau), RTOL_SOLVE)
        _close(sym.forward_dynamics_crba(q, v, tau), pin.aba(model, data, q, v, tau), RTOL_SOLVE)
        _close(sym.rnea(q, v, a), pin.rnea(model, data, q, v, a), RTOL)
        _close(sym.mass_matrix(q), _sym_mat(pin.crba(model, data, q)), RTOL)
        _close(sym.generalized_gravity(q), pin.computeGeneralizedGravity(model, data, q), RTOL)
        _close(sym.nonlinear_effects(q, v), pin.nonLinearEffects(model, data, q, v), RTOL)


def test_kinematics_match_pinocchio(case: tuple[str, pin.Model, object]) -> None:
    """Joint and frame placements equal Pinocchio's oMi / oMf (1e-12, unit-size data)."""
    name, model, sym = case
    data = model.createData()
    frame_fns = {f.name: sym.frame_placement(f.name) for f in model.frames}
    for q, *_ in _random_states(model, seed=7):
        pin.framesForwardKinematics(model, data, q)
        rotations, translations = sym.forward_kinematics(q)
        for i in range(1, model.njoints):
            _close(rotations[:, 3 * (i - 1) : 3 * i], data.oMi[i].rotation, RTOL)
            _close(translations[:, i - 1], data.oMi[i].translation, RTOL)
        for fid, frame in enumerate(model.frames):
            rot, pos = frame_fns[frame.name](q)
            _close(rot, data.oMf[fid].rotation, RTOL)
            _close(pos, data.oMf[fid].translation, RTOL)


def test_armature_matches_pinocchio() -> None:
    """Nonzero armature enters M, RNEA (1e-12) and ABA (1e-10) exactly as in Pinocchio."""
    model = _load("ur5")
    model.armature = np.linspace(0.05, 0.3, model.nv)
    sym = build_symbolic_model(model)
    data = model.createData()
    for q, v, tau, a in _random_states(model, seed=3, n=5):
        _close(sym.mass_matrix(q), _sym_mat(pin.crba(model, data, q)), RTOL)
        _close(sym.aba(q, v, tau), pin.aba(model, data, q, v, tau), RTOL_SOLVE)
        _close(sym.rnea(q, v, a), pin.rnea(model, data, q, v, a), RTOL)


@pytest.mark.parametrize("name", ["planar_3r", "panda", "youbot"])
def test_dynamics_include_damping(name: str) -> None:
    """forward/inverse_dynamics equal pin.aba(tau - b v) (1e-10) / pin.rnea + b v (1e-12)."""
    model = _load(name)
    assert np.any(model.damping > 0)
    dyn = build_dynamics(model, "symbolic")
    data = model.createData()
    b = model.damping
    np.testing.assert_array_equal(dyn.damping, b)
    for q, v, tau, a in _random_states(model, seed=11):
        _close(dyn.forward_dynamics(q, v, tau), pin.aba(model, data, q, v, tau - b * v), RTOL_SOLVE)
        _close(dyn.inverse_dynamics(q, v, a), pin.rnea(model, data, q, v, a) + b * v, RTOL)


def test_damping_false_is_plain_pinocchio() -> None:
    """With damping=False the Functions reduce to Pinocchio's aba (1e-10) / rnea (1e-12)."""
    model = _load("panda")
    dyn = build_dynamics(model, "symbolic", damping=False)
    data = model.createData()
    np.testing.assert_array_equal(dyn.damping, np.zeros(model.nv))
    for q, v, tau, a in _random_states(model, seed=5, n=5):
        _close(dyn.forward_dynamics(q, v, tau), pin.aba(model, data, q, v, tau), RTOL_SOLVE)
        _close(dyn.inverse_dynamics(q, v, a), pin.rnea(model, data, q, v, a), RTOL)


def test_forward_inverse_roundtrip(panda_dyn: tuple[pin.Model, object]) -> None:
    """inverse(forward(tau)) = tau with damping on (1e-10: passes through M^-1, cond ~ 1e4)."""
    model, dyn = panda_dyn
    for q, v, tau, _ in _random_states(model, seed=2):
        acc = dyn.forward(q, v, tau)
        _close(dyn.inverse(q, v, acc), tau, RTOL_SOLVE)


def _central_differences(fn: object, z0: np.ndarray, nv: int, h: float) -> np.ndarray:
    """Central-difference Jacobian of ``fn(q, v, x)`` w.r.t. z = (q, v, x), step ``h``."""
    cols = []
    for e in np.eye(3 * nv):
        plus, minus = np.split(z0 + h * e, 3), np.split(z0 - h * e, 3)
        cols.append((np.asarray(fn(*plus)) - np.asarray(fn(*minus))) / (2 * h))
    return np.column_stack(cols)


def test_jacobians_match_pinocchio_and_fd(
    jacobian_case: tuple[pin.Model, ca.Function, ca.Function],
) -> None:
    """CasADi Jacobians (with damping) equal Pinocchio's analytic derivatives and central FD."""
    model, jac_fd, jac_id = jacobian_case
    data = model.createData()
    b = model.damping
    assert np.all(b > 0)  # the damping terms below are really exercised
    nv = model.nv
    for q, v, tau, a in _random_states(model, seed=13, n=5):
        # Forward dynamics a = ABA(q, v, tau - b v): the chain rule through tau - b v
        # gives da/dv = dABA/dv - M^-1 diag(b). Through M^-1: RTOL_SOLVE (measured 1e-13).
        da_dq, da_dv, minv = pin.computeABADerivatives(model, data, q, v, tau - b * v)
        ref_fd = np.hstack([da_dq, da_dv - minv @ np.diag(b), minv])
        _close(jac_fd(q, v, tau), ref_fd, RTOL_SOLVE)
        # Inverse dynamics tau = RNEA(q, v, a) + b v: direct recursion, RTOL (measured 2e-15).
        dt_dq, dt_dv, dt_da = pin.computeRNEADerivatives(model, data, q, v, a)
        ref_id = np.hstack([dt_dq, dt_dv + np.diag(b), dt_da])
        _close(jac_id(q, v, a), ref_id, RTOL)
        # Third, independent check: central differences of Pinocchio itself with
        # the damping applied by hand. Step 1e-6 gives truncation O(h^2 |f^(3)|)
        # ~1e-10 and rounding O(eps |f| / h) ~1e-9 of the largest entry, so 1e-6
        # (relative to the Jacobian's largest entry) is safe.
        h = 1e-6
        fd_fd = _central_differences(
            lambda q_, v_, u_: pin.aba(model, data, q_, v_, u_ - b * v_),
            np.concatenate([q, v, tau]),
            nv,
            h,
        )
        _close(jac_fd(q, v, tau), fd_fd, 1e-6)
        fd_id = _central_differences(
            lambda q_, v_, a_: pin.rnea(model, data, q_, v_, a_) + b * v_,
            np.concatenate([q, v, a]),
            nv,
            h,
        )
        _close(jac_id(q, v, a), fd_id, 1e-6)


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
    _close(hess_fn(z0), fd, 1e-6)


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


BAD_INPUTS = [
    # (method, argument, bad value, expected message); nv = 2 (double pendulum).
    (
        "forward",
        "q",
        np.zeros(3),
        r"q \(joint positions in \[rad\] or \[m\]\) must have shape \(2,\) or \(2, 1\), "
        r"got shape \(3,\)",
    ),
    (
        "forward",
        "v",
        np.zeros(3),
        r"v \(joint velocities in \[rad/s\] or \[m/s\]\) must have shape \(2,\) or \(2, 1\), "
        r"got shape \(3,\)",
    ),
    (
        "forward",
        "v",
        np.array([0.0, np.nan]),
        r"v \(joint velocities .*\) must be finite, got \[ *0\. +nan\] "
        r"\(non-finite at indices \[1\]\)",
    ),
    (
        "forward",
        "tau",
        np.zeros((2, 2)),
        r"tau \(joint torques in \[N m\]\) must have shape \(2,\) or \(2, 1\), got shape \(2, 2\)",
    ),
    (
        "forward",
        "tau",
        np.array([np.inf, 1.0]),
        r"tau \(joint torques in \[N m\]\) must be finite, got \[ *inf +1\.\] "
        r"\(non-finite at indices \[0\]\)",
    ),
    (
        "forward",
        "tau",
        "ab",
        r"tau \(joint torques in \[N m\]\) must be a numeric vector of shape \(2,\), got 'ab'",
    ),
    (
        "inverse",
        "v",
        np.zeros(1),
        r"v \(joint velocities .*\) must have shape \(2,\) or \(2, 1\), got shape \(1,\)",
    ),
    (
        "inverse",
        "v",
        np.array([np.nan, -np.inf]),
        r"v \(joint velocities .*\) must be finite, got \[ *nan +-inf\] "
        r"\(non-finite at indices \[0, 1\]\)",
    ),
    (
        "inverse",
        "a",
        np.zeros(4),
        r"a \(joint accelerations in \[rad/s\^2\]\) must have shape \(2,\) or \(2, 1\), "
        r"got shape \(4,\)",
    ),
    (
        "inverse",
        "a",
        np.array([0.0, np.inf]),
        r"a \(joint accelerations .*\) must be finite, got \[ *0\. +inf\] "
        r"\(non-finite at indices \[1\]\)",
    ),
]


@pytest.fixture(scope="module", params=["symbolic", "pinocchio"])
def pendulum_dyn(request: pytest.FixtureRequest) -> object:
    return build_dynamics(_load("double_pendulum"), request.param)


@pytest.mark.parametrize(("method", "arg", "bad", "match"), BAD_INPUTS)
def test_numeric_wrapper_validates(
    pendulum_dyn: object, method: str, arg: str, bad: object, match: str
) -> None:
    """Wrong-shaped, non-finite or non-numeric q, v, tau, a raise ParameterError naming the
    argument, its meaning and unit, the expected shape and the offending shape or entries."""
    good = {"q": np.zeros(2), "v": np.zeros(2), "tau": np.zeros(2), "a": np.zeros(2)}
    names = ("q", "v", "tau") if method == "forward" else ("q", "v", "a")
    args = [bad if name == arg else good[name] for name in names]
    with pytest.raises(ParameterError, match=match) as info:
        getattr(pendulum_dyn, method)(*args)
    assert info.value.name == arg


def test_numeric_wrapper_accepts_columns(pendulum_dyn: object) -> None:
    """Column vectors (nv, 1), as CasADi returns them, give the same result (exactly)."""
    q, v, tau = np.array([0.3, -0.2]), np.array([1.0, 0.5]), np.array([0.1, -0.4])
    flat = pendulum_dyn.forward(q, v, tau)
    np.testing.assert_array_equal(pendulum_dyn.forward(*(x[:, None] for x in (q, v, tau))), flat)
    assert flat.shape == (2,)


def test_frame_not_found() -> None:
    """An unknown frame name raises FrameNotFound listing the model's frames."""
    sym = build_symbolic_model(_load("planar_3r"))
    with pytest.raises(FrameNotFound, match="'nope' not found.*tip"):
        sym.frame_placement("nope")
