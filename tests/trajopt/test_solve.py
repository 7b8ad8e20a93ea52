"""Tests of the trajectory solver (youbot_opt.trajopt.solver, youbot_opt.trajopt.result).

Every solution is re-checked with Pinocchio's numeric ABA and numpy, a path
independent of the CasADi expressions IPOPT saw.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

from youbot_opt.exceptions import ParameterError, SolveFailed, YoubotOptWarning
from youbot_opt.nlp.ipopt import IpoptOptions
from youbot_opt.reproduction.study1 import study1_problem
from youbot_opt.robot.load import load_model
from youbot_opt.trajopt.certify import check_bounds as certify_bounds
from youbot_opt.trajopt.problem import BoundaryState, TrajOptProblem
from youbot_opt.trajopt.result import SolveStatus
from youbot_opt.trajopt.solver import TrajOptSolver, solve
from youbot_opt.trajopt.transcription import HermiteSimpsonCollocation

SLIDER_URDF = """<?xml version="1.0"?>
<robot name="slider">
  <link name="base"/>
  <link name="cart">
    <inertial><origin xyz="0 0 0"/><mass value="2.0"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
  </link>
  <joint name="slide" type="prismatic">
    <parent link="base"/><child link="cart"/><axis xyz="1 0 0"/>
    <limit lower="-5" upper="5" velocity="10" effort="4"/>
  </joint>
</robot>
"""
"""A 2 kg cart on a horizontal rail (gravity off along the joint), force bound 4 N."""

SLIDER_MASS, SLIDER_FORCE, SLIDER_DISTANCE = 2.0, 4.0, 1.0  # [kg], [N], [m]


@pytest.fixture(scope="module")
def base_solver(youbot):
    return TrajOptSolver(study1_problem(robot=youbot), "trapezoidal")


@pytest.fixture(scope="module")
def base_result(base_solver):
    return base_solver.solve(beta=0.5)


@pytest.fixture(scope="module")
def slider(tmp_path_factory):
    path = tmp_path_factory.mktemp("urdf") / "slider.urdf"
    path.write_text(SLIDER_URDF)
    return load_model(path)


def _slider_problem(slider, n):
    return TrajOptProblem(
        robot=slider,
        start=BoundaryState(q=[0.0]),
        goal=BoundaryState(q=[SLIDER_DISTANCE]),
        n_knots=n,
    )


def _aba(robot, q, v, tau):
    """Accelerations by Pinocchio's ABA with the model's damping (independent of CasADi)."""
    model, data = robot.model, robot.model.createData()
    b = np.asarray(robot.damping)
    return np.array([pin.aba(model, data, *s) - 0 for s in zip(q, v, tau - b * v, strict=True)])


def _check_trapezoidal(result, tol):
    """Max trapezoidal defect of a result, recomputed with pin.aba and numpy."""
    robot, traj = result.problem.robot, result.trajectory
    q, v, tau, dt = traj.q, traj.v, traj.tau, result.dt
    a = _aba(robot, q, v, tau)
    dq = q[1:] - q[:-1] - dt / 2 * (v[1:] + v[:-1])
    dv = v[1:] - v[:-1] - dt / 2 * (a[1:] + a[:-1])
    np.testing.assert_allclose(dq, 0.0, atol=tol)
    np.testing.assert_allclose(dv, 0.0, atol=tol)
    np.testing.assert_allclose(traj.a, a, atol=1e-9)  # the result's a is ABA at the knots


def _check_bounds(result, tol):
    b = result.bounds()
    traj = result.trajectory
    for x, lo, hi in ((traj.q, b.q_lower, b.q_upper), (traj.v, b.v_lower, b.v_upper),
                      (traj.tau, b.tau_lower, b.tau_upper)):  # fmt: skip
        assert np.all(x >= lo - tol) and np.all(x <= hi + tol)
    np.testing.assert_allclose(traj.q[0], result.start.q, atol=tol)
    np.testing.assert_allclose(traj.q[-1], result.goal.q, atol=tol)
    np.testing.assert_allclose(traj.v[[0, -1]], 0.0, atol=tol)


# ------------------------------------------------------------------ study 1
def test_base_case_is_a_dynamically_consistent_solution(base_result):
    """Study-1 base case converges; pin.aba defects < 1e-8 and bounds hold within 1e-7."""
    r = base_result
    assert r.status is SolveStatus.SOLVED and r.success
    # IPOPT stops with constraint violation ~1e-11; 1e-8 leaves room for round-off
    # in the 50 independent ABA evaluations.
    _check_trapezoidal(r, tol=1e-8)
    # IPOPT relaxes bounds by 1e-8 relative (bound_relax_factor): |bound| <= 9.5 -> 1e-7.
    _check_bounds(r, tol=1e-7)
    assert r.max_violation < 1e-7


def test_base_case_objective_terms(base_result):
    """T = (N - 1) dt, W = sum dt (w_k + w_k+1) / 2 and f = (T + W) / 2, recomputed (1e-12)."""
    r = base_result
    tau = r.trajectory.tau
    w = np.sum(tau**2, axis=1)
    work = sum(r.dt * (w[k] + w[k + 1]) / 2 for k in range(49))
    assert r.duration == pytest.approx(49 * r.dt, rel=1e-12)
    assert r.trajectory.duration == pytest.approx(r.duration, rel=1e-12)
    assert r.work == pytest.approx(work, rel=1e-12)
    assert r.objective == pytest.approx(0.5 * r.duration + 0.5 * work, rel=1e-12)
    # IPOPT's own final objective agrees with the recomputed one.
    assert r.objective_history[-1] == pytest.approx(r.objective, rel=1e-9)
    assert r.objective_history.size == r.iterations + 1


def test_base_case_regression(base_result):
    """The base-case optimum stays at f = 8.26980, T = 2.19400 s (reference run, 1e-5 rel).

    Not an independent oracle: it guards against silent changes; the value lies
    below the study's 9.359 because the study's code integrated the wrong
    accelerations (spec, "What the study's code actually computed").
    """
    assert base_result.objective == pytest.approx(8.269796, rel=1e-5)
    assert base_result.duration == pytest.approx(2.194004, rel=1e-5)


def test_time_reversed_motion_has_the_same_cost(base_solver, base_result, youbot):
    """Swapping start and goal gives the same optimum (1e-6 rel): tau(T - t) is feasible backwards.

    Without damping M a + C(q, v) v + g is invariant under v -> -v, so the
    time-reversed motion needs the same torques, duration and work.
    """
    p = base_solver.problem
    r = base_solver.solve(start=p.goal, goal=p.start)
    assert r.success
    assert r.objective == pytest.approx(base_result.objective, rel=1e-6)
    np.testing.assert_allclose(r.trajectory.q[::-1], base_result.trajectory.q, atol=1e-4)


def test_multiplier_sign_convention(base_solver, base_result):
    """grad f + J_g' lam_g + lam_x = 0 by finite differences; lam > 0 upper, < 0 lower bounds."""
    r, nlp = base_result, base_solver.nlp
    lam_x = np.zeros(nlp.n_variables)
    for name, block in nlp.variables.blocks.items():
        from youbot_opt.trajopt.transcription.base import BOUND_NAMES

        fam = BOUND_NAMES[name]
        lam = r.multipliers[f"{fam}_lower"] + r.multipliers[f"{fam}_upper"]
        lam_x[block.offset : block.offset + block.size] = lam.ravel()
    lam_g = nlp.constraints.pack({k: r.multipliers[k] for k in nlp.constraints.blocks})
    x = nlp.variables.pack(dict(r.variables))
    fun = ca.Function("fg", [nlp.x, nlp.p], [nlp.f, nlp.g]).expand()
    h = 1e-6  # central differences: error ~ h^2 |f'''| ~ 1e-11, round-off ~ 1e-16 / h ~ 1e-10
    grad = np.zeros_like(x)
    jt_lam = np.zeros_like(x)
    for i in range(x.size):
        e = np.zeros_like(x)
        e[i] = h
        fp, gp = fun(x + e, 0.5)
        fm, gm = fun(x - e, 0.5)
        grad[i] = float(fp - fm) / (2 * h)
        jt_lam[i] = (np.asarray(gp - gm).ravel() @ lam_g) / (2 * h)
    residual = grad + jt_lam + lam_x
    # IPOPT's dual infeasibility at tol = 1e-8 plus the FD error: 1e-6 absolute
    # against gradients of size ~ max|grad f| ~ 1e2.
    assert np.max(np.abs(residual)) < 1e-6 * max(1.0, np.max(np.abs(grad)))
    rows = r.active_bounds(1e-6)
    uppers = [a for a in rows if a.name.endswith("_upper")]
    lowers = [a for a in rows if a.name.endswith("_lower")]
    assert uppers and lowers  # the base case has speed bounds active both ways
    assert all(a.multiplier > 0 for a in uppers)
    assert all(a.multiplier < 0 for a in lowers)
    assert {a.name for a in rows} <= {"velocity_upper", "velocity_lower"}


