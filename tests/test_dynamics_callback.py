"""The "pinocchio" backend: Pinocchio through CasADi Callbacks.

Values are compared with Pinocchio called directly and with the independent
symbolic backend; Jacobians with Pinocchio's analytic derivatives, the symbolic
backend's exact CasADi Jacobians and central finite differences. Tolerances
are justified at each check (machine-precision scale for exact quantities).
"""

from __future__ import annotations

import gc

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

from test_dynamics_symbolic import MODEL_NAMES, _close, _load, _random_states
from youbot_opt.dynamics import build_dynamics


@pytest.fixture(scope="module", params=MODEL_NAMES)
def both(request: pytest.FixtureRequest) -> tuple[pin.Model, object, object]:
    model = _load(request.param)
    return model, build_dynamics(model, "pinocchio"), build_dynamics(model, "symbolic")


def _jacobian_fn(fn: ca.Function, nv: int) -> ca.Function:
    """MX Function (q, v, x) -> d fn / d (q, v, x), built through CasADi's AD."""
    q, v, x = ca.MX.sym("q", nv), ca.MX.sym("v", nv), ca.MX.sym("x", nv)
    return ca.Function("j", [q, v, x], [ca.jacobian(fn(q, v, x), ca.vertcat(q, v, x))])


def test_values_match_pinocchio_and_symbolic(both: tuple[pin.Model, object, object]) -> None:
    """Callback values equal pin.aba/rnea with damping and the symbolic backend (1e-9 rel)."""
    model, cb, sym = both
    data = model.createData()
    b = model.damping
    np.testing.assert_array_equal(cb.damping, b)
    for q, v, tau, a in _random_states(model, seed=23):
        # Same Pinocchio call on the same numbers: equal to rounding.
        _close(cb.forward_dynamics(q, v, tau), pin.aba(model, data, q, v, tau - b * v))
        _close(cb.inverse_dynamics(q, v, a), pin.rnea(model, data, q, v, a) + b * v)
        # Independent implementation: agreement at machine-precision scale (see
        # test_dynamics_symbolic for the 1e-9 justification).
        _close(cb.forward_dynamics(q, v, tau), sym.forward_dynamics(q, v, tau))
        _close(cb.inverse_dynamics(q, v, a), sym.inverse_dynamics(q, v, a))


def test_jacobians(both: tuple[pin.Model, object, object]) -> None:
    """Callback Jacobians equal Pinocchio's derivatives, the symbolic AD (1e-8) and FD (1e-6)."""
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
    for q, v, tau, a in _random_states(model, seed=29, n=2):
        da_dq, da_dv, minv = pin.computeABADerivatives(model, data, q, v, tau - b * v)
        jf = np.asarray(jac_cb_fd(q, v, tau))
        # Exact derivatives evaluated two ways: rounding-level agreement (~1e-12).
        _close(jf, np.hstack([da_dq, da_dv - minv @ np.diag(b), minv]), rtol=1e-8)
        _close(jf, jac_sym_fd(q, v, tau), rtol=1e-8)
        dt_dq, dt_dv, dt_da = pin.computeRNEADerivatives(model, data, q, v, a)
        ji = np.asarray(jac_cb_id(q, v, a))
        _close(ji, np.hstack([dt_dq, dt_dv + np.diag(b), dt_da]), rtol=1e-8)
        _close(ji, jac_sym_id(q, v, a), rtol=1e-8)
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
        _close(jf, fd, rtol=1e-6)


def test_callbacks_survive_garbage_collection() -> None:
    """The Dynamics object keeps its Callbacks alive: usable after gc with no other reference."""

    def make() -> object:
        return build_dynamics(_load("planar_3r"), "pinocchio")

    dyn = make()
    gc.collect()
    q, v, tau, _ = _random_states(_load("planar_3r"), seed=31, n=1)[0]
    ref = pin.aba(_load("planar_3r"), _load("planar_3r").createData(), q, v, tau - 0.1 * v)
    _close(dyn.forward(q, v, tau), ref)
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
