"""Certificates: check a planned trajectory by a path independent of its transcription.

:func:`certify` takes a solve result (or a bare
:class:`~youbot_opt.trajopt.trajectory.Trajectory` and a robot) and checks it against
Pinocchio's numeric ABA integrated by SciPy's adaptive ``solve_ivp``
(:mod:`youbot_opt.trajopt.simulate`), never against the collocation equations that
produced it (spec ``trajopt.md``: "prove each trajectory by forward
simulation"). It reports:

* **local errors** (:func:`integrate_intervals`): restart from every knot's
  state, integrate one interval under the plan's torque interpolant, compare
  with the next knot (position [rad], velocity [rad/s]). All intervals are
  integrated as one stacked ODE in normalised time, so SciPy's per-step
  overhead is paid once and one batched ABA call serves all intervals;
* **tracking**: the arm follows the plan with an inertia-scaled PD feedback
  (:class:`~youbot_opt.trajopt.simulate.PDGains`) added to the planned torque; the
  feedback torque relative to the planned torque (RMS and peak, worst joint)
  and the tracking error measure how far the plan is from a motion the arm
  can make;
* **open loop**: the plan's torque alone from the first knot. The arm is
  open-loop unstable, so this drifts from any plan, valid or not: reported
  (final-state error, time to drift by ``open_loop_stop``), never tested;
* **bounds** at the knots and between them (the interpolants sampled
  ``samples_per_interval`` times per interval) for position, velocity and
  torque against the scaled bounds, with the worst excess and where.

:class:`Tolerances` holds the documented pass/fail thresholds;
:meth:`Certificate.passed` and :attr:`Certificate.ok` apply them.
"""

from __future__ import annotations

import logging
import math
import time
from typing import Any, NamedTuple

import numpy as np
from scipy.integrate import solve_ivp

from youbot_opt._typing import Array
from youbot_opt.trajopt.certificate import BoundCheck, Certificate, Tolerances
from youbot_opt.exceptions import ParameterError
from youbot_opt.trajopt.problem import JointBounds
from youbot_opt.trajopt.simulate import (
    DEFAULT_ATOL,
    DEFAULT_RTOL,
    PDGains,
    RobotView,
    _batched_aba,
    _check_dimensions,
    _IntervalPolynomials,
    robot_view,
    sample_times,
    simulate,
)
from youbot_opt.trajopt.trajectory import Trajectory

__all__ = [
    "BoundCheck",
    "Certificate",
    "Tolerances",
    "IKCheck",
    "certify",
    "check_bounds",
    "check_ik_result",
    "integrate_intervals",
    "robot_bounds",
]

_LOG = logging.getLogger(__name__)

TRACKING_RTOL = 1e-8
"""Relative tolerance of the tracking and open-loop simulations (their figures
are ratios at the 1e-5 level and above, so tighter tolerances only cost time)."""
TRACKING_ATOL = 1e-10
"""Absolute tolerance of the tracking and open-loop simulations, in [rad] and [rad/s]."""


def robot_bounds(robot: Any, bound_scale: float = 1.0) -> JointBounds:
    """Scale all of the robot's limits by ``bound_scale`` (positions about zero).

    This is the default bound family of
    :meth:`youbot_opt.trajopt.problem.TrajOptProblem.bounds` (the study scaled every bound).

    Parameters
    ----------
    robot : RobotModel, pinocchio.Model or RobotView
        The robot (see :func:`youbot_opt.trajopt.simulate.robot_view`).
    bound_scale : float, optional
        Factor > 0 (1.0 = data sheet).

    Returns
    -------
    JointBounds
        Position [rad], velocity [rad/s] and torque [N m] bounds.

    Raises
    ------
    ParameterError
        If ``bound_scale`` is not finite and > 0.
    """
    if not (math.isfinite(bound_scale) and bound_scale > 0.0):
        raise ParameterError(
            f"bound_scale must be finite and > 0 (1.0 = data sheet), got {bound_scale!r}",
            name="bound_scale",
            value=bound_scale,
        )
    view = robot_view(robot)
    s = float(bound_scale)
    return JointBounds(
        q_lower=s * view.q_lower,
        q_upper=s * view.q_upper,
        v_lower=-s * view.velocity_limit,
        v_upper=s * view.velocity_limit,
        tau_lower=-s * view.effort_limit,
        tau_upper=s * view.effort_limit,
    )