def test_multipliers_predict_the_bound_scale_sensitivity(base_solver, base_result):
    """d f* / d s = -sum lam_x * bound / s (first-order sensitivity), within 2 %.

    Every bound is s times its data-sheet value, so a central difference of
    re-solves at s = 1 +- 0.002 must match the multipliers' prediction.
    """
    r = base_result
    b = r.bounds()
    pairs = {"position": (b.q_lower, b.q_upper), "velocity": (b.v_lower, b.v_upper),
             "torque": (b.tau_lower, b.tau_upper)}  # fmt: skip
    predicted = 0.0
    for fam, (lo, hi) in pairs.items():
        predicted -= np.sum(r.multipliers[f"{fam}_lower"] * lo + r.multipliers[f"{fam}_upper"] * hi)
    ds = 2e-3
    fp = base_solver.solve(bound_scale=1 + ds, guess=r).objective
    fm = base_solver.solve(bound_scale=1 - ds, guess=r).objective
    # 2 %: the central difference has an O(ds^2) curvature error plus active-set
    # changes at the ends of the speed arcs.
    assert (fp - fm) / (2 * ds) == pytest.approx(predicted, rel=0.02)
    assert predicted < 0  # looser bounds, lower cost


def test_hermite_simpson_base_case(hs_result, base_result, youbot):
    """Hermite-Simpson solves the base case; its Simpson defects, rechecked with pin.aba, vanish."""
    r = hs_result
    assert r.success and r.trajectory.interpolation == "hermite_simpson"
    robot, dt = youbot, r.dt
    q, v, tau = r.variables["q"], r.variables["v"], r.variables["tau"]
    qm, vm, taum = r.variables["q_mid"], r.variables["v_mid"], r.variables["tau_mid"]
    a, am = _aba(robot, q, v, tau), _aba(robot, qm, vm, taum)
    np.testing.assert_allclose(q[1:] - q[:-1] - dt / 6 * (v[:-1] + 4 * vm + v[1:]), 0, atol=1e-8)
    np.testing.assert_allclose(v[1:] - v[:-1] - dt / 6 * (a[:-1] + 4 * am + a[1:]), 0, atol=1e-8)
    np.testing.assert_allclose(qm - (q[:-1] + q[1:]) / 2 - dt / 8 * (v[:-1] - v[1:]), 0, atol=1e-8)
    # Hermite-Simpson is 4th order: at 50 knots it lies within 3 % of the trapezoidal
    # value (the exact figure is pinned in test_hermite_simpson_base_case_objective).
    assert abs(r.objective / base_result.objective - 1) < 0.03


