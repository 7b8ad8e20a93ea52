"""The "pinocchio" backend: Pinocchio through CasADi Callbacks.

Values are compared with the independent symbolic backend on every test robot
and with the study's hand-derived Lagrangian (``tests/_analytic.py``) on the
youBot with damping; Jacobians with Pinocchio's analytic derivatives, the
symbolic backend's exact CasADi Jacobians and central finite differences.
Tolerances (``RTOL`` 1e-12 for direct recursions, ``RTOL_SOLVE`` 1e-10 through
M^-1) are justified in test_dynamics_symbolic's docstring and at each check.
"""

from __future__ import annotations

import gc

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest
from test_dynamics_symbolic import (
    MODEL_NAMES,
    RTOL,
    RTOL_SOLVE,
    _close,
    _load,
    _random_states,
    _with_damping,
)

import _analytic as analytic
from youbot_opt.dynamics import build_dynamics
from youbot_opt.robot.load import load_model
from youbot_opt.robot.params import YOUBOT_PLANAR


@pytest.fixture(scope="module", params=MODEL_NAMES)
def both(request: pytest.FixtureRequest) -> tuple[pin.Model, object, object]:
    model = _with_damping(_load(request.param))  # damping exercised on every robot
    return model, build_dynamics(model, "pinocchio"), build_dynamics(model, "symbolic")


def _jacobian_fn(fn: ca.Function, nv: int) -> ca.Function:
    """MX Function (q, v, x) -> d fn / d (q, v, x), built through CasADi's AD."""
    q, v, x = ca.MX.sym("q", nv), ca.MX.sym("v", nv), ca.MX.sym("x", nv)
    return ca.Function("j", [q, v, x], [ca.jacobian(fn(q, v, x), ca.vertcat(q, v, x))])


def test_values_match_symbolic(both: tuple[pin.Model, object, object]) -> None:
    """Callback values equal the independent symbolic backend's, damping included, at 10 states."""
    model, cb, sym = both
    b = model.damping
    np.testing.assert_array_equal(cb.damping, b)
    np.testing.assert_array_equal(sym.damping, b)
    for q, v, tau, a in _random_states(model, seed=23, n=10):
        # Two implementations of ABA (through M^-1): RTOL_SOLVE, measured <= 1.7e-15.
        _close(cb.forward_dynamics(q, v, tau), sym.forward_dynamics(q, v, tau), RTOL_SOLVE)
        # RNEA, a direct recursion: RTOL, measured <= 3.0e-16.
        _close(cb.inverse_dynamics(q, v, a), sym.inverse_dynamics(q, v, a), RTOL)


@pytest.fixture(scope="module")
def youbot_callback() -> object:
    """The "pinocchio" backend of the committed youBot with the study's b = 0.1 [N m s/rad]."""
    return build_dynamics(load_model("youbot", damping=0.1), "pinocchio")


def test_values_match_analytic_oracle(youbot_callback: object) -> None:
    """On the youBot with damping b = 0.1, the Callbacks equal the hand-derived Lagrangian
    a = M^-1 (tau - C v - N - b v) and tau = M a + C v + N + b v at 20 seeded states."""
    b = 0.1  # [N m s/rad]
    np.testing.assert_array_equal(youbot_callback.damping, [b, b, b])
    rng = np.random.default_rng(41)
    for _ in range(20):
        # Angles over the full circle, speeds up to 3 rad/s, torques up to the 9.5 N m limit.
        q, v = rng.uniform(-np.pi, np.pi, 3), rng.uniform(-3.0, 3.0, 3)
        tau, a = rng.uniform(-9.5, 9.5, 3), rng.uniform(-10.0, 10.0, 3)
        expected_a = analytic.forward_dynamics(YOUBOT_PLANAR, q, v, tau, damping=b)
        expected_tau = analytic.inverse_dynamics(YOUBOT_PLANAR, q, v, a, damping=b)
        # Oracle solves M x = rhs by LU, Pinocchio by ABA: rounding x cond(M), RTOL_SOLVE
        # (measured 2.1e-15). A sign error in b v changes a by >= 19 rad/s^2 here.
        _close(youbot_callback.forward(q, v, tau), expected_a, RTOL_SOLVE)
        # Both are sums of O(10) products of O(1) terms: RTOL (measured 6.9e-16).
        _close(youbot_callback.inverse(q, v, a), expected_tau, RTOL)


