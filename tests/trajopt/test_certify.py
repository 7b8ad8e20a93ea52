"""Certificates by forward simulation: exact plans pass, wrong ones fail by the predicted amount."""

from __future__ import annotations

import json
import logging
import math
import re
import time

import numpy as np
import pinocchio as pin
import pytest
from scipy.integrate import solve_ivp
from scipy.linalg import expm

from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.load import load_model
from youbot_opt.sweeps.forked import can_fork
from youbot_opt.trajopt.certify import (
    Tolerances,
    certify,
    check_bounds,
    integrate_intervals,
)
from youbot_opt.trajopt.simulate import PDGains, simulate
from youbot_opt.trajopt.trajectory import Trajectory

DAMPING = 0.1  # [N m s/rad], the study code's joint damping
Q_START = np.array([-math.pi / 6, -math.pi / 6, -math.pi / 3])


@pytest.fixture(scope="module")
def youbot():
    """The planar youBot with the study code's joint damping (so damping is exercised)."""
    return load_model("youbot", damping=DAMPING)


@pytest.fixture(scope="module")
def exact(youbot):
    """exact(n): the youBot's exact trajectory with n knots over 3 s, built once per module."""
    cache: dict[int, Trajectory] = {}

    def get(n: int) -> Trajectory:
        if n not in cache:
            cache[n] = exact_trajectory(youbot, n)
        return cache[n]

    return get


