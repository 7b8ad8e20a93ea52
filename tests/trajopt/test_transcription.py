"""Tests of the collocation transcriptions (youbot_opt.trajopt.transcription)."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

from youbot_opt.dynamics import build_dynamics
from youbot_opt.exceptions import ParameterError, TranscriptionError
from youbot_opt.reproduction.study1 import study1_problem
from youbot_opt.robot.load import load_model
from youbot_opt.trajopt.transcription import (
    HermiteSimpsonCollocation,
    RadauCollocation,
    TrapezoidalCollocation,
    get_transcription,
)

METHODS = [TrapezoidalCollocation(), HermiteSimpsonCollocation(), RadauCollocation()]
SQ6 = np.sqrt(6.0)
RADAU_C = np.array([(4 - SQ6) / 10, (4 + SQ6) / 10, 1.0])  # Hairer & Wanner, Table IV.5.6
RADAU_A = np.array(
    [
        [(88 - 7 * SQ6) / 360, (296 - 169 * SQ6) / 1800, (-2 + 3 * SQ6) / 225],
        [(296 + 169 * SQ6) / 1800, (88 + 7 * SQ6) / 360, (-2 - 3 * SQ6) / 225],
        [(16 - SQ6) / 36, (16 + SQ6) / 36, 1 / 9],
    ]
)
RADAU_BASE_F = 8.094584  # study-1 base case, Radau, 50 knots (this library's figure)


@pytest.fixture(scope="module")
def youbot():
    return load_model("youbot", damping=0.1)


@pytest.fixture(scope="module")
def dynamics(youbot):
    return build_dynamics(youbot, "symbolic")


@pytest.mark.parametrize("n", [2, 50, 73])
def test_trapezoidal_counts_match_the_study(youbot, dynamics, n):
    """Trapezoidal: 9n + 1 variables and 6(n - 1) + 12 equalities for the 3-joint youBot."""
    nlp = TrapezoidalCollocation().build(study1_problem(n, robot=youbot), dynamics.forward_dynamics)
    assert nlp.n_variables == 9 * n + 1
    assert nlp.n_constraints == nlp.n_equalities == 6 * (n - 1) + 12
    assert nlp.n_inequalities == 0
    assert nlp.x.numel() == nlp.n_variables and nlp.g.numel() == nlp.n_constraints


@pytest.mark.parametrize("n", [2, 50])
def test_hermite_simpson_counts(youbot, dynamics, n):
    """Hermite-Simpson: 9(2n - 1) + 1 variables, 12(n - 1) + 12 equalities, 12(n - 1) path rows."""
    nlp = HermiteSimpsonCollocation().build(
        study1_problem(n, robot=youbot), dynamics.forward_dynamics
    )
    assert nlp.n_variables == 9 * (2 * n - 1) + 1
    assert nlp.n_equalities == 12 * (n - 1) + 12
    # Two inner Bernstein control points of the velocity cubic and two of the
    # position cubic per interval and joint.
    assert nlp.n_inequalities == 12 * (n - 1)
    assert nlp.n_constraints == nlp.n_equalities + nlp.n_inequalities == nlp.g.numel()
    assert dict(nlp.path_bounds) == {
        "velocity_control_left": "v",
        "velocity_control_right": "v",
        "position_control_left": "q",
        "position_control_right": "q",
    }
    assert set(nlp.unbounded) == {"q_mid", "v_mid"}


def _polynomial_motion(robot, n, coeffs, dt):
    """Knot, midpoint and Radau-stage values of q(t) = sum_i c_i t^i with RNEA torques."""
    model, data = robot.model, robot.model.createData()
    b = np.asarray(robot.damping)

    def states(t):
        q = sum(c * t[:, None] ** i for i, c in enumerate(coeffs))
        v = sum(i * c * t[:, None] ** (i - 1) for i, c in enumerate(coeffs) if i >= 1)
        a = sum(i * (i - 1) * c * t[:, None] ** (i - 2) for i, c in enumerate(coeffs) if i >= 2)
        v = v + 0 * q
        a = a + 0 * q
        tau = np.array([pin.rnea(model, data, *s) + b * s[1] for s in zip(q, v, a, strict=True)])
        return q, v, tau

    t = dt * np.arange(n)
    q, v, tau = states(t)
    qm, vm, taum = states(t[:-1] + dt / 2)
    out = {"q": q, "v": v, "tau": tau, "q_mid": qm, "v_mid": vm, "tau_mid": taum, "dt": dt}
    for i, c in enumerate(RADAU_C[:2], start=1):
        names = (f"q_stage{i}", f"v_stage{i}", f"tau_stage{i}")
        out.update(zip(names, states(t[:-1] + c * dt), strict=True))
    return out


@pytest.mark.parametrize("method", METHODS, ids=lambda m: m.name)
def test_defects_vanish_for_constant_acceleration(youbot, dynamics, method):
    """Defects are zero (1e-10) on q = q0 + v0 t + a t^2 / 2 with inverse-dynamics torques."""
    n, dt = 12, 0.07
    q0, v0, a0 = np.array([-0.5, 0.3, -0.9]), np.array([0.4, -0.2, 0.6]), np.array([1.5, -2.0, 3.0])
    values = _polynomial_motion(youbot, n, [q0, v0, a0 / 2], dt)
    nlp = method.build(study1_problem(n, robot=youbot), dynamics.forward_dynamics)
    x = nlp.variables.pack(values)
    g = np.asarray(ca.Function("g", [nlp.x], [nlp.g])(x)).ravel()
    blocks = nlp.constraints.unpack(g)
    # Trapezoid, Simpson and Radau are exact for this quadratic q (linear v, constant a);
    # the remaining error is ABA(RNEA(.)) round-off, ~1e-13 for accelerations of O(1).
    for name in blocks:
        if name.startswith(("defect", "midpoint", "collocation")):
            np.testing.assert_allclose(blocks[name], 0.0, atol=1e-10, err_msg=name)
    np.testing.assert_allclose(blocks["start_position"][0], values["q"][0], atol=1e-15)
    np.testing.assert_allclose(blocks["goal_velocity"][0], values["v"][-1], atol=1e-15)


@pytest.mark.parametrize("method", METHODS, ids=lambda m: m.name)
def test_defects_do_not_vanish_for_a_quartic_motion(youbot, dynamics, method):
    """A quartic q(t) leaves defects of order dt^3 or more: the check above can fail."""
    n, dt = 12, 0.07
    coeffs = [np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3), np.array([5.0, -4.0, 6.0])]
    values = _polynomial_motion(youbot, n, coeffs, dt)
    nlp = method.build(study1_problem(n, robot=youbot), dynamics.forward_dynamics)
    g = np.asarray(ca.Function("g", [nlp.x], [nlp.g])(nlp.variables.pack(values))).ravel()
    blocks = nlp.constraints.unpack(g)
    prefixes = ("defect", "mid", "collocation")
    worst = max(np.max(np.abs(v)) for k, v in blocks.items() if k.startswith(prefixes))
    # q = c t^4: the trapezoid errs by ~ dt^3 |q'''| ~ 1e-2 rad, the Hermite midpoint
    # interpolation by ~ dt^4 |q''''| / 384 ~ 1e-5 rad, Radau's stages (stage order 3)
    # by ~ dt^4 |q''''| c^4 / 24 ~ 1e-6 rad; round-off is ~1e-15.
    assert worst > 1e-6


@pytest.mark.parametrize("method", METHODS, ids=lambda m: m.name)
def test_objective_terms(youbot, dynamics, method):
    """The NLP's duration is (N - 1) dt and its objective beta T + (1 - beta) W (1e-12 rel)."""
    n, dt = 9, 0.11
    nlp = method.build(study1_problem(n, robot=youbot), dynamics.forward_dynamics)
    rng = np.random.default_rng(3)
    values = {name: rng.normal(size=(b.count, b.width)) for name, b in nlp.variables.blocks.items()}
    values["dt"] = np.array([[dt]])
    x = nlp.variables.pack(values)
    f, total, w = ca.Function("f", [nlp.x, nlp.p], [nlp.f, nlp.duration, nlp.work])(x, 0.3)
    power = np.sum(values["tau"] ** 2, axis=1)
    if method.name == "trapezoidal":
        expected_w = sum(dt * (power[k] + power[k + 1]) / 2 for k in range(n - 1))
    elif method.name == "radau":  # Radau weights on stages 1, 2 and the end knot
        p1, p2 = (np.sum(values[f"tau_stage{i}"] ** 2, axis=1) for i in (1, 2))
        expected_w = sum(dt * RADAU_A[2] @ [p1[k], p2[k], power[k + 1]] for k in range(n - 1))
    else:
        pm = np.sum(values["tau_mid"] ** 2, axis=1)
        expected_w = sum(dt * (power[k] + 4 * pm[k] + power[k + 1]) / 6 for k in range(n - 1))
    assert float(total) == pytest.approx((n - 1) * dt, rel=1e-12)
    assert float(w) == pytest.approx(expected_w, rel=1e-12)
    assert float(f) == pytest.approx(0.3 * (n - 1) * dt + 0.7 * expected_w, rel=1e-12)