class _HermiteSimpsonWithoutHull(HermiteSimpsonCollocation):
    """HS bounding only the knot and midpoint velocities (the scheme before the hull rows)."""

    unbounded = ()

    def path_constraints(self, sym, accel):
        return []


def _speed_overshoot(result, samples_per_interval=400):
    """Largest relative speed-bound excess of the result's Trajectory, sampled densely.

    400 samples per interval: the cubic's maximum between two samples exceeds the
    larger sample by at most (h / 400)^2 max|d^2v/dt^2| / 8 ~ 1e-8 rad/s here.
    """
    traj, b = result.trajectory, result.bounds()
    t = np.linspace(traj.t[0], traj.t[-1], samples_per_interval * (traj.n_knots - 1) + 1)
    v = traj.velocity(t)
    return float(np.max(np.maximum(v - b.v_upper, b.v_lower - v) / b.v_upper))


@pytest.mark.parametrize("n", [50, 100])
def test_hermite_simpson_speed_bound_holds_between_knots(youbot, n):
    """HS velocity interpolant stays within the speed bounds everywhere (dense sampling, 1e-6 rel).

    The Bernstein control points of every interval's velocity cubic are bounded,
    so by the convex-hull property the excess is only IPOPT's bound relaxation
    (1e-8 relative); 1e-6 is far below the certificate's 1e-2.
    """
    r = solve(study1_problem(n, robot=youbot), method="hermite_simpson")
    assert r.success
    assert _speed_overshoot(r) < 1e-6
    checks = {(c.quantity, c.where): c for c in certify_bounds(r.trajectory, r.bounds())}
    assert checks["velocity", "between"].relative < 1e-6


def test_hermite_simpson_without_hull_rows_overshoots(youbot):
    """Control: bounding only knot and midpoint speeds lets the cubic overshoot by > 1e-2."""
    r = solve(study1_problem(50, robot=youbot), method=_HermiteSimpsonWithoutHull())
    assert r.success
    # 8.4 % on joint 2 at t ~ 2.15 s (reference run); the certificate allows 1 %.
    assert _speed_overshoot(r) > 1e-2


def test_hermite_simpson_trajectory_matches_the_midpoint_variables(youbot):
    """The HS Trajectory passes through q_mid, v_mid, tau_mid with slope a_mid there (1e-8)."""
    r = solve(study1_problem(20, robot=youbot), method="hermite_simpson")
    traj, var = r.trajectory, r.variables
    tm = traj.t[:-1] + 0.5 * r.dt
    # The Hermite midpoint conditions hold to IPOPT's constraint violation (~1e-11);
    # 1e-8 is round-off headroom.
    np.testing.assert_allclose(traj(tm), var["q_mid"], atol=1e-8)
    np.testing.assert_allclose(traj.velocity(tm), var["v_mid"], atol=1e-8)
    np.testing.assert_allclose(traj.torque(tm), var["tau_mid"], atol=1e-12)
    am = _aba(youbot, var["q_mid"], var["v_mid"], var["tau_mid"])
    # Central difference of a cubic: truncation O(eps^2 |v'''|) ~ 1e-12 and
    # round-off ~1e-16 / eps ~ 1e-8 (|v| ~ 1 rad/s); the Simpson defect holds to ~1e-9.
    eps = 1e-4 * r.dt
    slope = (traj.velocity(tm + eps) - traj.velocity(tm - eps)) / (2 * eps)
    np.testing.assert_allclose(slope, am, atol=1e-6)


def test_pinocchio_backend_reaches_the_same_optimum(youbot):
    """The Callback backend (limited-memory Hessian) finds the symbolic optimum (1e-6 rel)."""
    problem = study1_problem(15, robot=youbot)
    ref = solve(problem)
    cb = solve(problem, backend="pinocchio")
    assert ref.success and cb.success and cb.backend == "pinocchio"
    assert cb.objective == pytest.approx(ref.objective, rel=1e-6)


def test_warm_start_from_a_result(base_solver, base_result):
    """Re-solving from the solution converges in a handful of iterations to the same f (1e-8)."""
    r = base_solver.solve(guess=base_result)
    assert r.success and r.iterations <= 10
    assert r.objective == pytest.approx(base_result.objective, rel=1e-8)


def test_fixed_duration(youbot):
    """With duration = 3 s the result lasts 3 s (1e-12) and dt = 3 / 49."""
    r = solve(study1_problem(20, robot=youbot, duration=3.0))
    assert r.success
    assert r.duration == pytest.approx(3.0, rel=1e-12)
    assert r.dt == pytest.approx(3.0 / 19, rel=1e-12)


