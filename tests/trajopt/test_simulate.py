"""The certificate's simulations against a SciPy reference: tracking, open loop, stops, failures.

The reference is the algorithm the certificate used before its own DOP853: SciPy's
``solve_ivp`` restarted at every knot, written here from the plan's public
interpolants (``trajectory(t)``, ``velocity``, ``torque``) and ``pin.aba``, run at
tolerances 1e-4 tighter than the simulation under test, so the difference is the
simulation's own error.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from scipy.integrate import solve_ivp
from test_certify import DAMPING, exact_trajectory

from youbot_opt.robot.load import load_model
from youbot_opt.trajopt import simulate as simulate_module
from youbot_opt.trajopt.certify import TRACKING_ATOL, TRACKING_RTOL, certify
from youbot_opt.trajopt.simulate import (
    PDGains,
    integrate_intervals,
    sample_times,
    simulate,
    simulate_batch,
)
from youbot_opt.trajopt.trajectory import Trajectory

UR5_START = np.array([0.0, -1.2, 1.0, -0.5, 0.3, 0.0])  # [rad], the CLI example's motion
UR5_GOAL = np.array([0.8, -0.6, 0.4, -1.2, -0.3, 0.5])
M = 20  # samples per interval, as certify's


@pytest.fixture(scope="module")
def youbot():
    """The planar youBot with the study code's joint damping."""
    return load_model("youbot", damping=DAMPING)


@pytest.fixture(scope="module")
def ur5():
    """UR5 (no joint damping)."""
    return load_model("ur5")


@pytest.fixture(scope="module")
def youbot_plan(youbot) -> Trajectory:
    """The youBot's dynamically exact 40-knot plan over 3 s (test_certify's)."""
    return exact_trajectory(youbot, 40)


@pytest.fixture(scope="module")
def ur5_plan(ur5) -> Trajectory:
    """A 30-knot quintic rest-to-rest motion of the UR5 in 1.2 s, knot torques by RNEA.

    Not dynamically exact (trapezoidal torque between knots): open loop it drifts,
    with PD tracking the feedback makes up the difference.
    """
    model, data = ur5.model, ur5.model.createData()
    duration, n = 1.2, 30
    t = np.linspace(0.0, duration, n)
    s = t / duration
    shape = (10 * s**3 - 15 * s**4 + 6 * s**5)[:, None]
    d1 = ((30 * s**2 - 60 * s**3 + 30 * s**4) / duration)[:, None]
    d2 = ((60 * s - 180 * s**2 + 120 * s**3) / duration**2)[:, None]
    dq = UR5_GOAL - UR5_START
    q, v, a = UR5_START + dq * shape, dq * d1, dq * d2
    tau = np.array([pin.rnea(model, data, *x) for x in zip(q, v, a, strict=True)])
    return Trajectory(t=t, q=q, v=v, a=a, tau=tau)


def _scaled(plan: Trajectory, scale: float) -> Trajectory:
    """The plan with its torques multiplied by ``scale``."""
    return Trajectory(t=plan.t, q=plan.q, v=plan.v, a=plan.a, tau=scale * plan.tau)


def reference_simulate(
    plan: Trajectory,
    robot,
    *,
    gains: PDGains | None = None,
    stop_deviation: float | None = None,
    rtol: float = 1e-12,
    atol: float = 1e-14,
) -> tuple[np.ndarray, float | None]:
    """States ``[q, v]`` at ``sample_times(plan.t, M)`` and the stop time (None: no stop).

    ``solve_ivp`` (DOP853) from knot to knot, the state carried over; the torque
    ``tau_plan(t) + Kp (q_plan(t) - q) + Kd (v_plan(t) - v) - b v`` with the gains
    of ``gains.matrices`` at each interval's middle; the stop as a terminal event.
    """
    model, data = robot.model, robot.model.createData()
    nv = model.nv
    b = np.asarray(robot.damping, dtype=float)
    t = plan.t
    if gains is None:
        kp = kd = np.zeros((t.size - 1, nv, nv))
    else:
        kp, kd = gains.matrices(robot, plan(0.5 * (t[:-1] + t[1:])))
    times = sample_times(t, M)
    states = np.full((times.size, 2 * nv), np.nan)
    states[0] = np.concatenate([plan.q[0], plan.v[0]])
    for k in range(t.size - 1):

        def rhs(tt, x, k=k):
            q, v = x[:nv], x[nv:]
            tau = plan.torque(tt) + kp[k] @ (plan(tt) - q) + kd[k] @ (plan.velocity(tt) - v)
            return np.concatenate([v, pin.aba(model, data, q, v, tau - b * v)])

        def gap(tt, x):
            return float(np.max(np.abs(x[:nv] - plan(tt)))) - stop_deviation

        gap.terminal, gap.direction = True, 1.0
        events = None if stop_deviation is None else gap
        t_eval = times[k * M + 1 : (k + 1) * M + 1]
        sol = solve_ivp(
            rhs, (t[k], t[k + 1]), states[k * M], method="DOP853", rtol=rtol, atol=atol,
            t_eval=t_eval, events=events,
        )  # fmt: skip
        assert sol.status >= 0, sol.message
        states[k * M + 1 : k * M + 1 + sol.t.size] = sol.y.T
        if sol.status == 1:
            return states, float(sol.t_events[0][0])
    return states, None