def test_layout_round_trip(youbot, dynamics):
    """pack() and unpack() are inverse, with knot-major blocks."""
    nlp = HermiteSimpsonCollocation().build(
        study1_problem(4, robot=youbot), dynamics.forward_dynamics
    )
    x = np.arange(nlp.n_variables, dtype=float)
    blocks = nlp.variables.unpack(x)
    np.testing.assert_array_equal(nlp.variables.pack(blocks), x)
    np.testing.assert_array_equal(blocks["q"][1], [3.0, 4.0, 5.0])


def test_get_transcription_names():
    """Names map to strategy objects; unknown names list the valid ones."""
    assert isinstance(get_transcription("hermite-simpson"), HermiteSimpsonCollocation)
    assert isinstance(get_transcription("trapezoidal"), TrapezoidalCollocation)
    with pytest.raises(ParameterError, match="choose one of"):
        get_transcription("euler")


def test_dynamics_of_the_wrong_size_is_rejected(youbot):
    """A forward-dynamics Function for 2 joints cannot transcribe the 3-joint youBot."""
    q, v, tau = (ca.SX.sym(name, 2) for name in ("q", "v", "tau"))
    bad = ca.Function("forward_dynamics", [q, v, tau], [q + v + tau])
    with pytest.raises(TranscriptionError, match="forward dynamics must map"):
        TrapezoidalCollocation().build(study1_problem(5, robot=youbot), bad)