def _worst(
    quantity: str, where: str, values: Array, times: Array, lower: Array, upper: Array
) -> BoundCheck:
    with np.errstate(invalid="ignore"):
        excess = np.maximum(values - upper, lower - values)
        half = 0.5 * (upper - lower)
        relative = np.where(np.isfinite(half) & (half > 0.0), excess / half, np.nan)
        relative = np.where(np.isfinite(excess), relative, -np.inf)
    if values.size == 0 or not np.any(np.isfinite(excess)):
        return BoundCheck(quantity, where, -math.inf, -math.inf, math.nan, -1)
    key = np.where(np.isnan(relative), np.where(excess > 0.0, np.inf, -np.inf), relative)
    i, j = np.unravel_index(int(np.argmax(key)), excess.shape)
    return BoundCheck(
        quantity, where, float(excess[i, j]), float(relative[i, j]), float(times[i]), int(j)
    )


def check_bounds(
    trajectory: Trajectory, bounds: Any, *, samples_per_interval: int = 20
) -> tuple[BoundCheck, ...]:
    """Worst position, velocity and torque bound excess at and between the knots.

    Parameters
    ----------
    trajectory : Trajectory
        The plan.
    bounds : JointBounds
        Scaled bounds (anything with ``q_lower``, ``q_upper``, ``v_lower``,
        ``v_upper``, ``tau_lower``, ``tau_upper`` of shape (nv,)).
    samples_per_interval : int, optional
        Samples per interval of the interpolants (the knots excluded for ``"between"``).

    Returns
    -------
    tuple of BoundCheck
        Six checks: for position, velocity and torque, at ``"knots"`` then ``"between"``.
    """
    times = sample_times(trajectory.t, samples_per_interval)
    inner = times[np.arange(times.size) % int(samples_per_interval) != 0]
    knot_values = (trajectory.q, trajectory.v, trajectory.tau)
    between_values = (trajectory(inner), trajectory.velocity(inner), trajectory.torque(inner))
    limits = (
        (bounds.q_lower, bounds.q_upper),
        (bounds.v_lower, bounds.v_upper),
        (bounds.tau_lower, bounds.tau_upper),
    )
    checks: list[BoundCheck] = []
    names = ("position", "velocity", "torque")
    for name, at_knots, between, (lo, hi) in zip(
        names, knot_values, between_values, limits, strict=True
    ):
        lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
        checks.append(_worst(name, "knots", at_knots, trajectory.t, lo, hi))
        checks.append(_worst(name, "between", between.reshape(inner.size, -1), inner, lo, hi))
    return tuple(checks)


