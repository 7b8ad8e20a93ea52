"""Certificates: check a planned trajectory by a path independent of its transcription.

:func:`certify` checks a solve result (or a bare trajectory and a robot) against
Pinocchio's numeric ABA integrated by SciPy (:mod:`youbot_opt.trajopt.simulate`),
never against the collocation equations that produced it (spec ``trajopt.md``:
"prove each trajectory by forward simulation"): local errors of one interval
from every knot, PD tracking of the whole plan (feedback torque relative to the
plan's), the open-loop drift (reported, never tested) and the bounds at and
between knots (:func:`check_bounds`). :class:`Tolerances` holds the pass/fail
thresholds that :attr:`Certificate.ok` applies.

>>> certify(result).ok  # doctest: +SKIP
"""

from __future__ import annotations

import math
import time

import numpy as np

from youbot_opt._checks import check_time_limit
from youbot_opt._typing import Array
from youbot_opt.dynamics.coordinates import angle_robot
from youbot_opt.dynamics.numeric import RobotLike
from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.model import JointBounds, RobotModel, as_robot_model
from youbot_opt.trajopt.certificate import BoundCheck, Certificate, Tolerances
from youbot_opt.trajopt.result import TrajOptResult
from youbot_opt.trajopt.simulate import (
    DEFAULT_ATOL,
    DEFAULT_RTOL,
    PDGains,
    integrate_intervals,
    sample_times,
    simulate,
)
from youbot_opt.trajopt.trajectory import Trajectory

__all__ = [
    "BoundCheck",
    "Certificate",
    "Tolerances",
    "certify",
    "check_bounds",
    "integrate_intervals",
]

