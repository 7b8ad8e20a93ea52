"""Certificates: check a planned trajectory by a path independent of its transcription.

:func:`certify` checks a solve result (or a bare trajectory and a robot) against
Pinocchio's numeric ABA integrated by SciPy (:mod:`youbot_opt.trajopt.simulate`),
never against the collocation equations that produced it (spec ``trajopt.md``):
local errors of one interval from every knot, PD tracking of the whole plan, the
open-loop drift (reported, never tested) and the bounds at and between knots
(:func:`check_bounds`). The :class:`Certificate` holds the figures; its
:class:`Tolerances` the pass/fail thresholds that :attr:`Certificate.ok` applies.

>>> certify(result).ok  # doctest: +SKIP
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from youbot_opt._checks import check_int, check_time_limit
from youbot_opt._typing import Array, JSONDict
from youbot_opt.dynamics.coordinates import angle_robot
from youbot_opt.dynamics.numeric import RobotLike
from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.model import (
    REVOLUTE_UNITS,
    JointBounds,
    JointUnits,
    RobotModel,
    as_robot_model,
)
from youbot_opt.sweeps.forked import ForkedCall, can_fork
from youbot_opt.trajopt.result import TrajOptResult
from youbot_opt.trajopt.simulate import (
    DEFAULT_ATOL,
    DEFAULT_RTOL,
    PDGains,
    integrate_intervals,
    sample_times,
    simulate_batch,
)
from youbot_opt.trajopt.tool_certificate import ToolCertificate, certify_plan_tool
from youbot_opt.trajopt.trajectory import Trajectory

__all__ = [
    "BoundCheck",
    "Certificate",
    "Tolerances",
    "certify",
    "check_bounds",
    "integrate_intervals",
]

_BOUND_UNIT: dict[str, Callable[[JointUnits], str]] = {
    "position": lambda u: u.position,
    "velocity": lambda u: u.velocity,
    "torque": lambda u: u.effort,
}


_WHERE = {"knots": "at knots", "between": "between knots"}


@dataclass(frozen=True, slots=True, kw_only=True)
class Tolerances:
    """Pass/fail thresholds of a :class:`Certificate`.

    The defaults describe a plan the arm can follow to a few degrees without
    leaning on its feedback: every figure is an error the plan would leave for a
    controller to absorb.

    Attributes
    ----------
    local_position : float
        Largest one-interval position error in [rad] (0.05 rad, about 3 deg).
    local_velocity : float
        Largest one-interval velocity error in [rad/s] (0.5 rad/s, a third of
        the youBot's speed limit).
    feedback_rms : float
        Largest RMS feedback-to-planned torque ratio of any joint (5 %).
    feedback_peak : float
        Largest peak feedback-to-planned torque ratio of any joint (10 %).
    tracking_position : float
        Largest tracking position error in [rad] (0.05 rad).
    knot_bound : float
        Largest bound excess at the knots, relative to the bound's half range
        (``(upper - lower) / 2``; the bound itself for speed and torque). The
        default 1e-6 leaves room for the NLP solver's feasibility tolerance only.
    between_bound : float
        Largest bound excess between the knots, relative as above (1 %): the
        interpolants are O(h^2) approximations between knots and may overshoot
        a bound that is active at a knot.
    """

    local_position: float = 0.05  # [rad]
    local_velocity: float = 0.5  # [rad/s]
    feedback_rms: float = 0.05
    feedback_peak: float = 0.10
    tracking_position: float = 0.05  # [rad]
    knot_bound: float = 1e-6
    between_bound: float = 1e-2

    def __post_init__(self) -> None:
        for name in self.__dataclass_fields__:
            value = getattr(self, name)
            if not (isinstance(value, int | float) and value >= 0.0 and not math.isnan(value)):
                raise ParameterError(
                    f"tolerance {name} must be a number >= 0, got {value!r}", name=name, value=value
                )


class BoundCheck(NamedTuple):
    """Worst bound excess of one quantity, at the knots or between them.

    Attributes
    ----------
    quantity : str
        ``"position"``, ``"velocity"`` or ``"torque"``.
    where : str
        ``"knots"`` or ``"between"`` (interpolant samples strictly inside intervals).
    excess : float
        Largest ``value - upper`` or ``lower - value`` in [rad], [rad/s] or [N m];
        negative when the bound holds (then minus the smallest margin).
    relative : float
        ``excess`` divided by the bound's half range (dimensionless).
    time : float
        Time in [s] of the worst sample.
    joint : int
        Joint index (0-based) of the worst sample.
    """

    quantity: str
    where: str
    excess: float
    relative: float
    time: float
    joint: int


@dataclass(frozen=True, slots=True, kw_only=True)
class Certificate:
    """Figures of an independent forward-simulation check of a plan.

    Attributes
    ----------
    robot : str
        Robot name.
    n_knots : int
        Number of knots N.
    duration : float
        Plan duration in [s].
    interpolation : str
        The plan's interpolant (``"trapezoidal"`` or ``"hermite_simpson"``).
    local_position_error : ndarray, shape (N - 1,)
        Per interval, ``max_i |q_sim_i(t[k+1]) - q[k+1]_i|`` after restarting at
        knot k, in [rad].
    local_velocity_error : ndarray, shape (N - 1,)
        The same for velocities, in [rad/s].
    feedback_rms_ratio : ndarray, shape (nv,)
        Per joint, ``sqrt(int fb^2 dt / int tau_plan^2 dt)`` over the tracking
        simulation (dimensionless).
    feedback_peak_ratio : ndarray, shape (nv,)
        Per joint, ``max_t |fb| / max_t |tau_plan|`` (dimensionless).
    tracking_position_error : float
        Largest ``|q_sim - q_plan(t)|`` of the tracking simulation in [rad].
    tracking_velocity_error : float
        Largest ``|v_sim - v_plan(t)|`` of the tracking simulation in [rad/s].
    open_loop_final_error : float
        ``max_i |q_sim_i(T) - q[-1]_i|`` of the open-loop simulation in [rad];
        ``inf`` if it drifted by ``open_loop_stop`` before the end.
    open_loop_divergence_time : float
        Time in [s] (from the start) at which the open-loop simulation drifted by
        ``open_loop_stop``; ``inf`` if it never did.
    open_loop_stop : float
        Drift in [rad] at which the open-loop simulation is stopped.
    bounds : tuple of BoundCheck
        Worst bound excesses (see :func:`check_bounds`).
    gains : PDGains
        The tracking controller's gains.
    elapsed : float
        Wall time of :func:`certify` in [s].
    tolerances : Tolerances
        Thresholds used by :attr:`ok` (and by :meth:`passed` when given none).
    incomplete : str
        Why some figures were not measured (``certify``'s time limit ran out;
        they are NaN), or ``""``. An incomplete certificate never passes.
    joint_units : tuple of JointUnits
        Units of each joint coordinate (:meth:`RobotModel.joint_units`), for
        the report; empty: every joint revolute.
    tool : tuple of ToolCertificate
        The problem's tool constraints certified between samples of the plan
        (:func:`youbot_opt.trajopt.tool.certify_plan_tool`); empty without any.
    """

    robot: str
    n_knots: int
    duration: float
    interpolation: str
    local_position_error: Array
    local_velocity_error: Array
    feedback_rms_ratio: Array
    feedback_peak_ratio: Array
    tracking_position_error: float
    tracking_velocity_error: float
    open_loop_final_error: float
    open_loop_divergence_time: float
    open_loop_stop: float
    bounds: tuple[BoundCheck, ...]
    gains: PDGains
    elapsed: float
    tolerances: Tolerances = field(default_factory=Tolerances)
    incomplete: str = ""
    joint_units: tuple[JointUnits, ...] = ()
    tool: tuple[ToolCertificate, ...] = ()

    # ------------------------------------------------------------ aggregates
    @property
    def local_position_max(self) -> float:
        """Largest one-interval position error in [rad]."""
        return float(np.max(self.local_position_error))

    @property
    def local_position_median(self) -> float:
        """Median one-interval position error in [rad]."""
        return float(np.median(self.local_position_error))

    @property
    def local_velocity_max(self) -> float:
        """Largest one-interval velocity error in [rad/s]."""
        return float(np.max(self.local_velocity_error))

    @property
    def local_velocity_median(self) -> float:
        """Median one-interval velocity error in [rad/s]."""
        return float(np.median(self.local_velocity_error))

    @property
    def worst_interval(self) -> int:
        """Index of the interval with the largest local position error."""
        return int(np.argmax(self.local_position_error))

    @property
    def feedback_rms(self) -> float:
        """Worst joint's RMS feedback-to-planned torque ratio."""
        return float(np.max(self.feedback_rms_ratio))

    @property
    def feedback_peak(self) -> float:
        """Worst joint's peak feedback-to-planned torque ratio."""
        return float(np.max(self.feedback_peak_ratio))

    def worst_bound(self, where: str) -> BoundCheck:
        """Return the check with the largest relative excess at ``"knots"`` or ``"between"``."""
        checks = [c for c in self.bounds if c.where == where]
        if not checks:
            raise ParameterError(
                f"where must be 'knots' or 'between', got {where!r}", name="where", value=where
            )
        return max(checks, key=lambda c: c.relative)

    def _position_units(self) -> tuple[str, str]:
        """Units of the figures that are maxima over all joints: position and velocity."""
        kinds = {u.prismatic for u in self.joint_units} or {False}
        if kinds == {True}:
            return "m", "m/s"
        return ("rad or m", "rad/s or m/s") if True in kinds else ("rad", "rad/s")

    # ------------------------------------------------------------- verdicts
    def _rows(self, tol: Tolerances) -> list[tuple[str, float, float, float, str]]:
        """(label, value, median or NaN, limit, note) of every tested figure."""
        nan = math.nan
        pos, vel = self._position_units()
        rows = [
            (f"local error, position [{pos}]", self.local_position_max,
             self.local_position_median, tol.local_position,
             f"worst interval {self.worst_interval}"),
            (f"local error, velocity [{vel}]", self.local_velocity_max,
             self.local_velocity_median, tol.local_velocity, ""),
            ("tracking: feedback/plan torque, RMS", self.feedback_rms, nan, tol.feedback_rms, ""),
            ("tracking: feedback/plan torque, peak", self.feedback_peak, nan, tol.feedback_peak,
             ""),
            (f"tracking: position error [{pos}]", self.tracking_position_error, nan,
             tol.tracking_position, ""),
        ]  # fmt: skip
        for c in self.bounds:
            limit = tol.knot_bound if c.where == "knots" else tol.between_bound
            units = self.joint_units[c.joint] if 0 <= c.joint < len(self.joint_units) else None
            unit = _BOUND_UNIT[c.quantity](units or REVOLUTE_UNITS)
            label = f"bound {c.quantity}, {_WHERE[c.where]} (relative)"
            side = "excess" if c.excess > 0.0 else "margin"  # how far over, or short of, it
            note = f"{side} {abs(c.excess):.2e} {unit} {'over' if c.excess > 0.0 else 'to'} the "
            note += f"bound at t = {c.time:.4g} s, joint {c.joint}"
            rows.append((label, c.relative, nan, limit, note))
        for t in self.tool:
            kind = t.constraint
            note = "certified between samples" if t.certified else t.describe()
            label = f"tool: {kind.label} [{kind.unit}]"
            rows.append((label, t.value, nan, kind.limit + t.tolerance, note))
        return rows

    def failures(self, tolerances: Tolerances | None = None) -> list[str]:
        """List each figure that exceeds its tolerance (empty if the plan passes).

        Parameters
        ----------
        tolerances : Tolerances, optional
            Thresholds; :attr:`tolerances` when omitted.

        Returns
        -------
        list of str
            One line per failed check. A NaN figure (failed integration) fails.
        """
        tol = self.tolerances if tolerances is None else tolerances
        incomplete = [f"incomplete: {self.incomplete}"] if self.incomplete else []
        return incomplete + [
            f"{label} = {value:.3g} > {limit:.3g}"
            for label, value, _, limit, _ in self._rows(tol)
            if not value <= limit
        ]

    def passed(self, tolerances: Tolerances | None = None) -> bool:
        """Return True if every figure is within ``tolerances`` (:attr:`tolerances` by default).

        The open-loop figures are reported, never tested.
        """
        return not self.failures(tolerances)

    @property
    def ok(self) -> bool:
        """:meth:`passed` with :attr:`tolerances`."""
        return self.passed()

    # -------------------------------------------------------------- reports
    def summary(self) -> JSONDict:
        """JSON-ready figures (non-finite numbers become ``None``)."""

        def num(x: float) -> float | None:
            return float(x) if math.isfinite(x) else None

        out: JSONDict = {
            "robot": self.robot,
            "n_knots": self.n_knots,
            "duration_s": num(self.duration),
            "interpolation": self.interpolation,
            "ok": self.ok,
            "worst_interval": self.worst_interval,
            "tracking_bandwidth_rad_s": self.gains.bandwidth,
            "open_loop_stop_rad": self.open_loop_stop,
            "elapsed_s": self.elapsed,
            "incomplete": self.incomplete,
        }
        for key, value in (
            ("local_position_max_rad", self.local_position_max),
            ("local_position_median_rad", self.local_position_median),
            ("local_velocity_max_rad_s", self.local_velocity_max),
            ("local_velocity_median_rad_s", self.local_velocity_median),
            ("feedback_rms_ratio", self.feedback_rms),
            ("feedback_peak_ratio", self.feedback_peak),
            ("tracking_position_error_rad", self.tracking_position_error),
            ("tracking_velocity_error_rad_s", self.tracking_velocity_error),
            ("open_loop_final_error_rad", self.open_loop_final_error),
            ("open_loop_divergence_time_s", self.open_loop_divergence_time),
        ):
            out[key] = num(value)
        for c in self.bounds:
            key = f"bound_{c.quantity}_{c.where}"
            out.update({f"{key}_excess": num(c.excess), f"{key}_relative": num(c.relative)})
            out.update({f"{key}_time_s": num(c.time), f"{key}_joint": c.joint})
        if self.tool:
            out["tool"] = [
                {"label": t.constraint.label, "certified": t.certified, "value": num(t.value),
                 "limit": t.constraint.limit, "unit": t.constraint.unit}
                for t in self.tool
            ]  # fmt: skip
        return out

    def __str__(self) -> str:
        verdict = "PASSED" if self.ok else "FAILED"
        if self.incomplete:
            verdict = f"INCOMPLETE, {self.incomplete}"
        lines = [
            f"Certificate: {self.robot}, {self.n_knots} knots, {self.interpolation}, "
            f"T = {self.duration:.4g} s: {verdict}",
            f"  {'check':<40}{'max':>10}{'median':>10}{'tol':>9}",
        ]
        for label, value, median, limit, note in self._rows(self.tolerances):
            med = f"{median:>10.2e}" if math.isfinite(median) else " " * 10
            mark = "ok  " if value <= limit else "FAIL"
            lines.append(f"  {label:<40}{value:>10.2e}{med}{limit:>9.1e}  {mark}  {note}".rstrip())
        pos = self._position_units()[0]
        if math.isfinite(self.open_loop_divergence_time):
            drift = (
                f"drifted {self.open_loop_stop:g} {pos} from the plan at "
                f"t = {self.open_loop_divergence_time:.3g} s"
            )
        else:
            drift = f"final position error {self.open_loop_final_error:.2e} {pos}"
        lines.append(f"  open loop (reported, not tested): {drift}")
        lines.append(
            f"  (PD tracking at {self.gains.bandwidth:g} rad/s, damping ratio "
            f"{self.gains.damping_ratio:g}; certified in {self.elapsed:.3f} s)"
        )
        return "\n".join(lines)


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
    processes: int = 1,
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
    processes : int, optional
        Processes the simulations may use (>= 1). With 2 or more (and
        ``fork``, Linux), the one-interval integrations run in a forked
        process while this one runs the tracking and open-loop simulations:
        the same figures, about a third less wall time on a long certificate
        (the xArm7's stiff 106-knot plan: 1.10 -> 0.72 s), and a few
        milliseconds either way on a short one. 1 (default): one after the
        other, here (what a worker of a sweep, whose cores are taken, wants).

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
    processes = check_int(processes, "processes", minimum=1)
    local = functools.partial(
        integrate_intervals, trajectory, model, damping=use_damping, rtol=rtol, atol=atol,
        deadline=deadline,
    )  # fmt: skip
    tracking = functools.partial(
        simulate_batch, trajectory, model, damping=use_damping, gains=(gains, None),
        stop_deviation=(None, open_loop_stop), samples_per_interval=samples_per_interval,
        rtol=TRACKING_RTOL, atol=TRACKING_ATOL,
    )  # fmt: skip
    if processes > 1 and can_fork():  # the one-interval integrations beside the others
        with ForkedCall(local) as forked:
            sim, open_loop = tracking(deadline=deadline)
            q_end, v_end = forked.result()
        stage = "the one-interval integrations and the tracking and open-loop simulations"
        incomplete = _out_of_time(deadline, limit, stage)
    else:
        q_end, v_end = local()
        incomplete = _out_of_time(deadline, limit, "the one-interval integrations")
        sim, open_loop = tracking(deadline=deadline if not incomplete else tic)
        stage = "the tracking and open-loop simulations"
        incomplete = incomplete or _out_of_time(deadline, limit, stage)
    local_q = np.max(np.abs(q_end - trajectory.q[1:]), axis=1)
    local_v = np.max(np.abs(v_end - trajectory.v[1:]), axis=1)
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
    if incomplete:
        ol_final = ol_time = math.nan
    elif open_loop.stop_time is None:
        ol_final = float(np.max(np.abs(open_loop.q[-1] - trajectory.q[-1])))
        ol_time = math.inf
    else:
        ol_final, ol_time = math.inf, open_loop.stop_time - float(trajectory.t[0])

    checks = check_bounds(trajectory, bounds, samples_per_interval=samples_per_interval)
    tool: tuple[ToolCertificate, ...] = ()
    if isinstance(plan, TrajOptResult) and plan.problem.tool:
        tool = certify_plan_tool(trajectory, plan.problem.robot, plan.problem.tool)
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
        joint_units=model.joint_units(),
        tool=tool,
    )


def _out_of_time(deadline: float | None, limit: float | None, stage: str) -> str:
    """Return the ``incomplete`` note if ``deadline`` has passed during ``stage``, else ""."""
    if deadline is None or time.perf_counter() <= deadline:
        return ""
    return f"time limit {limit:.3g} s reached during {stage}"