def integrate_intervals(
    trajectory: Trajectory,
    robot: Any,
    *,
    rtol: float = DEFAULT_RTOL,
    atol: float = DEFAULT_ATOL,
    method: str = "DOP853",
) -> tuple[Array, Array]:
    """Integrate every interval from its left knot's state under the plan's torque.

    Interval ``k`` starts at ``(q[k], v[k])`` at time ``t[k]`` and runs to
    ``t[k + 1]`` under ``trajectory.torque(t)``. The intervals are stacked into one
    ODE in normalised time ``s in [0, 1]`` (``t = t[k] + s h[k]``), so the
    integrator's error norm is taken over all intervals together.

    Parameters
    ----------
    trajectory : Trajectory
        The plan, with N knots.
    robot : RobotModel, pinocchio.Model or RobotView
        The robot the plan is for (see :func:`robot_view`).
    rtol : float, optional
        Relative tolerance of ``solve_ivp``.
    atol : float, optional
        Absolute tolerance of ``solve_ivp`` in [rad] and [rad/s].
    method : str, optional
        ``solve_ivp`` method (an explicit Runge–Kutta method is expected).

    Returns
    -------
    q_end : ndarray, shape (N - 1, nq)
        Simulated positions in [rad] at ``t[1:]`` (NaN if the integrator failed).
    v_end : ndarray, shape (N - 1, nv)
        Simulated velocities in [rad/s] at ``t[1:]`` (NaN if the integrator failed).

    Raises
    ------
    ParameterError
        If the trajectory and the robot disagree in size or the robot is unsupported.
    """
    view = robot_view(robot)
    _check_dimensions(trajectory, view)
    batch = _batched_aba(view)
    polys = _IntervalPolynomials(trajectory)
    nv = view.model.nv
    h = polys.h
    n = h.size

    def rhs(s: float, x: Array) -> Array:
        state = x.reshape(n, 2 * nv)
        q, v = state[:, :nv], state[:, nv:]
        acc = batch(q, v, polys.torques(s))
        return (np.hstack([v, acc]) * h[:, None]).ravel()

    x0 = np.hstack([trajectory.q[:-1], trajectory.v[:-1]]).ravel()
    sol = solve_ivp(rhs, (0.0, 1.0), x0, method=method, rtol=rtol, atol=atol)
    if not sol.success:
        _LOG.warning("local integration failed: %s", sol.message)
        nan = np.full((n, nv), np.nan)
        return nan, nan.copy()
    end = sol.y[:, -1].reshape(n, 2 * nv)
    _LOG.debug("local integration: %d intervals, %d RHS evaluations", n, sol.nfev)
    return end[:, :nv], end[:, nv:]


def _ratio(num: Array, den: Array) -> Array:
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(
            den > 0.0, num / np.where(den > 0.0, den, 1.0), np.where(num > 0, np.inf, 0.0)
        )


def _resolve(
    plan: Any, robot: Any, bounds: Any, bound_scale: float, damping: bool | None
) -> tuple[Trajectory, RobotView, Any]:
    """Trajectory, robot view (with the damping the plan assumed) and bounds of a plan."""
    if isinstance(plan, Trajectory):
        if robot is None:
            raise ParameterError(
                "certify(trajectory) needs the robot: certify(trajectory, robot)", name="robot"
            )
        trajectory = plan
        use_damping = True if damping is None else bool(damping)
    else:
        found = getattr(plan, "trajectory", None)
        if not isinstance(found, Trajectory):
            status = getattr(plan, "status", None)
            raise ParameterError(
                f"cannot certify {type(plan).__name__}: expected a Trajectory or a result with "
                f"a finite trajectory (status {status})",
                name="plan",
            )
        trajectory = found
        problem = getattr(plan, "problem", None)
        if robot is None:
            robot = getattr(problem, "robot", None)
            if robot is None:
                raise ParameterError("the result has no problem.robot; pass robot=", name="robot")
        if damping is None:
            damping = bool(getattr(problem, "damping", True))
        use_damping = damping
        if bounds is None and callable(getattr(plan, "bounds", None)):
            bounds = plan.bounds()
    view = robot_view(robot)
    if not use_damping:
        view = view._replace(damping=np.zeros_like(view.damping))
    if bounds is None:
        bounds = robot_bounds(view, bound_scale)
    return trajectory, view, bounds