def _quintic(t: float, duration: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rest-to-rest quintic from Q_START to -Q_START: q, v, a."""
    s = t / duration
    shape = 10 * s**3 - 15 * s**4 + 6 * s**5
    d1 = (30 * s**2 - 60 * s**3 + 30 * s**4) / duration
    d2 = (60 * s - 180 * s**2 + 120 * s**3) / duration**2
    dq = -2 * Q_START
    return Q_START + dq * shape, dq * d1, dq * d2


def exact_trajectory(robot, n: int, duration: float = 3.0) -> Trajectory:
    """Knots of pin.aba integrated (rtol 1e-12) under a piecewise-linear torque.

    The knot torques follow a quintic by inverse dynamics plus an inertia-scaled
    PD on the previous knot's state (10 rad/s), so the motion stays near the
    quintic although the arm is open-loop unstable. Independent of youbot_opt's
    simulation code: its own RHS, its own per-interval solve_ivp.
    """
    model, data = robot.model, robot.model.createData()
    b = np.asarray(robot.damping)
    t = np.linspace(0.0, duration, n)
    x = np.concatenate([Q_START, np.zeros(3)])
    qr, vr, ar = _quintic(0.0, duration)
    taus = [pin.rnea(model, data, qr, vr, ar) + b * vr]
    states = [x]
    w = 10.0  # [rad/s]
    for k in range(n - 1):
        qr, vr, ar = _quintic(t[k + 1], duration)
        qc, vc, _ = _quintic(t[k], duration)
        fb = pin.crba(model, data, qc) @ (w * w * (qc - x[:3]) + 2 * w * (vc - x[3:]))
        tau1 = pin.rnea(model, data, qr, vr, ar) + b * vr + fb
        tau0 = taus[-1]

        def rhs(tt, xx, k=k, tau0=tau0, tau1=tau1):
            u = tau0 + (tt - t[k]) / (t[k + 1] - t[k]) * (tau1 - tau0)
            return np.concatenate([xx[3:], pin.aba(model, data, xx[:3], xx[3:], u - b * xx[3:])])

        x = solve_ivp(rhs, (t[k], t[k + 1]), x, method="DOP853", rtol=1e-12, atol=1e-14).y[:, -1]
        states.append(x)
        taus.append(tau1)
    states, tau = np.array(states), np.array(taus)
    a = np.array(
        [
            pin.aba(model, data, s[:3], s[3:], u - b * s[3:])
            for s, u in zip(states, tau, strict=True)
        ]
    )
    return Trajectory(t=t, q=states[:, :3], v=states[:, 3:], a=a, tau=tau)


def _newton(residual, x: np.ndarray) -> np.ndarray:
    """Newton's method with a forward-difference Jacobian (absolute step 1e-7), to 1e-12."""
    for _ in range(30):
        r = residual(x)
        if np.max(np.abs(r)) < 1e-12 * (1.0 + np.max(np.abs(x))):
            return x
        jac = np.column_stack([(residual(x + 1e-7 * e) - r) / 1e-7 for e in np.eye(x.size)])
        x = x - np.linalg.solve(jac, r)
    raise AssertionError(f"Newton did not converge: residual {np.max(np.abs(residual(x)))}")


def trapezoidal_plan(robot, n: int, duration: float = 1.0) -> Trajectory:
    """Knots that satisfy the trapezoidal collocation equations exactly (implicit march).

    The knot torques are the quintic's inverse dynamics; each step solves
    q+ = q + h/2 (v + v+), v+ = v + h/2 (a + a+), a+ = ABA(q+, v+, tau+) to 1e-12.
    """
    model, data = robot.model, robot.model.createData()
    b = np.asarray(robot.damping)
    t = np.linspace(0.0, duration, n)
    h = t[1] - t[0]
    ref = [_quintic(tk, duration) for tk in t]
    tau = np.array([pin.rnea(model, data, q, v, a) + b * v for q, v, a in ref])

    def fd(q, v, u):
        return pin.aba(model, data, q, v, u - b * v)

    q, v = [Q_START.copy()], [np.zeros(3)]
    acc = [fd(q[0], v[0], tau[0])]
    for k in range(n - 1):

        def residual(v1, k=k):
            q1 = q[k] + 0.5 * h * (v[k] + v1)
            return v1 - v[k] - 0.5 * h * (acc[k] + fd(q1, v1, tau[k + 1]))

        v1 = _newton(residual, v[k] + h * acc[k])
        q.append(q[k] + 0.5 * h * (v[k] + v1))
        v.append(v1)
        acc.append(fd(q[-1], v1, tau[k + 1]))
    return Trajectory(t=t, q=np.array(q), v=np.array(v), a=np.array(acc), tau=tau)


def _one_joint_model(inertia: float) -> pin.Model:
    """One revolute joint, no gravity, no damping: M = inertia [kg m^2], constant."""
    model = pin.Model()
    joint = model.addJoint(0, pin.JointModelRY(), pin.SE3.Identity(), "joint")
    model.appendBodyToJoint(
        joint, pin.Inertia(1.0, np.zeros(3), np.eye(3) * inertia), pin.SE3.Identity()
    )
    model.gravity = pin.Motion.Zero()
    model.lowerPositionLimit = np.array([-10.0])
    model.upperPositionLimit = np.array([10.0])
    model.velocityLimit = np.array([10.0])
    model.effortLimit = np.array([10.0])
    return model


def _constant_torque_plan(n: int, tau0: float, inertia: float, scale: float = 1.0) -> Trajectory:
    """Exact motion under a constant torque (q quadratic); the plan's torque scaled by ``scale``."""
    t = np.linspace(0.0, 2.0, n)
    acc = tau0 / inertia
    return Trajectory(
        t=t, q=np.c_[0.1 + 0.3 * t + 0.5 * acc * t**2], v=np.c_[0.3 + acc * t],
        a=np.full((n, 1), acc), tau=np.full((n, 1), scale * tau0),
    )  # fmt: skip


# --------------------------------------------------------------------------- local errors
def test_exact_trajectory_certifies_to_integrator_tolerance(youbot, exact) -> None:
    """A dynamically exact plan has local errors at integrator level and passes."""
    traj = exact(50)
    cert = certify(traj, youbot)
    # rtol 1e-10 on a stacked system of 6 * 49 states (RMS error norm): per-component
    # errors up to sqrt(294) * 1e-10 ~ 2e-9 on states of size ~1; the reference is 1e-12.
    assert cert.local_position_max < 1e-8
    assert cert.local_velocity_max < 1e-8
    assert cert.ok, cert.failures()


def test_damping_is_applied(youbot, exact) -> None:
    """certify(damping=False) matches an independent undamped restart-per-knot simulation."""
    traj = exact(30)
    cert = certify(traj, youbot, damping=False)
    model, data = youbot.model, youbot.model.createData()
    expected_q, expected_v = [], []
    for k in range(traj.n_knots - 1):
        t0, t1 = traj.t[k], traj.t[k + 1]

        def rhs(tt, x, k=k, t0=t0, t1=t1):
            u = traj.tau[k] + (tt - t0) / (t1 - t0) * (traj.tau[k + 1] - traj.tau[k])
            return np.concatenate([x[3:], pin.aba(model, data, x[:3], x[3:], u)])

        x0 = np.concatenate([traj.q[k], traj.v[k]])
        x1 = solve_ivp(rhs, (t0, t1), x0, method="DOP853", rtol=1e-12, atol=1e-14).y[:, -1]
        expected_q.append(np.max(np.abs(x1[:3] - traj.q[k + 1])))
        expected_v.append(np.max(np.abs(x1[3:] - traj.v[k + 1])))
    # The missing damping torque b v makes errors of order 0.1-1 (joint 3 is light);
    # both simulations resolve them to ~1e-9 (rtol 1e-10 on the stacked system).
    assert min(expected_v) > 1e-4
    np.testing.assert_allclose(cert.local_position_error, expected_q, rtol=0, atol=1e-8)
    np.testing.assert_allclose(cert.local_velocity_error, expected_v, rtol=0, atol=1e-8)
    assert not cert.ok


def _sym(m: np.ndarray) -> np.ndarray:
    """Full symmetric matrix from pin.crba's upper triangle."""
    return np.triu(m) + np.triu(m, 1).T


def test_scaled_torque_fails_with_predicted_local_errors(youbot, exact) -> None:
    """Torques scaled by 1.05: local errors match the linearised error dynamics over one interval.

    Linearised about the exact motion with M and the damping b frozen at the left knot,
    the error obeys dq' = dv, dv' = M^-1 (eps tau - b dv), solved exactly by a matrix
    exponential. (The damping must be kept: joint 3 is light, M/b ~ 30 ms ~ h.)
    """
    plan = exact(100)
    eps = 0.05
    traj = Trajectory(t=plan.t, q=plan.q, v=plan.v, a=plan.a, tau=(1 + eps) * plan.tau)
    q_end, v_end = integrate_intervals(traj, youbot)
    data = youbot.model.createData()
    h = plan.t[1] - plan.t[0]
    predicted = []
    for q, u in zip(plan.q[:-1], 0.5 * (plan.tau[:-1] + plan.tau[1:]), strict=True):
        m_inv = np.linalg.inv(_sym(pin.crba(youbot.model, data, q)))
        z = np.zeros((7, 7))
        z[:3, 3:6] = np.eye(3)
        z[3:6, 3:6] = -m_inv * DAMPING
        z[3:6, 6] = m_inv @ (eps * u)
        predicted.append((expm(z * h) @ np.r_[np.zeros(6), 1.0])[:6])
    predicted = np.array(predicted)
    # The neglected terms (M, gravity, Coriolis varying along the interval) are O(h)
    # relative: measured 6 % at h = 0.03 s (11 % at 0.06 s), hence 10 % in norm.
    errors = ((q_end - plan.q[1:], predicted[:, :3]), (v_end - plan.v[1:], predicted[:, 3:]))
    for sim, pred in errors:
        assert np.linalg.norm(sim - pred) < 0.1 * np.linalg.norm(pred)
    cert = certify(traj, youbot)
    assert cert.local_velocity_max > 1e3 * certify(plan, youbot).local_velocity_max
    assert not cert.ok


def test_trapezoidal_local_error_shrinks_like_h2_or_better(youbot) -> None:
    """Exact trapezoidal-collocation plans: local error falls > 4x per halving of h."""
    errors = []
    for n in (21, 41, 81):
        plan = trapezoidal_plan(youbot, n)
        q_end, v_end = integrate_intervals(plan, youbot)
        errors.append((np.max(np.abs(q_end - plan.q[1:])), np.max(np.abs(v_end - plan.v[1:]))))
    for coarse, fine in zip(errors, errors[1:], strict=False):
        # O(h^2) or better: a ratio > 4 when h halves. Measured: position 8.8, 6.9
        # (O(h^3), the trapezoid's local order), velocity 4.9, 5.1 (tending to 8 as the
        # stiff damped joint 3, M/b ~ 30 ms, gets resolved).
        assert coarse[0] / fine[0] > 4.0, errors
        assert coarse[1] / fine[1] > 4.0, errors


# ------------------------------------------------------------------------------ tracking
def test_tracking_exact_plan_needs_no_feedback() -> None:
    """Zero gravity, constant torque: the trapezoidal plan is exact, feedback and errors vanish."""
    model = _one_joint_model(0.2)
    traj = _constant_torque_plan(11, 0.3, 0.2)
    sim = simulate(traj, model, gains=PDGains(), rtol=1e-12, atol=1e-14)
    # Integrator-level: states of size ~1, rtol 1e-12, gains ~ 400 * 0.2.
    assert np.max(np.abs(sim.q - traj(sim.t))) < 1e-10
    assert np.max(np.abs(sim.tau_feedback)) < 1e-8
    cert = certify(traj, model)
    assert cert.feedback_rms < 1e-6 and cert.feedback_peak < 1e-6
    # Neutrally stable system: open loop follows too (reported as a final error).
    assert cert.open_loop_final_error < 1e-8
    assert math.isinf(cert.open_loop_divergence_time)


def test_tracking_feedback_matches_closed_form() -> None:
    """Plan torque 5 % too large: feedback is M(w^2 e + 2 w e'), e the critically damped step."""
    inertia, tau0, eps, w = 0.2, 0.3, 0.05, 20.0
    model = _one_joint_model(inertia)
    traj = _constant_torque_plan(11, tau0, inertia, scale=1 + eps)
    sim = simulate(traj, model, gains=PDGains(bandwidth=w), rtol=1e-12, atol=1e-14)
    # e = q_plan - q solves e'' + 2 w e' + w^2 e = -eps tau0 / M from rest.
    tt = sim.t
    c = -eps * tau0 / (inertia * w**2)
    e = c * (1 - (1 + w * tt) * np.exp(-w * tt))
    de = c * w**2 * tt * np.exp(-w * tt)
    np.testing.assert_allclose(sim.q[:, 0], traj(tt)[:, 0] - e, atol=1e-10)
    np.testing.assert_allclose(sim.tau_feedback[:, 0], inertia * (w**2 * e + 2 * w * de), atol=1e-8)
    cert = certify(traj, model, gains=PDGains(bandwidth=w))
    # fb = -eps tau0 (1 + (w t - 1) exp(-w t)) peaks at w t = 2, i.e. t = 0.1 s, a sample
    # time (0.01 s grid), so the sampled peak is exact up to certify's tracking rtol (1e-8).
    peak = eps * tau0 * (1 + math.exp(-2.0))
    assert cert.feedback_peak == pytest.approx(peak / ((1 + eps) * tau0), rel=1e-7)


def test_tracking_exact_youbot_plan_feedback_small_and_shrinking(youbot, exact) -> None:
    """Exact youBot plans need < 1 % feedback, falling as knots are added (interpolation only)."""
    coarse = certify(exact(50), youbot)
    fine = certify(exact(100), youbot)
    # The only mismatch is the trapezoidal interpolant between knots, O(h^2):
    # expect ~4x less when h halves; require 2.5x to allow for the closed loop.
    assert coarse.feedback_rms < 1e-2 and coarse.feedback_peak < 2e-2
    assert fine.feedback_rms < coarse.feedback_rms / 2.5
    assert fine.tracking_position_error < coarse.tracking_position_error / 2.5
    assert coarse.ok and fine.ok


# -------------------------------------------------------------------------------- bounds
def test_bound_violation_between_knots_detected(youbot) -> None:
    """Knots on the upper position limit with v = +w, -w overshoot it by w h / 4 at mid-interval."""
    bounds = youbot.bounds()
    upper = bounds.q_upper[0]
    w, h = 1.0, 0.2  # [rad/s], [s]
    q = np.tile(Q_START, (3, 1))
    q[:2, 0] = upper
    v = np.zeros((3, 3))
    v[0, 0], v[1, 0] = w, -w
    traj = Trajectory(t=[0.0, h, 2 * h], q=q, v=v, a=np.zeros((3, 3)), tau=np.zeros((3, 3)))
    checks = {(c.quantity, c.where): c for c in check_bounds(traj, bounds)}
    assert checks["position", "knots"].excess == pytest.approx(0.0, abs=1e-15)
    worst = checks["position", "between"]
    # Quadratic position interpolant: peak u + w h / 4 at t = h / 2 (a sample point).
    assert worst.excess == pytest.approx(w * h / 4, rel=1e-12)
    assert worst.time == pytest.approx(h / 2, rel=1e-12) and worst.joint == 0
    cert = certify(traj, youbot)
    assert not cert.ok
    assert any("between knots" in f for f in cert.failures())


def test_scaled_bounds_flag_knot_violation(youbot, exact) -> None:
    """A plan within the data sheet violates 85 % bounds at the knots, by the computed amount."""
    traj = exact(50)
    bounds = youbot.bounds(0.85)
    checks = {(c.quantity, c.where): c for c in check_bounds(traj, bounds)}
    excess = np.max(np.abs(traj.tau) - bounds.tau_upper)
    assert checks["torque", "knots"].excess == pytest.approx(excess, rel=1e-12)


# ------------------------------------------------------------------------ API and reports
def test_summary_is_json_and_table_readable(youbot, exact) -> None:
    """summary() holds only JSON numbers (no NaN/inf) and str() names every check."""
    cert = certify(exact(50), youbot)
    text = json.dumps(cert.summary(), allow_nan=False)
    assert "local_position_max_rad" in text
    table = str(cert)
    for word in ("local error", "feedback", "bound torque, between knots", "open loop", "PASSED"):
        assert word in table
    strict = Tolerances(local_position=0.0)
    assert not cert.passed(strict) and cert.passed()


def test_table_prints_a_margin_as_a_margin_and_an_excess_as_an_excess(youbot, exact) -> None:
    """A bound kept prints its margin (positive), a bound crossed its excess, never a "-" excess."""
    traj = exact(50)
    kept = str(certify(traj, youbot))
    assert "excess -" not in kept
    margin = re.search(r"bound position, at knots.*margin (\S+) rad to the bound", kept)
    assert margin is not None and float(margin.group(1)) > 0.0, kept
    crossed = str(certify(traj, youbot, bounds=youbot.bounds(0.3)))
    excess = re.search(r"bound torque, at knots.*excess (\S+) N m over the bound", crossed)
    assert excess is not None and float(excess.group(1)) > 0.0, crossed


def test_bad_inputs_raise(youbot) -> None:
    """A trajectory without a robot, a wrong-size robot or bad options raise ParameterError."""
    traj = exact_trajectory(youbot, 5, duration=0.4)
    with pytest.raises(ParameterError, match="needs the robot"):
        certify(traj)
    with pytest.raises(ParameterError, match="nq = 3"):
        certify(traj, _one_joint_model(0.1))
    with pytest.raises(ParameterError, match="bandwidth"):
        PDGains(bandwidth=-1.0)
    with pytest.raises(ParameterError, match="Trajectory or a result"):
        certify(object(), youbot)
    with pytest.raises(ParameterError, match="processes"):
        certify(traj, youbot, processes=0)


def _figures(cert) -> list[np.ndarray]:
    """Every simulated figure of a certificate, as arrays."""
    return [
        cert.local_position_error, cert.local_velocity_error, cert.feedback_rms_ratio,
        cert.feedback_peak_ratio, np.array([cert.tracking_position_error,
        cert.tracking_velocity_error, cert.open_loop_final_error,
        cert.open_loop_divergence_time]),
    ]  # fmt: skip


@pytest.mark.skipif(not can_fork(), reason="the forked integrations need fork (Linux)")
def test_two_processes_give_the_same_certificate(youbot, exact) -> None:
    """The one-interval integrations in a forked process: the same computation, the same figures.

    Bit for bit: the child runs the same code on the same inputs (it is a copy
    of this process), only at the same time as the tracking simulations here.
    A wrong plan (torques 5 % high) is used so that every figure is non-zero.
    """
    traj = exact(30)
    wrong = Trajectory(t=traj.t, q=traj.q, v=traj.v, a=traj.a, tau=1.05 * traj.tau)
    for plan in (traj, wrong):
        one, two = certify(plan, youbot), certify(plan, youbot, processes=2)
        for a, b in zip(_figures(one), _figures(two), strict=True):
            np.testing.assert_array_equal(a, b)
        assert one.ok == two.ok and two.incomplete == ""
    assert not certify(wrong, youbot, processes=2).ok


@pytest.mark.skipif(not can_fork(), reason="the forked integrations need fork (Linux)")
def test_two_processes_out_of_time_say_both_stages_and_log_here(youbot, exact, caplog) -> None:
    """A deadline already passed stops both at once: every figure NaN, the certificate
    incomplete naming both stages, and the forked integrations' log line given here."""
    with caplog.at_level(logging.WARNING, logger="youbot_opt.trajopt.simulate"):
        cert = certify(exact(30), youbot, time_limit=1e-9, processes=2)
    assert cert.incomplete == (
        "time limit 1e-09 s reached during the one-interval integrations and the tracking and "
        "open-loop simulations"
    )
    assert np.all(np.isnan(cert.local_position_error)) and np.isnan(cert.tracking_position_error)
    assert not cert.ok
    assert "local integration stopped: time limit reached" in caplog.text


# ---------------------------------------------------------------- the real solver, study 1
@pytest.mark.slow
def test_study1_certificates_improve_with_knots() -> None:
    """Study 1 solved at 25/50/100 knots: local error and feedback within shrinking tolerances."""
    from youbot_opt.reproduction.study1 import study1_problem
    from youbot_opt.trajopt.solver import solve

    # Measured (trapezoidal, beta 0.5): local position 0.14 / 0.017 / 0.0068 rad,
    # feedback RMS ratio 0.076 / 0.053 / 0.02. The optimum saturates torques and reverses
    # joint 3 within about one interval, so the worst interval converges only ~O(h);
    # tolerances are twice the measurements.
    limits = {25: (0.3, 0.15), 50: (0.035, 0.11), 100: (0.015, 0.05)}
    previous = None
    for n, (local_tol, feedback_tol) in limits.items():
        result = solve(study1_problem(n), beta=0.5)
        assert result.success, result.message
        cert = certify(result)
        assert cert.local_position_max < local_tol
        assert cert.feedback_rms < feedback_tol
        assert cert.worst_bound("knots").relative < 1e-6
        if previous is not None:
            assert cert.local_position_max < previous.local_position_max
            assert cert.feedback_rms < previous.feedback_rms
        previous = cert
    # The 100-knot plan passes, yet its open-loop simulation drifts 0.5 rad away within
    # the motion (measured 0.4 s of 2.26 s): the open loop is no test of a plan.
    assert cert.ok, cert.failures()
    assert cert.open_loop_divergence_time < 0.5 * cert.duration


def test_study1_hermite_simpson_certificates_improve_with_knots() -> None:
    """HS study 1 at 25/50/100 knots: local error and feedback shrink fast and stay within bounds.

    Measured (Hermite-Simpson, beta 0.5): local position 6.5e-3 / 5.4e-4 / 7.3e-5
    rad, local velocity 0.092 / 0.012 / 2.2e-3 rad/s, feedback RMS ratio 6.5e-3 /
    1.2e-3 / 2.4e-4. Tolerances are twice the measurements. Halving the step
    divides the local position error by 12 and 7.4 (the active-set switches of
    the bang-bang-like optimum keep it below the smooth-case 16): require > 4,
    i.e. better than the trapezoid's ~O(h) at its worst interval, and feedback
    ratios (measured 5.5x, 5.0x) by > 3. Each plan passes its certificate. The
    three solves and certificates take ~1 s, so the test is not marked slow.
    """
    from youbot_opt.reproduction.study1 import study1_problem
    from youbot_opt.trajopt.solver import solve

    limits = {25: (0.013, 0.19, 0.013), 50: (1.1e-3, 0.025, 2.4e-3), 100: (1.5e-4, 4.4e-3, 4.8e-4)}
    previous = None
    for n, (position_tol, velocity_tol, feedback_tol) in limits.items():
        result = solve(study1_problem(n), beta=0.5, method="hermite_simpson")
        assert result.success, result.message
        cert = certify(result)
        assert cert.ok, cert.failures()
        assert cert.local_position_max < position_tol
        assert cert.local_velocity_max < velocity_tol
        assert cert.feedback_rms < feedback_tol
        # IPOPT's 1e-8 relative bound relaxation, at the knots and between them.
        assert cert.worst_bound("knots").relative < 1e-6
        assert cert.worst_bound("between").relative < 1e-6
        if previous is not None:
            assert cert.local_position_max < previous.local_position_max / 4
            assert cert.feedback_rms < previous.feedback_rms / 3
        previous = cert


def test_time_running_out_during_the_simulations_leaves_their_figures_unknown(
    youbot, exact, monkeypatch
) -> None:
    """The deadline passes during the tracking and open-loop simulations (one stacked run):
    the local errors are measured, the simulations' figures NaN, the certificate incomplete.

    A fake clock (one second a reading) puts the deadline ten readings past the
    one-interval integrations, whose readings are counted first.
    """
    traj = exact(30)
    clock = iter(range(10**9))
    monkeypatch.setattr(time, "perf_counter", lambda: float(next(clock)))
    integrate_intervals(traj, youbot, deadline=1e18)  # the readings the local integrations take
    readings = next(clock)
    clock = iter(range(10**9))
    cert = certify(traj, youbot, time_limit=float(readings + 10))
    monkeypatch.undo()
    assert cert.incomplete == (
        f"time limit {readings + 10:.3g} s reached during the tracking and open-loop simulations"
    )
    assert np.all(np.isfinite(cert.local_position_error)) and cert.local_position_max < 1e-6
    assert np.all(np.isnan(cert.feedback_rms_ratio)) and np.isnan(cert.tracking_position_error)
    assert math.isnan(cert.open_loop_final_error) and math.isnan(cert.open_loop_divergence_time)
    assert not cert.ok