# ------------------------------------------------------------ analytic toys
@pytest.mark.parametrize("n", [11, 21])
def test_double_integrator_minimum_time(slider, n):
    """Rest-to-rest min time of a double integrator: T* = 2 sqrt(d / a_max).

    Hermite-Simpson represents the bang-bang optimum exactly (1e-7 rel: IPOPT's
    1e-8 bound relaxation); the trapezoid overestimates it by at most
    1/M^2 for M intervals (measured ~0.98/M^2).
    """
    t_star = 2 * np.sqrt(SLIDER_DISTANCE / (SLIDER_FORCE / SLIDER_MASS))
    hs = solve(_slider_problem(slider, n), method="hermite_simpson", beta=1.0)
    tr = solve(_slider_problem(slider, n), method="trapezoidal", beta=1.0)
    assert hs.success and tr.success
    assert hs.duration == pytest.approx(t_star, rel=1e-7)
    assert 0 < tr.duration / t_star - 1 <= 1.05 / (n - 1) ** 2


def test_double_integrator_time_and_work_and_method_agreement(slider):
    """beta = 0.5: T* = (36 (1 - b) m^2 d^2 / b)^(1/4); methods agree better as knots grow.

    Optimal force is linear in time, so Hermite-Simpson is exact (1e-8 rel) and
    the trapezoid converges at second order.
    """
    beta, m, d = 0.5, SLIDER_MASS, SLIDER_DISTANCE
    t_star = (36 * (1 - beta) * m**2 * d**2 / beta) ** 0.25
    f_star = beta * t_star + (1 - beta) * 12 * m**2 * d**2 / t_star**3
    gaps = []
    for n in (6, 11, 21):
        hs = solve(_slider_problem(slider, n), method="hermite_simpson", beta=beta)
        tr = solve(_slider_problem(slider, n), beta=beta)
        assert hs.success and tr.success
        assert hs.duration == pytest.approx(t_star, rel=1e-8)
        assert hs.objective == pytest.approx(f_star, rel=1e-8)
        gaps.append(abs(tr.objective - hs.objective) / f_star)
    # Second order: halving the step divides the gap by ~4; require > 3.
    assert gaps[0] > 3 * gaps[1] > 9 * gaps[2]
    assert gaps[2] < 1 / 20**2


# -------------------------------------------------------------- any robot
def test_ur5_short_horizon(youbot):
    """UR5 point-to-point in 10 knots: success, pin.aba defects < 1e-8, bounds hold."""
    ur5 = load_model("ur5")
    q0 = np.array([0.0, -1.2, 1.0, -0.5, 0.3, 0.0])
    q1 = np.array([0.8, -0.6, 0.4, -1.2, -0.3, 0.5])
    problem = TrajOptProblem(
        robot=ur5, start=BoundaryState(q=q0), goal=BoundaryState(q=q1), n_knots=10
    )
    r = solve(problem)
    assert r.success, r.message
    _check_trapezoidal(r, tol=1e-8)
    _check_bounds(r, tol=1e-6)  # UR5 bounds up to 150 N m: relaxation within 1e-7 (nlp.ipopt)


def test_ur5_minimum_time_ends_inside_its_torque_bounds():
    """UR5 at beta = 1 (bang-bang torques at 150 N m): no bound exceeded past IPOPT's tolerance.

    IPOPT relaxes every bound by ``bound_relax_factor * max(1, |bound|)`` while it
    iterates and returns a point of the relaxed box: with its default 1e-8 the
    torques ended 1.4e-6 N m past 150 N m, over the 1e-6 feasibility tolerance (a
    false ``constraint_violation``, still what ``extra`` asking for that factor
    gives). The solver lowers the factor for bounds this large
    (``nlp.ipopt.bound_relaxation``): every bound then holds within a tenth of the
    tolerance, and the solve is a success.
    """
    ur5 = load_model("ur5")
    q0 = np.array([0.0, -1.2, 1.0, -0.5, 0.3, 0.0])
    q1 = np.array([0.8, -0.6, 0.4, -1.2, -0.3, 0.5])
    problem = TrajOptProblem(
        robot=ur5, start=BoundaryState(q=q0), goal=BoundaryState(q=q1), n_knots=10
    )
    r = solve(problem, beta=1.0)
    assert r.status is SolveStatus.SOLVED and r.success, r.message
    assert r.max_violation <= 0.1 * r.feasibility_tol
    b, tau = r.bounds(), r.trajectory.tau
    assert np.any(np.isclose(np.abs(tau), b.tau_upper, rtol=0, atol=1e-6))  # bang-bang
    _check_bounds(r, tol=0.1 * r.feasibility_tol)
    _check_trapezoidal(r, tol=1e-8)
    ipopt_default = IpoptOptions(extra={"bound_relax_factor": 1e-8})
    relaxed = solve(problem, beta=1.0, options=ipopt_default)
    assert relaxed.status is SolveStatus.CONSTRAINT_VIOLATION
    assert np.max(np.abs(relaxed.trajectory.tau) - b.tau_upper) > relaxed.feasibility_tol