def reference_feedback(plan: Trajectory, robot, states: np.ndarray) -> np.ndarray:
    """The PD feedback torque [N m] of ``PDGains()`` at the samples of ``states``."""
    nv = robot.model.nv
    times = sample_times(plan.t, M)
    kp, kd = PDGains().matrices(robot, plan(0.5 * (plan.t[:-1] + plan.t[1:])))
    k = np.maximum(np.arange(times.size) - 1, 0) // M  # sample j in interval (j - 1) // M
    e_q, e_v = plan(times) - states[:, :nv], plan.velocity(times) - states[:, nv:]
    return np.einsum("jab,jb->ja", kp[k], e_q) + np.einsum("jab,jb->ja", kd[k], e_v)


def _error(got: np.ndarray, want: np.ndarray) -> float:
    """Largest ``|got - want|`` in tolerances ``atol + rtol max_t |want|`` (each coordinate).

    A global error builds up from every step, so it is measured against the
    coordinate's size along the motion (not at the instant: a velocity at rest
    would ask for atol alone). NaN where ``want`` is NaN, and nowhere else, or
    the error is infinite.
    """
    if not np.array_equal(np.isnan(got), np.isnan(want)):
        return math.inf
    bound = TRACKING_ATOL + TRACKING_RTOL * np.nanmax(np.abs(want), axis=0)
    return float(np.nanmax(np.abs(got - want) / bound))


def _states(sim) -> np.ndarray:
    return np.hstack([sim.q, sim.v])


# Global error allowed, in tolerances: every step's local error is held below one
# tolerance, and the global error is about their sum, at most the number of steps
# (40-270 in these motions) where the dynamics do not amplify errors (the closed loop
# contracts; the arms open loop amplify them little over these short motions).
GLOBAL = 300.0


def _matches_reference(sim, plan, robot, **kwargs) -> None:
    """The simulation's states are within GLOBAL tolerances of the reference's."""
    truth, _ = reference_simulate(plan, robot, **kwargs)
    assert _error(_states(sim), truth) <= GLOBAL


@pytest.mark.parametrize("robot_name", ["youbot", "ur5"])
def test_tracking_matches_the_reference(robot_name, request) -> None:
    """PD tracking: states at every sample within the tolerance's accumulated error."""
    robot = request.getfixturevalue(robot_name)
    plan = request.getfixturevalue(f"{robot_name}_plan")
    sim = simulate(plan, robot, gains=PDGains(), rtol=TRACKING_RTOL, atol=TRACKING_ATOL)
    truth, stop = reference_simulate(plan, robot, gains=PDGains())
    assert sim.stop_time is None and stop is None and sim.message == ""
    assert _error(_states(sim), truth) <= GLOBAL
    want_fb = reference_feedback(plan, robot, truth)
    # Kp e_q + Kd e_v: the states' error (here <= 21 tolerances, 2e-7) times the gains
    # is below 1e-4 of each joint's peak feedback
    scale = np.max(np.abs(want_fb), axis=0)
    assert np.all(np.abs(sim.tau_feedback - want_fb) <= 1e-4 * scale)
    np.testing.assert_array_equal(sim.t, sample_times(plan.t, M))


