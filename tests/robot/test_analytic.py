"""Tests of tests/_analytic.py (the study's hand derivation) against Pinocchio, the CasADi
symbolic dynamics and calculus."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from scipy.integrate import solve_ivp

import _analytic as an
from youbot_opt.dynamics import SymbolicModel, build_dynamics, build_symbolic_model
from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.load import load_model
from youbot_opt.robot.model import RobotModel, tip_pose
from youbot_opt.robot.params import YOUBOT_PLANAR as P

N_STATES = 20
MACHINE = 1e-12  # relative to the magnitude: Pinocchio and the oracle differ by rounding only
# Through M^-1 (forward dynamics), rounding is amplified by cond(M) <= 334 on the youBot
# (max over 2000 random q): eps * cond(M) * O(10) operations ~ 7e-13, so 1e-11.
SOLVE = 1e-11


def _states(n: int = N_STATES) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Seeded random (q, v, a): angles over the full circle, speeds up to 3 rad/s."""
    rng = np.random.default_rng(0)
    return [
        (rng.uniform(-np.pi, np.pi, 3), rng.uniform(-3, 3, 3), rng.uniform(-10, 10, 3))
        for _ in range(n)
    ]


def _close(actual: np.ndarray, expected: np.ndarray, tol: float = MACHINE) -> None:
    """Assert equality to ``tol`` relative to the largest entry of the reference."""
    actual = np.asarray(actual, dtype=float).reshape(np.shape(expected))
    scale = max(1.0, float(np.abs(expected).max()))
    np.testing.assert_allclose(actual, expected, rtol=0, atol=tol * scale)


@pytest.fixture(scope="module")
def symbolic(youbot: RobotModel) -> SymbolicModel:
    """The CasADi transcription of the committed youBot (no damping)."""
    return build_symbolic_model(youbot)


def test_mass_matrix_equals_crba(youbot: RobotModel) -> None:
    """Pinocchio's CRBA equals the hand-derived M(q) at 20 random configurations."""
    data = youbot.create_data()
    for q, _, _ in _states():
        crba = pin.crba(youbot.model, data, q)
        crba = np.triu(crba) + np.triu(crba, 1).T
        _close(crba, an.mass_matrix(P, q))


def test_bias_and_gravity_equal_rnea(youbot: RobotModel) -> None:
    """RNEA(q, v, 0) = C(q, v) v + N(q) and computeGeneralizedGravity = N(q), 20 states."""
    data = youbot.create_data()
    for q, v, _ in _states():
        _close(
            pin.rnea(youbot.model, data, q, v, np.zeros(3)),
            an.coriolis_matrix(P, q, v) @ v + an.gravity_torque(P, q),
        )
        _close(pin.computeGeneralizedGravity(youbot.model, data, q), an.gravity_torque(P, q))


def test_lagrangian_equals_casadi_symbolic(symbolic: SymbolicModel) -> None:
    """The hand-derived M(q), C(q, v) v + N(q) and N(q) equal the CasADi CRBA, nonlinear
    effects, RNEA at a = 0 and generalized gravity directly (not via Pinocchio), 20 states."""
    zero = np.zeros(3)
    for q, v, _ in _states():
        bias = an.coriolis_matrix(P, q, v) @ v + an.gravity_torque(P, q)
        # Sums of O(10) products of O(1) terms on both sides: MACHINE (measured 6e-16).
        _close(symbolic.mass_matrix(q), an.mass_matrix(P, q))
        _close(symbolic.nonlinear_effects(q, v), bias)
        _close(symbolic.rnea(q, v, zero), bias)
        _close(symbolic.generalized_gravity(q), an.gravity_torque(P, q))


def test_forward_dynamics_equals_casadi_aba(symbolic: SymbolicModel) -> None:
    """analytic.forward_dynamics equals the CasADi ABA (b = 0) and the symbolic backend's
    forward_dynamics with the study's b = 0.1 (ABA of tau - b v), 20 states."""
    b = 0.1  # [N m s/rad]
    damped = build_dynamics(load_model("youbot", damping=b), "symbolic")
    rng = np.random.default_rng(1)
    for q, v, _ in _states():
        tau = rng.uniform(-9.5, 9.5, 3)  # [N m], up to the largest effort limit
        # LU solve of the oracle's M vs Featherstone's ABA: SOLVE (measured 3.4e-14).
        _close(symbolic.aba(q, v, tau), an.forward_dynamics(P, q, v, tau, damping=0.0), SOLVE)
        _close(damped.forward(q, v, tau), an.forward_dynamics(P, q, v, tau, damping=b), SOLVE)


def test_inverse_and_forward_dynamics_with_damping(youbot: RobotModel) -> None:
    """Oracle ID/FD with b = 0.1 equal RNEA + b v and ABA(tau - b v) (Pinocchio ignores damping)."""
    b = 0.1
    robot = youbot
    data = robot.create_data()
    for q, v, a in _states(5):
        tau = pin.rnea(robot.model, data, q, v, a) + b * v
        _close(an.inverse_dynamics(P, q, v, a, damping=b), tau)
        _close(an.forward_dynamics(P, q, v, tau, damping=b), a)


def test_tip_pose_analytic_matches_pinocchio(youbot: RobotModel) -> None:
    """The trigonometric tip pose equals the URDF/Pinocchio tip pose at 20 configurations."""
    for q, _, _ in _states():
        ref = tip_pose(youbot, q)
        pose = an.tip_pose_analytic(P, q)
        # 1e-12 [m]: both are sums of O(0.5 m) products, rounding ~1e-16.
        np.testing.assert_allclose(pose.position, ref.position, rtol=0, atol=1e-12)
        np.testing.assert_allclose(pose.rotation, ref.rotation, rtol=0, atol=1e-12)