def _plain_derivatives(nlp, youbot, rng):
    """A random point within the youBot's bounds, random multipliers, and CasADi's AD there.

    Returns ``x``, ``lam_g`` and the plain NLP's ``f``, ``g``, Jacobian, upper
    Hessian of ``0.7 f + lam_g . g`` and gradient of ``f`` at ``(x, beta = 0.3)``, dense.
    """
    box = {
        "q": (youbot.q_lower, youbot.q_upper),
        "v": (-youbot.velocity_limit, youbot.velocity_limit),
        "tau": (-youbot.effort_limit, youbot.effort_limit),
    }
    values = {
        name: rng.uniform(*box[name.split("_")[0]], (block.count, 3))
        for name, block in nlp.variables.blocks.items()
        if name != "dt"
    }
    values["dt"] = rng.uniform(0.02, 0.2)
    x = nlp.variables.pack(values)
    lam_g = rng.normal(size=nlp.n_constraints)
    lag = 0.7 * nlp.f + ca.dot(ca.MX(lam_g), nlp.g)
    plain = ca.Function(
        "plain",
        [nlp.x, nlp.p],
        [
            nlp.f,
            nlp.g,
            ca.jacobian(nlp.g, nlp.x),
            ca.triu(ca.hessian(lag, nlp.x)[0]),
            ca.gradient(nlp.f, nlp.x),
        ],
    )
    return x, lam_g, [np.asarray(ca.densify(m)) for m in plain(x, 0.3)]


def _assert_same_derivatives(fns, x, lam_g, reference):
    """``fns``' f, g, Jacobian, Hessian and gradient equal :func:`_plain_derivatives`' (1e-9).

    Same derivatives by two assembly routes; entries are O(1e3) at most (1/I of
    the wrist), so 1e-9 absolute is ~1e4 ulps.
    """
    f1, g1 = fns.nlp(x, 0.3)
    _, jac1 = fns.jac_g(x, 0.3)
    hess1 = fns.hess_lag(x, 0.3, 0.7, lam_g)
    f2, grad1 = fns.grad_f(x, 0.3)
    assert float(f2) == pytest.approx(float(f1), rel=1e-14)
    for a, b in zip(reference, (f1, g1, jac1, hess1, grad1), strict=True):
        np.testing.assert_allclose(a, np.asarray(ca.densify(b)), atol=1e-9)