@pytest.mark.parametrize("robot_name", ["youbot", "ur5"])
def test_open_loop_matches_the_reference(robot_name, request) -> None:
    """Open loop without a stop: states at every sample within the accumulated error."""
    robot = request.getfixturevalue(robot_name)
    plan = request.getfixturevalue(f"{robot_name}_plan")
    sim = simulate(plan, robot, rtol=TRACKING_RTOL, atol=TRACKING_ATOL)
    assert sim.stop_time is None
    _matches_reference(sim, plan, robot)
    np.testing.assert_array_equal(sim.tau_feedback, 0.0)


@pytest.mark.parametrize("robot_name, scale", [("youbot", 1.1), ("ur5", 1.0)])
def test_open_loop_stops_where_the_reference_stops(robot_name, scale, request) -> None:
    """The drift reaches the stop deviation at the reference's time; NaN after it.

    The stop time is a root of ``max |q - q_plan| = stop`` on the dense output:
    the state's error e moves it by e / (drift rate), here below 1e-6 s.
    """
    robot = request.getfixturevalue(robot_name)
    plan = _scaled(request.getfixturevalue(f"{robot_name}_plan"), scale)
    stop = 0.05  # [rad]
    sim = simulate(plan, robot, stop_deviation=stop, rtol=TRACKING_RTOL, atol=TRACKING_ATOL)
    _, want_stop = reference_simulate(plan, robot, stop_deviation=stop)
    assert want_stop is not None and plan.t[0] < want_stop < plan.t[-1]
    assert sim.stop_time == pytest.approx(want_stop, abs=1e-6)
    assert sim.message == f"deviation from the plan reached {stop:g} rad"
    _matches_reference(sim, plan, robot, stop_deviation=stop)
    drift = np.max(np.abs(sim.q - plan(sim.t)), axis=1)
    assert np.nanmax(drift) <= stop and np.all(np.isnan(sim.q[sim.t > sim.stop_time]))


def test_batch_is_each_simulation_alone(ur5, ur5_plan) -> None:
    """simulate_batch (tracking and a stopping open loop stacked) = each simulate() alone.

    Both within the tolerance's accumulated error of each other; stacked, the
    open loop's stop leaves the tracking simulation to go on alone.
    """
    stop, gains = 0.05, PDGains()
    kwargs = {"rtol": TRACKING_RTOL, "atol": TRACKING_ATOL}
    track, drift = simulate_batch(
        ur5_plan, ur5, gains=(gains, None), stop_deviation=(None, stop), **kwargs
    )
    alone_track = simulate(ur5_plan, ur5, gains=gains, **kwargs)
    alone_drift = simulate(ur5_plan, ur5, stop_deviation=stop, **kwargs)
    assert drift.stop_time is not None and track.stop_time is None
    assert drift.stop_time == pytest.approx(alone_drift.stop_time, abs=1e-6)
    assert drift.message == alone_drift.message
    for got, want in ((track, alone_track), (drift, alone_drift)):
        assert _error(_states(got), _states(want)) <= GLOBAL
        np.testing.assert_array_equal(got.tau_plan, want.tau_plan)
    np.testing.assert_allclose(track.tau_feedback, alone_track.tau_feedback, rtol=0, atol=1e-5)


def test_interval_integration_matches_per_interval_reference(youbot, ur5, ur5_plan) -> None:
    """integrate_intervals = one solve_ivp per interval at 1e-3 tighter tolerances.

    Each interval is one short integration, so its error stays within ten of its
    tolerance (1e-10 relative, 1e-12 absolute).
    """
    for robot, plan in ((youbot, exact_trajectory(youbot, 20)), (ur5, ur5_plan)):
        model, data = robot.model, robot.model.createData()
        nv = model.nv
        b = np.asarray(robot.damping, dtype=float)
        q_end, v_end = integrate_intervals(plan, robot)
        for k in range(plan.n_knots - 1):

            def rhs(tt, x, model=model, data=data, plan=plan, b=b, nv=nv):
                q, v = x[:nv], x[nv:]
                return np.concatenate([v, pin.aba(model, data, q, v, plan.torque(tt) - b * v)])

            x0 = np.concatenate([plan.q[k], plan.v[k]])
            end = solve_ivp(
                rhs, (plan.t[k], plan.t[k + 1]), x0, method="DOP853", rtol=1e-13, atol=1e-15
            ).y[:, -1]  # fmt: skip
            got = np.concatenate([q_end[k], v_end[k]])
            assert np.all(np.abs(got - end) <= 10.0 * (1e-12 + 1e-10 * np.abs(end)))