def test_mass_matrix_symmetric_positive_definite() -> None:
    """M(q) is symmetric (1e-15 relative) with eigenvalues > 0 at 20 configurations."""
    for q, _, _ in _states():
        m = an.mass_matrix(P, q)
        np.testing.assert_allclose(m, m.T, rtol=0, atol=1e-15 * np.abs(m).max())
        assert np.linalg.eigvalsh(m).min() > 0


def test_derivatives_match_finite_differences() -> None:
    """Complex-step dM/dq and hand-derived N = dV/dq agree with central differences."""
    h = 1e-6  # [rad]; central-difference error ~ h^2 |f'''| + eps |f| / h ~ 1e-10
    for q, _, _ in _states(5):
        dm = an.mass_matrix_derivatives(P, q)
        grad_v = np.zeros(3)
        for k in range(3):
            e = np.zeros(3)
            e[k] = h
            fd = (an.mass_matrix(P, q + e) - an.mass_matrix(P, q - e)) / (2 * h)
            np.testing.assert_allclose(dm[k], fd, rtol=0, atol=1e-8)  # 100x the FD error
            grad_v[k] = (an.potential_energy(P, q + e) - an.potential_energy(P, q - e)) / (2 * h)
        # V ~ 5 J: rounding error eps*5/h ~ 1e-9, so 1e-7 [N m] leaves 100x margin.
        np.testing.assert_allclose(an.gravity_torque(P, q), grad_v, rtol=0, atol=1e-7)


def test_mdot_minus_two_c_is_skew() -> None:
    """dM/dt - 2 C(q, v) is skew-symmetric, dM/dt by a central directional difference."""
    h = 1e-6  # [s]; the FD error on dM/dt is ~1e-10, far below the 1e-8 tolerance
    for q, v, _ in _states():
        mdot = (an.mass_matrix(P, q + h * v) - an.mass_matrix(P, q - h * v)) / (2 * h)
        s = mdot - 2 * an.coriolis_matrix(P, q, v)
        np.testing.assert_allclose(s + s.T, np.zeros((3, 3)), rtol=0, atol=1e-8)
        # Not trivially zero: the skew part carries the Coriolis terms.
        assert np.abs(s).max() > 1e-4 or np.abs(v).max() < 1e-3


def test_energy_conserved_by_unforced_simulation(youbot: RobotModel) -> None:
    """Unforced, undamped pin.aba motion conserves the oracle's total energy over 2 s."""
    data = youbot.create_data()

    def rhs(_: float, x: np.ndarray) -> np.ndarray:
        return np.concatenate([x[3:], pin.aba(youbot.model, data, x[:3], x[3:], np.zeros(3))])

    x0 = np.array([-0.5, 0.3, 0.8, 1.0, -1.0, 0.5])
    sol = solve_ivp(
        rhs,
        (0.0, 2.0),
        x0,
        method="DOP853",
        rtol=1e-10,
        atol=1e-12,
        t_eval=np.linspace(0.0, 2.0, 21),
    )
    assert sol.success
    energy = np.array([an.total_energy(P, x[:3], x[3:]) for x in sol.y.T])
    assert np.ptp(sol.y[0]) > 0.5  # the arm really swings
    # rtol 1e-10 over ~1000 steps bounds the drift by ~1e-7 relative (observed ~6e-10).
    np.testing.assert_allclose(energy, energy[0], rtol=0, atol=1e-7 * abs(energy[0]))


def test_damped_energy_loss_equals_dissipated_work(youbot: RobotModel) -> None:
    """With b = 0.1, E(t) + integral of b |v|^2 stays constant (damping sign and size)."""
    b = 0.1  # [N m s/rad], the study's code
    data = youbot.create_data()

    def rhs(_: float, x: np.ndarray) -> np.ndarray:
        q, v = x[:3], x[3:6]
        a = pin.aba(youbot.model, data, q, v, -b * v)
        return np.concatenate([v, a, [b * v @ v]])

    x0 = np.array([-0.5, 0.3, 0.8, 1.0, -1.0, 0.5, 0.0])
    sol = solve_ivp(
        rhs,
        (0.0, 1.0),
        x0,
        method="DOP853",
        rtol=1e-10,
        atol=1e-12,
        t_eval=np.linspace(0.0, 1.0, 11),
    )
    energy = np.array([an.total_energy(P, x[:3], x[3:6]) for x in sol.y.T])
    assert sol.y[6, -1] > 0.05  # a visible loss, so the check is not vacuous
    np.testing.assert_allclose(energy + sol.y[6], energy[0], rtol=0, atol=1e-7 * abs(energy[0]))


def test_spec_tip_table_analytic() -> None:
    """The trigonometric tip pose reproduces the spec table's second row exactly (1e-12)."""
    pose = an.tip_pose_analytic(P, [0.0, np.pi / 2, 0.0])
    np.testing.assert_allclose(pose.position, [0.184 - 0.135 - 0.2175, 0.147 + 0.155], atol=1e-12)
    np.testing.assert_allclose(pose.rotation, [[-1, 0], [0, -1]], atol=1e-12)


def test_bad_inputs() -> None:
    """Wrong shapes and NaN raise ParameterError naming the argument."""
    with pytest.raises(ParameterError, match=r"q must have shape \(3,\)"):
        an.mass_matrix(P, [0.0, 0.0])
    with pytest.raises(ParameterError, match="v must be finite"):
        an.coriolis_matrix(P, [0.0, 0.0, 0.0], [np.nan, 0.0, 0.0])