def _assert_same_patterns(fns, nlp, graph=None):
    """The Jacobian's pattern holds the plain NLP's; all patterns are the ``graph`` route's.

    The kernels' Jacobians and Hessians are dense blocks, where CasADi's AD of
    the plain NLP knows that a clearance row ignores some joints and that the
    accelerations are affine in the torques; and SX drops what MX keeps of a
    zero weight (Radau's knot torque ``tau_0`` in the work), so the Hessian's
    pattern need not hold the plain one. The values are compared with the
    plain NLP's by :func:`_assert_same_derivatives`.
    """
    assert ca.jacobian(nlp.g, nlp.x).sparsity().is_subset(fns.jac_g.sparsity_out(1))
    if graph is not None:
        assert fns.grad_f.sparsity_out(1) == graph.grad_f.sparsity_out(1)
        assert fns.jac_g.sparsity_out(1) == graph.jac_g.sparsity_out(1)
        assert fns.hess_lag.sparsity_out(0) == graph.hess_lag.sparsity_out(0)


GRIDS = {"uniform": None, "graded": [1.0, 3.0, 0.5, 2.0, 1.0]}  # 6 knots


@pytest.mark.parametrize("grid", list(GRIDS))
@pytest.mark.parametrize("method", METHODS, ids=lambda m: m.name)
def test_structured_derivatives_match_casadi(youbot, dynamics, method, grid, rng):
    """The solver's structured f, g, Jacobian and Hessian equal CasADi's AD of the NLP (1e-9).

    Both assembly routes -- one interval's stencil mapped over the grid (the
    default) and the whole NLP's SX graph -- on a uniform and a graded grid,
    with the patterns of :func:`_assert_same_patterns`. With compiled kernels,
    ``nlp`` may be built on the compiled forward kernel (as the solver does):
    CasADi must then differentiate it through the kernel's compiled Jacobian,
    and its reverse-mode gradient of ``lam . g`` must equal the reference ``J^T lam``.
    """
    from youbot_opt.nlp.codegen import find_compiler
    from youbot_opt.trajopt.transcription.derivatives import (
        compile_kernels,
        dynamics_kernels,
        stencil_of,
        structured_functions,
    )

    method = method.with_fractions(GRIDS[grid])
    problem = study1_problem(6, robot=youbot)
    nlp = method.build(problem, dynamics.forward_dynamics)
    kernels = dynamics_kernels(dynamics.forward_dynamics)
    assert stencil_of(method, problem) is not None
    kernel_sets = [(kernels, kernels)]
    if find_compiler() is not None:  # the compiled kernels must agree too
        compiled = compile_kernels(kernels)
        assert compiled is not kernels
        kernel_sets += [(compiled, kernels), (compiled, compiled)]
    x, lam_g, reference = _plain_derivatives(nlp, youbot, rng)
    for own, values in kernel_sets:
        graph = structured_functions(method, problem, own, values=values, per_interval=False)
        fns = structured_functions(method, problem, own, values=values)
        _assert_same_patterns(fns, nlp, graph)
        assert fns.jac_g.sparsity_out(1) == ca.jacobian(nlp.g, nlp.x).sparsity()
        for variant in (fns, graph):
            _assert_same_derivatives(variant, x, lam_g, reference)
            xs, lams = ca.MX.sym("x", x.size), ca.MX.sym("lam", lam_g.size)
            _, g_sym = variant.nlp(xs, 0.3)
            grad = ca.Function("grad", [xs, lams], [ca.gradient(ca.dot(lams, g_sym), xs)])
            np.testing.assert_allclose(
                reference[2].T @ lam_g, np.asarray(grad(x, lam_g)).ravel(), atol=1e-9
            )


@pytest.mark.parametrize("method", METHODS, ids=lambda m: m.name)
def test_structured_derivatives_on_one_interval(youbot, dynamics, method, rng):
    """On 2 knots the stencil's first and last rows share the one interval (1e-9 to CasADi)."""
    from youbot_opt.trajopt.transcription.derivatives import dynamics_kernels, structured_functions

    problem = study1_problem(2, robot=youbot)
    nlp = method.build(problem, dynamics.forward_dynamics)
    fns = structured_functions(method, problem, dynamics_kernels(dynamics.forward_dynamics))
    x, lam_g, reference = _plain_derivatives(nlp, youbot, rng)
    _assert_same_derivatives(fns, x, lam_g, reference)
    _assert_same_patterns(fns, nlp)