TRACKING_RTOL = 1e-8
"""Relative tolerance of the tracking and open-loop simulations (their figures
are ratios at the 1e-5 level and above, so tighter tolerances only cost time)."""
TRACKING_ATOL = 1e-10
"""Absolute tolerance of the tracking and open-loop simulations, in [rad] and [rad/s]."""


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
    trajectory: Trajectory, bounds: JointBounds, *, samples_per_interval: int = 20
) -> tuple[BoundCheck, ...]:
    """Worst position, velocity and torque bound excess at and between the knots.

    Parameters
    ----------
    trajectory : Trajectory
        The plan.
    bounds : JointBounds
        Scaled bounds, each of shape (nv,).
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


def _ratio(num: Array, den: Array) -> Array:
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(
            den > 0.0, num / np.where(den > 0.0, den, 1.0), np.where(num > 0, np.inf, 0.0)
        )


def _resolve(
    plan: TrajOptResult | Trajectory,
    robot: RobotLike | None,
    bounds: JointBounds | None,
    bound_scale: float,
    damping: bool | None,
) -> tuple[Trajectory, RobotModel, JointBounds, bool]:
    """Trajectory, robot, bounds and damping flag (the plan's assumption) of a plan."""
    if isinstance(plan, Trajectory):
        if robot is None:
            raise ParameterError(
                "certify(trajectory) needs the robot: certify(trajectory, robot)", name="robot"
            )
        trajectory = plan
        use_damping = True if damping is None else bool(damping)
    elif isinstance(plan, TrajOptResult):
        if plan.trajectory is None:
            raise ParameterError(
                f"cannot certify {type(plan).__name__}: expected a Trajectory or a result with "
                f"a finite trajectory (status {plan.status})",
                name="plan",
            )
        trajectory = plan.trajectory
        if robot is None:
            robot = plan.problem.robot
        use_damping = plan.problem.damping if damping is None else bool(damping)
        if bounds is None:
            bounds = plan.bounds()
    else:
        raise ParameterError(
            f"cannot certify {type(plan).__name__}: expected a Trajectory or a result "
            "(TrajOptResult)",
            name="plan",
        )
    model = angle_robot(as_robot_model(robot))  # continuous joints: one angle each
    if bounds is None:
        bounds = model.bounds(bound_scale)
    return trajectory, model, bounds, use_damping


def certify(
    plan: TrajOptResult | Trajectory,
    robot: RobotLike | None = None,
    *,
    bounds: JointBounds | None = None,
    bound_scale: float = 1.0,
    damping: bool | None = None,
    gains: PDGains | None = None,
    tolerances: Tolerances | None = None,
    samples_per_interval: int = 20,
    open_loop_stop: float = 0.5,
    rtol: float = DEFAULT_RTOL,
    atol: float = DEFAULT_ATOL,
    time_limit: float | None = None,
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
        Scaled bounds; by default the result's, else
        :meth:`RobotModel.bounds(bound_scale) <youbot_opt.robot.model.RobotModel.bounds>`.
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
    time_limit : float, optional
        Wall time in [s] for the simulations (None: no limit). When it runs
        out, the remaining simulations are skipped, their figures are NaN and
        :attr:`Certificate.incomplete` says where it stopped: the certificate
        fails (stiff robots, such as light fingers under 20 rad/s tracking,
        can take minutes).

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
    limit = check_time_limit(time_limit, "time_limit")
    deadline = None if limit is None else tic + limit
    trajectory, model, bounds, use_damping = _resolve(plan, robot, bounds, bound_scale, damping)
    gains = PDGains() if gains is None else gains
    q_end, v_end = integrate_intervals(
        trajectory, model, damping=use_damping, rtol=rtol, atol=atol, deadline=deadline
    )
    local_q = np.max(np.abs(q_end - trajectory.q[1:]), axis=1)
    local_v = np.max(np.abs(v_end - trajectory.v[1:]), axis=1)
    incomplete = _out_of_time(deadline, limit, "the one-interval integrations")

    sim = simulate(
        trajectory, model, damping=use_damping, gains=gains,
        samples_per_interval=samples_per_interval, rtol=TRACKING_RTOL, atol=TRACKING_ATOL,
        deadline=deadline if not incomplete else tic,
    )  # fmt: skip
    incomplete = incomplete or _out_of_time(deadline, limit, "the tracking simulation")
    fb, plan_tau = sim.tau_feedback, sim.tau_plan
    rms = _ratio(
        np.sqrt(np.trapezoid(fb**2, sim.t, axis=0)),
        np.sqrt(np.trapezoid(plan_tau**2, sim.t, axis=0)),
    )
    peak = _ratio(np.max(np.abs(fb), axis=0), np.max(np.abs(plan_tau), axis=0))
    if sim.stop_time is not None:  # integrator failure: figures unknown
        rms = peak = np.full(model.nv, np.nan)
    track_q = float(np.max(np.abs(sim.q - trajectory(sim.t))))
    track_v = float(np.max(np.abs(sim.v - trajectory.velocity(sim.t))))

    open_loop = simulate(
        trajectory, model, damping=use_damping, samples_per_interval=1,
        stop_deviation=open_loop_stop, rtol=TRACKING_RTOL, atol=TRACKING_ATOL,
        deadline=deadline if not incomplete else tic,
    )  # fmt: skip
    incomplete = incomplete or _out_of_time(deadline, limit, "the open-loop simulation")
    if incomplete:
        ol_final = ol_time = math.nan
    elif open_loop.stop_time is None:
        ol_final = float(np.max(np.abs(open_loop.q[-1] - trajectory.q[-1])))
        ol_time = math.inf
    else:
        ol_final, ol_time = math.inf, open_loop.stop_time - float(trajectory.t[0])

    checks = check_bounds(trajectory, bounds, samples_per_interval=samples_per_interval)
    return Certificate(
        robot=model.name,
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
        incomplete=incomplete,
    )


def _out_of_time(deadline: float | None, limit: float | None, stage: str) -> str:
    """Return the ``incomplete`` note if ``deadline`` has passed during ``stage``, else ""."""
    if deadline is None or time.perf_counter() <= deadline:
        return ""
    return f"time limit {limit:.3g} s reached during {stage}"