def test_panda_minimum_time_short_horizon():
    """Panda (8 joints: finger 2 mimics finger 1, so it is locked) min-time move in 10 HS knots.

    Built with ``compile=False`` (CasADi's VM instead of C code generation for
    the 8-joint kernels: ~1.5 s build instead of a long C compile). Measured:
    T = 0.243408 s in 22 iterations (23 with the finger free: its mass barely
    matters); local position error 3.7e-4 rad, feedback RMS ratio 1.7e-3, far
    inside the certificate's 5e-2 and 5e-2.
    """
    from youbot_opt.trajopt.certify import certify

    with pytest.warns(YoubotOptWarning, match="panda_finger_joint2"):
        panda = load_model("panda")
    q0 = np.array([0.0, -0.5, 0.0, -2.0, 0.0, 1.6, 0.8, 0.02])
    q1 = np.array([0.5, -0.2, 0.3, -1.6, 0.2, 1.9, 0.4, 0.02])
    problem = TrajOptProblem(
        robot=panda, start=BoundaryState(q=q0), goal=BoundaryState(q=q1), n_knots=10
    )
    r = TrajOptSolver(problem, "hermite_simpson", compile=False).solve(beta=1.0)
    assert r.success, r.message
    # IPOPT tol = 1e-8: the local optimum's T is reproducible far below 1e-5 relative.
    assert r.duration == pytest.approx(0.243408, rel=1e-5)
    q, v, tau, dt = r.variables["q"], r.variables["v"], r.variables["tau"], r.dt
    vm = r.variables["v_mid"]
    am = _aba(panda, r.variables["q_mid"], vm, r.variables["tau_mid"])
    a = _aba(panda, q, v, tau)
    # Simpson defects by pin.aba: IPOPT's constraint violation (~1e-10) plus round-off.
    np.testing.assert_allclose(q[1:] - q[:-1] - dt / 6 * (v[:-1] + 4 * vm + v[1:]), 0, atol=1e-8)
    np.testing.assert_allclose(v[1:] - v[:-1] - dt / 6 * (a[:-1] + 4 * am + a[1:]), 0, atol=1e-8)
    _check_bounds(r, tol=1e-6)  # panda torques up to 87 N m: relaxation within 1e-7
    cert = certify(r)
    assert cert.ok, cert.failures()


# ---------------------------------------------------------------- failures
def test_iteration_cap_is_a_status_with_the_last_iterate(youbot):
    """max_iter = 2 gives MAX_ITERATIONS with a finite iterate; raise_for_status raises."""
    r = solve(study1_problem(robot=youbot), options=IpoptOptions(max_iter=2))
    assert r.status is SolveStatus.MAX_ITERATIONS and not r.success
    assert r.iterations == 2 and r.trajectory is not None
    assert r.max_violation > 1e-6  # two iterations cannot close the defects
    with pytest.raises(SolveFailed, match="max_iterations") as info:
        r.raise_for_status()
    assert info.value.result is r


def test_infeasible_duration_is_a_status(youbot):
    """Moving 2.1 rad in 0.2 s at <= 1.57 rad/s is impossible: INFEASIBLE, not an exception."""
    r = solve(study1_problem(20, robot=youbot, duration=0.2))
    assert r.status is SolveStatus.INFEASIBLE and not r.success
    # Any point of this NLP violates some row by at least this much: joint 3 must
    # travel 2 pi / 3 rad but at most 0.2 s * 1.5708 rad/s = 0.314 rad are covered by
    # speeds within bounds, and the shortfall is shared by at most 19 position defects
    # and the 2 boundary rows of joint 3, so the largest violation is >= shortfall / 21.
    # (The failed solve returns its least-violating iterate, which must respect it.)
    shortfall = 2 * np.pi / 3 - 0.2 * np.deg2rad(90.0)
    assert r.max_violation >= shortfall / 21 - 1e-8  # 1e-8: IPOPT's bound relaxation
    assert r.max_violation < 0.2  # and the best iterate is close to that bound


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"beta": 1.5}, "beta must be in"),
        ({"bound_scale": 0.0}, "bound_scale must be finite and > 0"),
        ({"bound_scale": 0.5}, r"start\.q\[2\]"),
        ({"start": [3.0, 0.0, 0.0]}, r"start\.q\[0\] = 3"),
        ({"goal": [0.0, 0.0]}, r"goal\.q must have shape \(3,\)"),
        ({"guess": "straight"}, "guess must be None, a Trajectory"),
    ],
)
def test_bad_solve_arguments(base_solver, kwargs, match):
    """Bad sweep parameters raise ParameterError naming the value and the limit."""
    with pytest.raises(ParameterError, match=match):
        base_solver.solve(**kwargs)


def test_bad_solver_arguments(youbot):
    """Unknown backend and transcription names raise ParameterError listing the valid ones."""
    problem = study1_problem(5, robot=youbot)
    with pytest.raises(ParameterError, match="symbolic"):
        TrajOptSolver(problem, backend="nope")
    with pytest.raises(ParameterError, match="choose one of"):
        TrajOptSolver(problem, method="euler")
    with pytest.raises(ParameterError, match="TrajOptProblem"):
        TrajOptSolver("problem")  # type: ignore[arg-type]


def test_without_a_compiler_the_solver_falls_back_to_the_vm(youbot, monkeypatch, base_result):
    """No C compiler: one warning, VM kernels, and the same optimum as compiled kernels (1e-9)."""
    from youbot_opt.exceptions import YoubotOptWarning

    monkeypatch.setenv("CC", "/nonexistent/cc")
    with pytest.warns(YoubotOptWarning, match="no C compiler"):
        solver = TrajOptSolver(study1_problem(robot=youbot))
    assert not solver.compiled
    r = solver.solve(beta=0.5)
    # Same NLP and derivatives, evaluated by another code path: IPOPT takes the same
    # steps up to round-off, so the optima agree far below the 1e-8 tolerance.
    assert r.success and r.objective == pytest.approx(base_result.objective, rel=1e-9)