def test_stencil_route_is_for_the_builtin_schemes(youbot):
    """A subclass (which may change the rows) and SX path rows take the whole-graph route."""
    from youbot_opt.trajopt.transcription.derivatives import stencil_of
    from youbot_opt.trajopt.transcription.path import PathConstraint

    class Renamed(TrapezoidalCollocation):
        name = "renamed"

    problem = study1_problem(5, robot=youbot)
    q, v = ca.SX.sym("q", 3), ca.SX.sym("v", 3)
    toy = PathConstraint(
        name="toy", function=ca.Function("toy", [q, v], [q[0] * v[1]]), lower=-1.0, upper=1.0
    )
    assert stencil_of(TrapezoidalCollocation(), problem) is not None
    assert stencil_of(Renamed(), problem) is None
    assert stencil_of(TrapezoidalCollocation(), problem, (toy,)) is None  # no path kernels


def test_refinement_rounds_reuse_the_stencil(monkeypatch):
    """A solver on another grid reuses its scheme's stencil; another scheme derives its own."""
    import youbot_opt.trajopt.solver as solver_module

    calls = []
    original = solver_module.stencil_of

    def counted(method, *args):
        calls.append(method.name)
        return original(method, *args)

    monkeypatch.setattr(solver_module, "stencil_of", counted)
    solver = solver_module.TrajOptSolver(study1_problem(6), "trapezoidal", compile=False)
    finer = solver.on_grid(np.arange(1.0, 9.0)).on_grid(np.ones(11))
    finer.with_method("hermite_simpson").on_grid(np.ones(4))
    assert calls == ["trapezoidal", "hermite_simpson"]


# ------------------------------------------------------------ non-uniform grids
def _hand_defects(method, values, a, am, h):
    """Defects written out with per-interval steps ``h`` (numpy, from the docstrings)."""
    q, v = values["q"], values["v"]
    h = h[:, None]
    if method.name == "radau":  # am: the accelerations at stages 1 and 2
        qs = [values["q_stage1"], values["q_stage2"], q[1:]]
        vs = [values["v_stage1"], values["v_stage2"], v[1:]]
        acc = [am[0], am[1], a[1:]]
        rows = {}
        for label, x, x0, dx in (("position", qs, q[:-1], vs), ("velocity", vs, v[:-1], acc)):
            names = (f"collocation_{label}_1", f"collocation_{label}_2", f"defect_{label}")
            for i, name in enumerate(names):
                rows[name] = x[i] - x0 - h * sum(RADAU_A[i, j] * dx[j] for j in range(3))
        return rows
    if method.name == "trapezoidal":
        return {
            "defect_position": q[1:] - q[:-1] - 0.5 * h * (v[:-1] + v[1:]),
            "defect_velocity": v[1:] - v[:-1] - 0.5 * h * (a[:-1] + a[1:]),
        }
    qm, vm = values["q_mid"], values["v_mid"]
    return {
        "defect_position": q[1:] - q[:-1] - h / 6 * (v[:-1] + 4 * vm + v[1:]),
        "defect_velocity": v[1:] - v[:-1] - h / 6 * (a[:-1] + 4 * am + a[1:]),
        "midpoint_position": qm - 0.5 * (q[:-1] + q[1:]) - h / 8 * (v[:-1] - v[1:]),
        "midpoint_velocity": vm - 0.5 * (v[:-1] + v[1:]) - h / 8 * (a[:-1] - a[1:]),
        "position_control_left": q[:-1] + h / 3 * v[:-1],
        "velocity_control_right": v[1:] - h / 3 * a[1:],
    }