def certify(
    plan: Any,
    robot: Any = None,
    *,
    bounds: Any = None,
    bound_scale: float = 1.0,
    damping: bool | None = None,
    gains: PDGains | None = None,
    tolerances: Tolerances | None = None,
    samples_per_interval: int = 20,
    open_loop_stop: float = 0.5,
    rtol: float = DEFAULT_RTOL,
    atol: float = DEFAULT_ATOL,
) -> Certificate:
    """Check a plan by forward simulation with ``pin.aba``, independently of its transcription.

    Parameters
    ----------
    plan : TrajOptResult or Trajectory
        A solve result (its ``trajectory``, ``problem.robot``, ``problem.damping``
        and ``bounds()`` are used) or a bare trajectory.
    robot : RobotModel or pinocchio.Model, optional
        The robot; required for a bare trajectory, overrides the result's.
    bounds : JointBounds, optional
        Scaled bounds; by default the result's, else :func:`robot_bounds` with
        ``bound_scale``.
    bound_scale : float, optional
        Scale of the default bounds of a bare trajectory (1.0 = data sheet).
    damping : bool, optional
        Whether the robot's joint damping acts (``tau - b v``); by default the
        result's ``problem.damping``, and True for a bare trajectory.
    gains : PDGains, optional
        Tracking gains; ``PDGains()`` (20 rad/s, critically damped) by default.
    tolerances : Tolerances, optional
        Thresholds stored in the certificate for :attr:`Certificate.ok`.
    samples_per_interval : int, optional
        Samples per interval for the bound check and the tracking figures.
    open_loop_stop : float, optional
        Drift in [rad] at which the open-loop simulation stops.
    rtol, atol : float, optional
        Tolerances of the local integrations (``atol`` in [rad] and [rad/s]);
        the tracking and open-loop simulations use :data:`TRACKING_RTOL` and
        :data:`TRACKING_ATOL`.

    Returns
    -------
    Certificate
        All figures; ``certificate.ok`` applies the tolerances.

    Raises
    ------
    ParameterError
        If the plan has no trajectory, the robot is missing or does not match,
        or an option is out of range.
    """
    tic = time.perf_counter()
    trajectory, view, bounds = _resolve(plan, robot, bounds, bound_scale, damping)
    gains = PDGains() if gains is None else gains
    q_end, v_end = integrate_intervals(trajectory, view, rtol=rtol, atol=atol)
    local_q = np.max(np.abs(q_end - trajectory.q[1:]), axis=1)
    local_v = np.max(np.abs(v_end - trajectory.v[1:]), axis=1)

    sim = simulate(
        trajectory, view, gains=gains, samples_per_interval=samples_per_interval,
        rtol=TRACKING_RTOL, atol=TRACKING_ATOL,
    )  # fmt: skip
    fb, plan_tau = sim.tau_feedback, sim.tau_plan
    rms = _ratio(
        np.sqrt(np.trapezoid(fb**2, sim.t, axis=0)),
        np.sqrt(np.trapezoid(plan_tau**2, sim.t, axis=0)),
    )
    peak = _ratio(np.max(np.abs(fb), axis=0), np.max(np.abs(plan_tau), axis=0))
    if sim.stop_time is not None:  # integrator failure: figures unknown
        rms = peak = np.full(view.model.nv, np.nan)
    track_q = float(np.max(np.abs(sim.q - trajectory(sim.t))))
    track_v = float(np.max(np.abs(sim.v - trajectory.velocity(sim.t))))

    open_loop = simulate(
        trajectory, view, samples_per_interval=1, stop_deviation=open_loop_stop,
        rtol=TRACKING_RTOL, atol=TRACKING_ATOL,
    )  # fmt: skip
    if open_loop.stop_time is None:
        ol_final = float(np.max(np.abs(open_loop.q[-1] - trajectory.q[-1])))
        ol_time = math.inf
    else:
        ol_final, ol_time = math.inf, open_loop.stop_time - float(trajectory.t[0])

    checks = check_bounds(trajectory, bounds, samples_per_interval=samples_per_interval)
    return Certificate(
        robot=view.name,
        n_knots=trajectory.n_knots,
        duration=trajectory.duration,
        interpolation=trajectory.interpolation,
        local_position_error=local_q,
        local_velocity_error=local_v,
        feedback_rms_ratio=rms,
        feedback_peak_ratio=peak,
        tracking_position_error=track_q,
        tracking_velocity_error=track_v,
        open_loop_final_error=ol_final,
        open_loop_divergence_time=ol_time,
        open_loop_stop=float(open_loop_stop),
        bounds=checks,
        gains=gains,
        elapsed=time.perf_counter() - tic,
        tolerances=Tolerances() if tolerances is None else tolerances,
    )