def test_structured_and_casadi_derivatives_reach_the_same_optimum(youbot, base_result):
    """CasADi's AD of the whole expanded graph finds the structured-derivative optimum (1e-9)."""
    import casadi as ca

    solver = TrajOptSolver(study1_problem(robot=youbot), compile=False)
    nlp = solver.nlp
    reference = ca.nlpsol(
        "reference",
        "ipopt",
        ca.Function("nlp", [nlp.x, nlp.p], [nlp.f, nlp.g], ["x", "p"], ["f", "g"]).expand(),
        solver.options.to_casadi(True),
    )
    problem = solver.problem
    bounds = problem.bounds(1.0)
    lbx, ubx = nlp.variable_bounds(bounds, (problem.dt_min, problem.dt_max))
    lbg, ubg = nlp.constraint_bounds(problem.start, problem.goal, bounds)
    x0 = nlp.variables.pack(solver.method.knot_guess(base_result.guess, problem.n_knots))
    sol = reference(x0=x0, p=0.5, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
    assert reference.stats()["success"]
    # Both converge to tol = 1e-8 on the same NLP; the optimum is locally unique.
    assert float(sol["f"]) == pytest.approx(base_result.objective, rel=1e-9)


# ------------------------------------------------- HS active set and multipliers
@pytest.fixture(scope="module")
def hs_result(youbot):
    """The Hermite-Simpson base case: 50 knots, beta = 0.5."""
    r = TrajOptSolver(study1_problem(50, robot=youbot), "hermite_simpson").solve(beta=0.5)
    assert r.success, r.message
    return r


def test_hermite_simpson_base_case_objective(hs_result):
    """HS 50-knot base case: f = 8.099726, T = 2.2667 s, W = 13.9328 (documented values).

    IPOPT converges to tol = 1e-8 (relative KKT error); the optimum it returns
    moves by far less than the rounding of the documented digits, so each
    figure is asserted to half a unit of its last printed digit.
    """
    assert hs_result.objective == pytest.approx(8.099726, abs=5e-7)
    assert hs_result.duration == pytest.approx(2.2667, abs=5e-5)
    assert hs_result.work == pytest.approx(13.9328, abs=5e-5)


def _control_points(result, youbot):
    """Inner Bernstein control points of each interval's velocity cubic, by pin.aba."""
    v, dt = result.variables["v"], result.dt
    a = _aba(youbot, result.variables["q"], v, result.variables["tau"])
    return {"velocity_control_left": v[:-1] + dt / 3 * a[:-1],
            "velocity_control_right": v[1:] - dt / 3 * a[1:]}  # fmt: skip


def test_hermite_simpson_active_set_is_the_nlp_bound_structure(hs_result, youbot):
    """HS active set: knot speed bounds and hull rows with signed multipliers; no v_mid rows.

    v_mid has no bounds in the NLP (the hull rows bound the cubic), so no
    ``velocity_mid_*`` row may be reported; every reported row has a finite
    multiplier of the side's sign; and the hull rows carrying a multiplier are
    exactly the reported ones. IPOPT's multipliers split cleanly here: the
    active hull rows have |lam_g| >= 1e-4, the others <= 2e-6 (barrier residue
    lam * gap ~ mu ~ 1e-9), so 1e-5 separates them.
    """
    r, tol = hs_result, 1e-6
    rows = r.active_bounds(tol)
    names = {a.name for a in rows}
    assert not any(n.startswith("velocity_mid") for n in names)
    assert names == {"velocity_upper", "velocity_lower", "velocity_control_left_upper",
                     "velocity_control_left_lower", "velocity_control_right_upper",
                     "velocity_control_right_lower"}  # fmt: skip
    for a in rows:
        assert np.isfinite(a.multiplier), a
        assert a.multiplier > 0 if a.name.endswith("_upper") else a.multiplier < 0, a
    b = r.bounds()
    for block, values in _control_points(r, youbot).items():
        # The reported row values are the NLP's; pin.aba reproduces them to ~1e-12.
        np.testing.assert_allclose(r.bound_structure_of().path[block].values, values, atol=1e-9)
        lam = r.multipliers[block]
        for side, sign in (("upper", 1.0), ("lower", -1.0)):
            reported = {(a.knot, a.joint) for a in rows if a.name == f"{block}_{side}"}
            strong = {tuple(map(int, kj)) for kj in np.argwhere(sign * lam > 1e-5)}
            assert reported == strong, (block, side)
            bound = b.v_upper if side == "upper" else b.v_lower
            for k, j in reported:
                assert abs(values[k, j] - bound[j]) <= tol
    # Loading drops the stored structure; re-deriving it from the method name agrees.
    import dataclasses

    again = dataclasses.replace(r, bound_structure=None).active_bounds(tol)
    assert [(a.name, a.knot, a.joint) for a in again] == [(a.name, a.knot, a.joint) for a in rows]
    # Row values by pin.aba vs the CasADi dynamics: round-off (~1e-14 here).
    np.testing.assert_allclose([a.value for a in again], [a.value for a in rows], atol=1e-9)


def _objective_with_bounds(solver, result, lbx, ubx):
    """Re-solve the NLP from the result with explicit variable bounds (CasADi AD, no warm duals)."""
    nlp, problem = solver.nlp, solver.problem
    lbg, ubg = nlp.constraint_bounds(problem.start, problem.goal, problem.bounds(1.0))
    ref = ca.nlpsol(
        "bounds_fd",
        "ipopt",
        ca.Function("nlp", [nlp.x, nlp.p], [nlp.f, nlp.g], ["x", "p"], ["f", "g"]).expand(),
        solver.options.to_casadi(True),
    )
    x0 = nlp.variables.pack(dict(result.variables))
    fs = []
    for lo, hi in zip(lbx, ubx, strict=True):
        sol = ref(x0=x0, p=result.beta, lbx=lo, ubx=hi, lbg=lbg, ubg=ubg)
        assert ref.stats()["success"]
        fs.append(float(sol["f"]))
    return fs


def test_one_bound_perturbed_changes_f_by_minus_lambda_delta(base_solver, base_result):
    """d f* / d b = -lam for ONE upper and ONE lower speed bound (central difference, 1e-4).

    The most strongly active upper and lower speed bounds (lam = 0.154 and
    -0.049) are moved by +-delta; the objective change over 2 delta must be
    -lam. With delta = 1e-3 rad/s, f moves by lam * delta ~ 5e-5..1.5e-4,
    while IPOPT's optimum is accurate to ~1e-10 at tol = 1e-8, an error of
    ~1e-6 relative on the quotient; the central difference cancels the
    curvature term. Measured: 7e-7 relative; 1e-4 leaves a 100x margin and
    still rejects any other sign or scale convention.
    """
    r, nlp, problem = base_result, base_solver.nlp, base_solver.problem
    lbx, ubx = nlp.variable_bounds(problem.bounds(1.0), (problem.dt_min, problem.dt_max))
    offset = nlp.variables["v"].offset
    delta = 1e-3  # [rad/s]
    for side in ("upper", "lower"):
        lam = r.multipliers[f"velocity_{side}"]
        k, j = np.unravel_index(np.argmax(np.abs(lam)), lam.shape)
        i = offset + k * problem.nv + j
        assert r.variables["v"][k, j] == pytest.approx((ubx if side == "upper" else lbx)[i])
        bounds = []
        for step in (delta, -delta):
            lo, hi = lbx.copy(), ubx.copy()
            (hi if side == "upper" else lo)[i] += step
            bounds.append((lo, hi))
        fp, fm = _objective_with_bounds(base_solver, r, *zip(*bounds, strict=True))
        assert (fp - fm) / (2 * delta) == pytest.approx(-lam[k, j], rel=1e-4), side


# -------------------------------------------------------- feasibility tolerance
def test_feasibility_tol_reaches_the_result(youbot):
    """TrajOptSolver(feasibility_tol=...) is the result's; its status and check_result agree."""
    from youbot_opt.trajopt.check import check_result
    from youbot_opt.trajopt.result import DEFAULT_FEASIBILITY_TOL
    from youbot_opt.trajopt.solver import DEFAULT_FEASIBILITY_TOL as SOLVE_DEFAULT

    assert SOLVE_DEFAULT is DEFAULT_FEASIBILITY_TOL  # one definition
    problem = study1_problem(15, robot=youbot)
    # IPOPT relaxes bounds by 1e-8 relative (~1.6e-8 rad/s on a speed-limited
    # arc), so 1e-14 fails the check and 1e-4 passes it.
    for tol, status in ((1e-14, SolveStatus.CONSTRAINT_VIOLATION), (1e-4, SolveStatus.SOLVED)):
        r = TrajOptSolver(problem, feasibility_tol=tol).solve(beta=0.5)
        assert r.feasibility_tol == tol
        assert r.status is status, r.message
        assert check_result(r).status is r.status


def test_no_default_time_cap():
    """Decision (options.py): no CPU-time cap by default, max_iter bounds the run."""
    opts = IpoptOptions()
    assert opts.max_cpu_time is None and opts.max_iter == 3000
    assert "max_cpu_time" not in opts.to_casadi(True)["ipopt"]
    assert IpoptOptions(max_cpu_time=5.0).to_casadi(True)["ipopt"]["max_cpu_time"] == 5.0


# ------------------------------------------------------------------ CLI solve
@pytest.fixture()
def in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    return tmp_path


def test_cli_all_starts_failing_still_prints_json_and_writes_the_folder(in_tmp, capsys):
    """`solve --json --starts 2 --max-iter 1`: one JSON object, a folder, exit 1."""
    import json

    from youbot_opt.cli import main

    code = main(["solve", "--json", "--starts", "2", "--max-iter", "1", "--knots", "10",
                 "--out", "run"])  # fmt: skip
    assert code == 1
    out = capsys.readouterr().out
    summary = json.loads(out)  # exactly one object: json.loads rejects trailing text
    assert summary["success"] is False and summary["status"] == "max_iterations"
    assert summary["multistart"]["success_rate"] == 0.0
    assert len(summary["multistart"]["starts"]) == 3  # straight line + 2 splines
    folder = in_tmp / "run"
    assert json.loads((folder / "summary.json").read_text()) == summary
    assert (folder / "result.npz").exists()


def test_cli_starts_run_in_a_pool_with_progress(in_tmp, capsys):
    """`solve --starts 2` runs through run_multistart's pool and reports each start on stderr."""
    from youbot_opt.cli import main

    assert main(["solve", "--starts", "2", "--knots", "10", "--guess", "spline",
                 "--workers", "2", "--out", "run"]) == 0  # fmt: skip
    err = capsys.readouterr().err
    assert "solve: 1/2" in err and "solve: 2/2" in err
    main(["solve", "--starts", "2", "--knots", "10", "--json", "--out", "quiet"])
    assert "solve: 1/" not in capsys.readouterr().err  # no progress with --json


def test_cli_spline_guess_at_five_knots_uses_the_multistart_dt0(in_tmp, capsys, youbot):
    """`--knots 5 --guess spline` solves: the guess lasts 4.9 s (default_dt0), not 0.4 s."""
    import json

    from youbot_opt.cli import main
    from youbot_opt.trajopt.io import load_result
    from youbot_opt.trajopt.sweep import default_dt0

    argv = ["solve", "--knots", "5", "--guess", "spline", "--json", "--out", "run", "--no-refine"]
    assert main(argv) == 0  # the saved guess is the spline's (refinement would replace it)
    assert json.loads(capsys.readouterr().out)["success"] is True
    guess = load_result(in_tmp / "run" / "result.npz").guess
    assert guess.duration == pytest.approx(4 * default_dt0(study1_problem(5)), rel=1e-12)


def test_cached_kernels_load_without_being_derived(youbot, monkeypatch, tmp_path):
    """A second solver of one robot loads its compiled kernels by what they derive from.

    The first build (into an empty cache) derives and compiles the kernels and
    indexes them by the forward dynamics; the second must not derive them
    (``dynamics_kernels`` is made to fail) and reaches the first's optimum:
    the same compiled code, the same IPOPT steps (1e-12 relative). A robot
    whose dynamics differ (damped) is not found by that index.
    """
    from youbot_opt.nlp.codegen import find_compiler
    from youbot_opt.trajopt import solver as solver_module

    if find_compiler() is None:
        pytest.skip("no C compiler")
    monkeypatch.setenv("YOUBOT_OPT_CACHE", str(tmp_path))
    problem = study1_problem(8, robot=youbot)
    first = TrajOptSolver(problem, compile="wait")
    assert first.compiled
    expected = first.solve(beta=0.5)

    def underived(*_: object) -> None:
        raise AssertionError("the cached kernels were derived again")

    monkeypatch.setattr(solver_module, "dynamics_kernels", underived)
    second = TrajOptSolver(problem, compile="wait")
    assert second.compiled
    again = second.solve(beta=0.5)
    assert again.success and again.objective == pytest.approx(expected.objective, rel=1e-12)
    elbow = load_model("youbot", lock_joints={"arm_joint_3": 0.0})  # 2 joints: other dynamics
    other = TrajOptProblem(
        robot=elbow,
        start=BoundaryState(q=np.array([-0.5, -0.5])),
        goal=BoundaryState(q=np.array([0.5, 0.5])),
        n_knots=8,
    )
    with pytest.raises(AssertionError, match="derived again"):
        TrajOptSolver(other, compile="wait")


def test_a_solver_solved_often_expands_its_functions_to_sx(youbot, monkeypatch):
    """After ``EXPAND_AFTER_SOLVES`` solves the NLP functions run as SX, with the same values.

    The expanded functions are the assembled (MX) ones' arithmetic as one SX graph
    each, the compiled kernels left as calls: at a random point their values and
    derivatives agree to 1e-12 relative (the same operations, compiled kernels
    shared), and the solves on either side of the switch reach the same optimum
    (1e-9 relative: both converge to IPOPT's tol = 1e-8 on the same NLP, as the
    VM/compiled test above). A solver solved fewer times keeps the MX functions.
    """
    from youbot_opt.nlp.codegen import find_compiler
    from youbot_opt.trajopt import solver as solver_module

    if find_compiler() is None:
        pytest.skip("no C compiler: the expansion needs compiled kernels")
    monkeypatch.setattr(solver_module, "EXPAND_AFTER_SOLVES", 2)
    solver = TrajOptSolver(study1_problem(robot=youbot), compile="wait")
    assert solver.compiled
    assembled = solver.first_order_functions()
    assert all(fn.is_a("MXFunction") for fn in assembled)
    before = [solver.solve(beta=0.5) for _ in range(2)]
    assert not solver.expanded
    after = solver.solve(beta=0.5)
    assert solver.expanded
    expanded = solver.first_order_functions()
    assert all(fn.is_a("SXFunction") for fn in expanded)
    rng = np.random.default_rng(5)
    x = rng.uniform(-0.5, 0.5, solver.nlp.n_variables)
    x[-1] = 0.05  # dt [s]
    for old, new in zip(assembled, expanded, strict=True):
        for a, b in zip(old(x, 0.5), new(x, 0.5), strict=True):
            a, b = np.asarray(ca.densify(a)), np.asarray(ca.densify(b))
            assert np.max(np.abs(a - b)) <= 1e-12 * max(1.0, float(np.max(np.abs(a))))
    for r in (*before, after):
        assert r.success and r.objective == pytest.approx(before[0].objective, rel=1e-9)


def test_a_solver_on_vm_kernels_is_not_expanded(youbot, monkeypatch):
    """Kernels in CasADi's VM are never expanded (that would inline the dynamics' derivatives)."""
    from youbot_opt.trajopt import solver as solver_module

    monkeypatch.setattr(solver_module, "EXPAND_AFTER_SOLVES", 1)
    solver = TrajOptSolver(study1_problem(8, robot=youbot), compile=False)
    assert not solver.compiled
    for _ in range(3):
        assert solver.solve(beta=0.5).success
    assert not solver.expanded
    assert all(fn.is_a("MXFunction") for fn in solver.first_order_functions())