@pytest.mark.parametrize("robot_name, scale", [("youbot", 1.1), ("ur5", 1.0)])
def test_certificate_figures_match_the_reference(robot_name, scale, request) -> None:
    """certify's tracking and open-loop figures = the same figures of the reference's states.

    The figures are maxima and integrals of the states' and feedback's errors
    checked above (1e-4 of the feedback, 300 tolerances of the states): 1e-4
    relative, and the open-loop stop time to 1e-6 s.
    """
    robot = request.getfixturevalue(robot_name)
    plan = _scaled(request.getfixturevalue(f"{robot_name}_plan"), scale)
    cert = certify(plan, robot)
    truth, _ = reference_simulate(plan, robot, gains=PDGains())
    times = sample_times(plan.t, M)
    fb, tau = reference_feedback(plan, robot, truth), plan.torque(times)
    rms = np.sqrt(np.trapezoid(fb**2, times, axis=0) / np.trapezoid(tau**2, times, axis=0))
    peak = np.max(np.abs(fb), axis=0) / np.max(np.abs(tau), axis=0)
    nv = robot.model.nv
    track_q = np.max(np.abs(truth[:, :nv] - plan(times)))
    track_v = np.max(np.abs(truth[:, nv:] - plan.velocity(times)))
    np.testing.assert_allclose(cert.feedback_rms_ratio, rms, rtol=1e-4)
    np.testing.assert_allclose(cert.feedback_peak_ratio, peak, rtol=1e-4)
    np.testing.assert_allclose(cert.tracking_position_error, track_q, rtol=1e-4)
    np.testing.assert_allclose(cert.tracking_velocity_error, track_v, rtol=1e-4)
    drift, stop = reference_simulate(plan, robot, stop_deviation=cert.open_loop_stop)
    if stop is None:
        final = np.max(np.abs(drift[-1, :nv] - plan.q[-1]))
        assert math.isinf(cert.open_loop_divergence_time)
        np.testing.assert_allclose(cert.open_loop_final_error, final, rtol=1e-4)
    else:
        assert math.isinf(cert.open_loop_final_error)
        assert cert.open_loop_divergence_time == pytest.approx(stop - plan.t[0], abs=1e-6)


# --------------------------------------------------------------------------- stops
def test_a_passed_deadline_stops_at_the_start(youbot, youbot_plan) -> None:
    """A deadline already passed: stopped at t[0] in interval 0, every later sample NaN."""
    for method in ("DOP853", "Radau", "RK45"):
        sim = simulate(youbot_plan, youbot, gains=PDGains(), method=method, deadline=0.0)
        assert sim.stop_time == youbot_plan.t[0]
        assert sim.message == "time limit reached in interval 0"
        assert np.all(np.isnan(sim.q[1:])) and np.all(np.isfinite(sim.q[0]))
    q_end, v_end = integrate_intervals(youbot_plan, youbot, deadline=0.0)
    assert np.all(np.isnan(q_end)) and np.all(np.isnan(v_end))


def test_a_deadline_midway_keeps_the_intervals_before_it(youbot, youbot_plan, monkeypatch) -> None:
    """The deadline passes in interval k: the samples before it are the full run's, NaN after.

    A fake clock (one second a reading) makes the deadline pass at the same
    point every run.
    """
    full = simulate(youbot_plan, youbot, gains=PDGains(), rtol=TRACKING_RTOL, atol=TRACKING_ATOL)
    clock = iter(range(10**9))
    monkeypatch.setattr(simulate_module.time, "perf_counter", lambda: float(next(clock)))
    sim = simulate(
        youbot_plan, youbot, gains=PDGains(), rtol=TRACKING_RTOL, atol=TRACKING_ATOL,
        deadline=100.0,
    )  # fmt: skip
    monkeypatch.undo()
    k = int(sim.message.removeprefix("time limit reached in interval "))
    assert 0 < k < youbot_plan.n_knots - 1 and sim.stop_time == youbot_plan.t[k]
    np.testing.assert_array_equal(sim.q[: k * M + 1], full.q[: k * M + 1])
    assert np.all(np.isnan(sim.q[k * M + 1 :])) and np.all(np.isnan(sim.v[k * M + 1 :]))