@pytest.mark.parametrize("kind", ["trapezoidal", "hermite_simpson", "radau"])
def test_non_uniform_grid_defects_and_work_use_each_intervals_step(youbot, dynamics, kind):
    """On a grid of fractions, interval k has step (N - 1) f_k dt in every row and in W (1e-12)."""
    n, dt = 7, 0.09
    fractions = np.array([1.0, 3.0, 0.5, 2.0, 1.0, 0.25])
    method = get_transcription(kind).with_fractions(fractions)
    nlp = method.build(study1_problem(n, robot=youbot), dynamics.forward_dynamics)
    rng = np.random.default_rng(11)
    values = {name: rng.normal(size=(b.count, b.width)) for name, b in nlp.variables.blocks.items()}
    values["dt"] = np.array([[dt]])
    x = nlp.variables.pack(values)
    g, total, w = ca.Function("g", [nlp.x], [nlp.g, nlp.duration, nlp.work])(x)
    blocks = nlp.constraints.unpack(np.asarray(g).ravel())
    h = (n - 1) * fractions / fractions.sum() * dt  # independent of Transcription.ratios
    data = youbot.model.createData()
    b = np.asarray(youbot.damping)

    def aba(q, v, tau):
        rows = zip(q, v, tau, strict=True)
        return np.array([pin.aba(youbot.model, data, qk, vk, tk - b * vk) for qk, vk, tk in rows])

    a = aba(values["q"], values["v"], values["tau"])
    am = aba(values["q_mid"], values["v_mid"], values["tau_mid"]) if "q_mid" in values else None
    if kind == "radau":
        am = [aba(*(values[f"{x}_stage{i}"] for x in ("q", "v", "tau"))) for i in (1, 2)]
    for name, expected in _hand_defects(method, values, a, am, h).items():
        np.testing.assert_allclose(blocks[name], expected, rtol=1e-12, atol=1e-12, err_msg=name)
    p = np.sum(values["tau"] ** 2, axis=1)
    if kind == "trapezoidal":
        expected_w = np.sum(h * (p[:-1] + p[1:]) / 2)
    elif kind == "radau":
        p1, p2 = (np.sum(values[f"tau_stage{i}"] ** 2, axis=1) for i in (1, 2))
        expected_w = np.sum(h * (RADAU_A[2, 0] * p1 + RADAU_A[2, 1] * p2 + RADAU_A[2, 2] * p[1:]))
    else:
        pm = np.sum(values["tau_mid"] ** 2, axis=1)
        expected_w = np.sum(h * (p[:-1] + 4 * pm + p[1:]) / 6)
    assert float(total) == pytest.approx(h.sum(), rel=1e-12)
    assert float(w) == pytest.approx(expected_w, rel=1e-12)


@pytest.mark.parametrize(
    ("kind", "expected"),
    [("trapezoidal", 8.269796), ("hermite_simpson", 8.099726), ("radau", RADAU_BASE_F)],
)
def test_uniform_fractions_reproduce_the_uniform_grid(youbot, kind, expected):
    """Equal fractions give the uniform NLP's solution to round-off; both give the pinned f.

    The pinned values (README, docs/trajopt_reproduction.md) are the study-1 base
    case at 50 knots; equal fractions change ``h_k = dt * 1.0``, an exact product.
    Radau's is this library's own figure (docs/refinement.md), between
    Hermite-Simpson's and the converged optimum 8.074944 (800 knots).
    """
    from youbot_opt.trajopt.solver import TrajOptSolver

    problem = study1_problem(50)
    plain = TrajOptSolver(problem, kind).solve(beta=0.5)
    equal = TrajOptSolver(problem, get_transcription(kind).with_fractions(np.ones(49))).solve(
        beta=0.5
    )
    assert plain.success and equal.success and plain.grid is None
    assert plain.objective == pytest.approx(expected, abs=5e-7)
    assert equal.objective == pytest.approx(plain.objective, rel=1e-12)
    np.testing.assert_allclose(equal.trajectory.t, plain.trajectory.t, rtol=1e-12)


def test_grid_validation(youbot, dynamics):
    """Bad fractions and a grid of the wrong size are refused with the numbers."""
    with pytest.raises(ParameterError, match="fractions"):
        TrapezoidalCollocation([1.0, -1.0])
    with pytest.raises(ParameterError, match="fractions"):
        TrapezoidalCollocation([])
    method = TrapezoidalCollocation([1.0, 2.0])
    np.testing.assert_allclose(method.fractions, [1 / 3, 2 / 3])
    with pytest.raises(TranscriptionError, match="2 intervals"):
        method.build(study1_problem(5, robot=youbot), dynamics.forward_dynamics)