class IKCheck(NamedTuple):
    """Verdict of :func:`check_ik_result` on an IK-path result.

    Attributes
    ----------
    passed : bool
        Finite, every target met within ``residual_tol``, limits within
        ``limit_tol`` and the reported figures equal to the recomputed ones.
    message : str
        What failed (empty when nothing did).
    residual : float
        Largest ``|F(q_j) - p_j|`` in [m] by the study's closed-form kinematics
        (not Pinocchio, not CasADi); ``inf`` when not finite.
    limit_violation : float
        Largest joint-limit excess in [rad] (0 without limits).
    """

    passed: bool
    message: str
    residual: float
    limit_violation: float


def check_ik_result(
    result: Any, *, residual_tol: float = 1e-8, limit_tol: float = 1e-12
) -> IKCheck:
    """Check an IK-path result independently of the solver that produced it.

    The tip positions come from the study's formula
    ``F = b + sum_i l_i (cos phi_i, sin phi_i)``, ``phi_i = sum_{k <= i} (q_k +
    offset_k)`` evaluated here with NumPy; ``E`` is recomputed from the
    configurations.

    Parameters
    ----------
    result : IKPathResult
        The result to check.
    residual_tol : float, optional
        Largest accepted target residual in [m] (the solvers' defaults reach ~1e-10).
    limit_tol : float, optional
        Largest accepted joint-limit excess in [rad] (both solvers keep their
        iterates inside the box).

    Returns
    -------
    IKCheck
        The verdict and the recomputed figures.
    """
    problem = result.problem
    chain = problem.chain
    q = np.asarray(result.configurations, dtype=float)
    inf = math.inf
    if q.shape != (problem.n_targets, chain.n):
        want = (problem.n_targets, chain.n)
        return IKCheck(False, f"configurations have shape {q.shape}, want {want}", inf, inf)
    figures: dict[str, Any] = {
        "objective": float(result.objective),
        "residuals": np.asarray(result.residuals, dtype=float),
        "limit_violation": float(result.limit_violation),
    }
    nonfinite = [k for k, x in figures.items() if not np.all(np.isfinite(x))]
    if not np.all(np.isfinite(q)):
        nonfinite.insert(0, "configurations")
    if nonfinite:
        return IKCheck(False, f"non-finite values in {', '.join(nonfinite)}", inf, inf)
    phi = np.cumsum(q + chain.angle_offset, axis=1)
    tips = chain.base + np.stack([np.cos(phi) @ chain.lengths, np.sin(phi) @ chain.lengths], axis=1)
    residuals = np.linalg.norm(tips - problem.targets, axis=1)
    residual = float(np.max(residuals))
    limits = 0.0
    if problem.use_limits:
        limits = float(np.max(np.maximum(chain.q_lower - q, q - chain.q_upper), initial=0.0))
        limits = max(limits, 0.0)
    energy = 0.5 * float(np.sum((np.roll(q, -1, axis=0) - q) ** 2))
    wrong = []
    if not residual <= residual_tol:
        wrong.append(f"target residual {residual:.3g} m > {residual_tol:.3g} m")
    if not limits <= limit_tol:
        wrong.append(f"joint limits violated by {limits:.3g} rad > {limit_tol:.3g} rad")
    # Reported figures against the recomputed ones: Pinocchio's and the closed
    # form's tip positions agree to rounding (1e-12 on unit-size chains).
    scale = 1.0 + float(np.sum(chain.lengths))
    if not abs(figures["objective"] - energy) <= 1e-9 * max(1.0, energy):
        wrong.append(f"reported E = {figures['objective']:.12g}, recomputed {energy:.12g}")
    if not np.allclose(figures["residuals"], residuals, rtol=0.0, atol=1e-9 * scale):
        wrong.append("reported residuals differ from the recomputed ones")
    return IKCheck(not wrong, "; ".join(wrong), residual, limits)