@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")  # the state overflows
@pytest.mark.parametrize("method", ["DOP853", "Radau", "RK45"])
def test_an_integrator_failure_stops_where_it_happens(youbot, method) -> None:
    """A torque of 1e200 from knot 12 on: the state overflows, the integrator fails in
    interval 11; every sample before it is the sane plan's, none after it.

    (SciPy's path, RK45 here, used to crash with AttributeError when no sample of
    the interval was reached.)
    """
    plan = exact_trajectory(youbot, 30)
    tau = plan.tau.copy()
    tau[12:] = 1e200
    bad = Trajectory(t=plan.t, q=plan.q, v=plan.v, a=plan.a, tau=tau)
    sane = simulate(plan, youbot, gains=PDGains(), method=method)
    sim = simulate(bad, youbot, gains=PDGains(), method=method)
    assert sim.message.startswith("integrator failed in interval 11: ")
    assert sim.message.endswith("Required step size is less than spacing between numbers.")
    assert plan.t[11] <= sim.stop_time < plan.t[12]
    before = int(np.searchsorted(sim.t, sim.stop_time, side="right"))
    assert before >= 11 * M + 1
    np.testing.assert_array_equal(sim.q[:before], sane.q[:before])
    assert np.all(np.isnan(sim.q[before:]))
    q_end, _ = integrate_intervals(bad, youbot, method="auto" if method == "RK45" else method)
    assert np.all(np.isnan(q_end))  # one ODE for all intervals: all fail together


def test_a_failing_simulation_does_not_stop_its_batch(ur5, ur5_plan, monkeypatch) -> None:
    """Stacked with an open loop that fails (NaN once it leaves the plan by 0.1 rad), the
    tracking simulation goes on alone to the end, as it would alone.

    The NaN is injected into ``pin.aba`` (fault injection); the open loop fails
    where it fails alone.
    """
    aba = pin.aba
    low, high = ur5_plan.q.min(axis=0) - 0.1, ur5_plan.q.max(axis=0) + 0.1

    def poisoned(model, data, q, v, tau):
        acc = aba(model, data, q, v, tau)
        return acc * np.nan if np.any((q < low) | (q > high)) else acc

    kwargs = {"rtol": TRACKING_RTOL, "atol": TRACKING_ATOL}
    plan = _scaled(ur5_plan, 1.3)
    monkeypatch.setattr(pin, "aba", poisoned)
    track, drift = simulate_batch(
        plan, ur5, gains=(PDGains(), None), stop_deviation=(None, None), **kwargs
    )
    alone_drift = simulate(plan, ur5, **kwargs)
    monkeypatch.undo()
    alone_track = simulate(plan, ur5, gains=PDGains(), **kwargs)
    assert drift.message.startswith("integrator failed in interval ")
    assert drift.message == alone_drift.message
    assert drift.stop_time == pytest.approx(alone_drift.stop_time, abs=1e-12)
    assert track.stop_time is None and track.message == ""
    assert _error(_states(track), _states(alone_track)) <= GLOBAL


def test_scipy_is_imported_only_for_its_methods() -> None:
    """The default (DOP853) simulations import no SciPy: a fresh interpreter shows it."""
    import subprocess
    import sys

    code = (
        "import sys, warnings; warnings.simplefilter('ignore')\n"
        "from youbot_opt.robot.load import load_model\n"
        "from youbot_opt.trajopt.certify import certify\n"
        "from youbot_opt.trajopt.trajectory import Trajectory\n"
        "import numpy as np\n"
        "robot = load_model('youbot', damping=0.1)\n"
        "t = np.linspace(0, 1, 6); z = np.zeros((6, 3))\n"
        "certify(Trajectory(t=t, q=z, v=z, a=z, tau=z), robot)\n"
        "print(sorted(m for m in sys.modules if m.startswith('scipy')))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120
    ).stdout
    assert out.strip() == "[]"


def test_stop_deviation_and_batch_arguments_are_checked(youbot, youbot_plan) -> None:
    """A non-positive stop and mismatched batch sequences raise ParameterError."""
    from youbot_opt.exceptions import ParameterError

    with pytest.raises(ParameterError, match="stop_deviation must be > 0"):
        simulate(youbot_plan, youbot, stop_deviation=0.0)
    with pytest.raises(ParameterError, match="one entry per simulation"):
        simulate_batch(youbot_plan, youbot, gains=(None, None), stop_deviation=(None,))
    with pytest.raises(ParameterError, match="one entry per simulation"):
        simulate_batch(youbot_plan, youbot, gains=(), stop_deviation=())