@pytest.mark.parametrize("grid", list(GRIDS))
@pytest.mark.parametrize("method", METHODS, ids=lambda m: m.name)
def test_structured_path_rows_match_casadi(
    youbot, dynamics, method, grid, rng, fit_cache, monkeypatch
):
    """Path rows assembled from their own kernels equal CasADi's AD of the NLP (1e-9).

    Two path constraints: the youBot's self-collision clearance (bounding-ball
    distances, a soft-min) and a made-up ``(q0 v1, sin q2)``. Their rows at the
    knots and at the interior points that are variables (Hermite-Simpson's
    midpoints, Radau's stages) come from the per-point kernels, SX and, with a
    compiler, compiled; the trapezoid's midpoints (an expression of the knots)
    stay in the SX graph. f, g, the Jacobian and the Hessian of the Lagrangian
    (random multipliers) must equal the plain NLP's, differentiated by CasADi,
    by both assembly routes (the interval stencil and the whole SX graph), on a
    uniform and a graded grid.
    """
    from youbot_opt.collision.clearance import Clearance
    from youbot_opt.nlp.codegen import find_compiler
    from youbot_opt.trajopt.clearance import clearance_constraint
    from youbot_opt.trajopt.transcription.derivatives import (
        compile_path_kernels,
        dynamics_kernels,
        path_kernels,
        structured_functions,
    )
    from youbot_opt.trajopt.transcription.path import PathConstraint

    monkeypatch.setenv("YOUBOT_OPT_CACHE", str(fit_cache))
    method = method.with_fractions(GRIDS[grid])
    problem = study1_problem(6, robot=youbot, clearance=Clearance(margin=0.01))
    rows = clearance_constraint(problem)
    assert rows is not None
    q, v = ca.SX.sym("q", 3), ca.SX.sym("v", 3)
    toy = PathConstraint(
        name="toy",
        function=ca.Function("toy", [q, v], [ca.vertcat(q[0] * v[1], ca.sin(q[2]))]),
        lower=-1.0,
        upper=1.0,
    )
    paths = (rows, toy)
    nlp = method.build(problem, dynamics.forward_dynamics, paths)
    kernels = dynamics_kernels(dynamics.forward_dynamics)
    own = tuple(path_kernels(c) for c in paths)
    path_sets = [own]
    if find_compiler() is not None:
        compiled = tuple(compile_path_kernels(k) for k in own)
        assert all(c is not k for c, k in zip(compiled, own, strict=True))
        path_sets.append(compiled)
    x, lam_g, reference = _plain_derivatives(nlp, youbot, rng)
    assert np.count_nonzero(reference[2][nlp.constraints["clearance_knots"].offset :]) > 0
    for pk in path_sets:
        graph = structured_functions(
            method, problem, kernels, paths=paths, path_kernels=pk, per_interval=False
        )
        fns = structured_functions(method, problem, kernels, paths=paths, path_kernels=pk)
        _assert_same_patterns(fns, nlp, graph)
        for variant in (fns, graph):
            _assert_same_derivatives(variant, x, lam_g, reference)


def test_sparse_entries_sum_duplicates_and_scale(rng):
    """SparseEntries equals a dense numpy accumulation of the same entries (exact sums)."""
    from youbot_opt.trajopt.transcription.scatter import SparseEntries, upper_entries

    a, b = ca.MX.sym("a", 6), ca.MX.sym("b", 9)
    entries = SparseEntries()
    rows_a, cols_a, pos_a = np.array([0, 2, 2, 4]), np.array([1, 1, 1, 3]), np.array([5, 0, 3, 1])
    scale_a = np.array([1.0, 2.0, -0.5, 3.0])
    entries.add(a, rows_a, cols_a, pos_a, scale_a)
    block = np.array([[1, 4, 2]])  # a symmetric 3x3 block (column-major in b) at rows 1, 4, 2
    rows_b, cols_b, pos_b = upper_entries(3, 1, block)
    entries.add(b, rows_b, cols_b, pos_b)
    fn = ca.Function("m", [a, b], [entries.matrix(5, 5)])
    av, bm = rng.normal(size=6), rng.normal(size=(3, 3))
    bm = bm + bm.T
    expected = np.zeros((5, 5))
    np.add.at(expected, (rows_a, cols_a), scale_a * av[pos_a])
    np.add.at(expected, (rows_b, cols_b), bm.ravel(order="F")[pos_b])
    got = fn(av, bm.ravel(order="F"))
    np.testing.assert_array_equal(np.asarray(ca.densify(got)), expected)  # same sums, same order
    assert got.nnz() == np.count_nonzero(expected)  # no entry is zero by chance
    assert set(zip(rows_b, cols_b, strict=True)) == {
        (1, 1), (1, 4), (1, 2), (4, 4), (2, 4), (2, 2)
    }  # fmt: skip