def test_jacobians(both: tuple[pin.Model, object, object]) -> None:
    """Callback Jacobians equal Pinocchio's derivatives, the symbolic AD (1e-10, 1e-12) and FD."""
    model, cb, sym = both
    data = model.createData()
    b, nv = model.damping, model.nv
    jac_cb_fd, jac_sym_fd = (
        _jacobian_fn(cb.forward_dynamics, nv),
        _jacobian_fn(sym.forward_dynamics, nv),
    )
    jac_cb_id, jac_sym_id = (
        _jacobian_fn(cb.inverse_dynamics, nv),
        _jacobian_fn(sym.inverse_dynamics, nv),
    )
    for q, v, tau, a in _random_states(model, seed=29, n=5):
        da_dq, da_dv, minv = pin.computeABADerivatives(model, data, q, v, tau - b * v)
        jf = np.asarray(jac_cb_fd(q, v, tau))
        # The Callback must add the damping chain rule (-M^-1 diag(b)) itself: it
        # holds only that and the plumbing, so agreement is exact to rounding; against
        # the symbolic AD, two computations through M^-1 agree to RTOL_SOLVE.
        _close(jf, np.hstack([da_dq, da_dv - minv @ np.diag(b), minv]), RTOL)
        _close(jf, jac_sym_fd(q, v, tau), RTOL_SOLVE)
        dt_dq, dt_dv, dt_da = pin.computeRNEADerivatives(model, data, q, v, a)
        ji = np.asarray(jac_cb_id(q, v, a))
        _close(ji, np.hstack([dt_dq, dt_dv + np.diag(b), dt_da]), RTOL)
        _close(ji, jac_sym_id(q, v, a), RTOL)
        # Central differences of the Callback's own values, step 1e-6: truncation
        # ~1e-10 and rounding ~1e-9 relative, so 1e-6 is a safe bound.
        h = 1e-6
        z0 = np.concatenate([q, v, tau])
        fd = np.column_stack(
            [
                (cb.forward(*np.split(z0 + h * e, 3)) - cb.forward(*np.split(z0 - h * e, 3)))
                / (2 * h)
                for e in np.eye(3 * nv)
            ]
        )
        _close(jf, fd, 1e-6)


def test_callbacks_survive_garbage_collection() -> None:
    """The Dynamics object keeps its Callbacks alive: usable after gc with no other reference."""

    def make() -> object:
        return build_dynamics(_load("planar_3r"), "pinocchio")

    dyn = make()
    gc.collect()
    q, v, tau, _ = _random_states(_load("planar_3r"), seed=31, n=1)[0]
    ref = pin.aba(_load("planar_3r"), _load("planar_3r").createData(), q, v, tau - 0.1 * v)
    _close(dyn.forward(q, v, tau), ref, RTOL)  # same Pinocchio call: equal to rounding
    # The Jacobian Callback must survive too.
    jac = _jacobian_fn(dyn.forward_dynamics, 3)
    gc.collect()
    assert np.all(np.isfinite(np.asarray(jac(q, v, tau))))


def test_map_and_nlp_with_limited_memory_hessian() -> None:
    """Mapped over knots as NLP constraints (IPOPT, limited-memory Hessian), the solve recovers
    the torques pin.rnea gives for target accelerations (1e-6; IPOPT tol is 1e-10)."""
    model = _load("planar_3r")
    dyn = build_dynamics(model, "pinocchio")
    data = model.createData()
    n_knots, nv = 3, model.nv
    states = _random_states(model, seed=37, n=n_knots)
    q0 = np.column_stack([s[0] for s in states])
    v0 = np.column_stack([s[1] for s in states])
    a_target = np.column_stack([s[3] for s in states])
    tau = ca.MX.sym("tau", nv, n_knots)
    residual = dyn.forward_dynamics.map(n_knots)(q0, v0, tau) - a_target
    nlp = {"x": ca.vec(tau), "f": 1e-3 * ca.sumsqr(tau), "g": ca.vec(residual)}
    opts = {
        "ipopt.hessian_approximation": "limited-memory",
        "ipopt.print_level": 0,
        "ipopt.sb": "yes",
        "ipopt.tol": 1e-10,
        "print_time": False,
    }
    solver = ca.nlpsol("s", "ipopt", nlp, opts)
    result = solver(x0=np.zeros(nv * n_knots), lbg=0.0, ubg=0.0)
    assert solver.stats()["success"], solver.stats()["return_status"]
    sol = np.asarray(result["x"]).reshape(nv, n_knots, order="F")
    for k in range(n_knots):
        expected = (
            pin.rnea(model, data, q0[:, k], v0[:, k], a_target[:, k]) + model.damping * v0[:, k]
        )
        np.testing.assert_allclose(sol[:, k], expected, rtol=1e-6, atol=1e-6)


def test_second_derivatives_unavailable() -> None:
    """As documented, the Callback backend has no second derivatives: a Hessian request fails."""
    dyn = build_dynamics(_load("planar_3r"), "pinocchio")
    z = ca.MX.sym("z", 9)
    scalar = ca.sumsqr(dyn.forward_dynamics(z[:3], z[3:6], z[6:]))
    with pytest.raises(RuntimeError, match="Derivatives cannot be calculated"):
        ca.hessian(scalar, z)
