"""Tool constraints certified between a plan's knots (#30 item 2, ``docs/tool.md``).

:func:`certify_plan_tool` samples each :class:`~youbot_opt.trajopt.tool.ToolConstraint`'s
measure along the plan and bisects until a second-order bound
(:func:`tool_curvature_bounds`: the tool vector's second derivative from the joint
speed, acceleration and jerk bounds and the lever arms) proves the limit on every
subinterval; :class:`ToolCertificate` holds the verdict and the failing samples.

>>> certify_plan_tool(result.trajectory, robot, result.problem.tool)  # doctest: +SKIP
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from youbot_opt._typing import Array
from youbot_opt.robot.model import RobotModel
from youbot_opt.trajopt.tool import KeepAxis, NearLine, ToolConstraint, tool_measures
from youbot_opt.trajopt.trajectory import Trajectory

__all__ = ["ToolCertificate", "certify_plan_tool", "tool_curvature_bounds"]

_MAX_EVALUATIONS = 20_000  # bisection samples per constraint before giving up


def _lever_arms(robot: RobotModel, frame: str) -> tuple[Array, Array]:
    """Per velocity index: the lever arm ``R_j`` [m] to the frame's origin, and revolute flags.

    ``R_j`` bounds the distance from joint ``j``'s axis to the frame's origin:
    the norms of the joint placements after ``j`` on the chain, their
    prismatic travel and the frame's offset from its parent joint; joints off
    the chain get 0. A prismatic joint moves the point at its own speed (``R_j = 1``).
    """
    model = robot.model
    fr = model.frames[robot.frame_id(frame)]
    chain = []
    joint = int(fr.parentJoint)
    while joint > 0:
        chain.append(joint)
        joint = int(model.parents[joint])
    chain.reverse()
    travel = np.maximum(np.abs(model.lowerPositionLimit), np.abs(model.upperPositionLimit))
    prismatic = {j: model.joints[j].shortname().startswith("JointModelP") for j in chain}
    arms = np.zeros(model.nv)
    revolute = np.zeros(model.nv, dtype=bool)
    for i, j in enumerate(chain):
        idx = model.joints[j].idx_v
        if prismatic[j]:
            arms[idx] = 1.0
            continue
        revolute[idx] = True
        radius = float(np.linalg.norm(fr.placement.translation))
        for k in chain[i + 1 :]:
            radius += float(np.linalg.norm(model.jointPlacements[k].translation))
            if prismatic[k]:
                radius += float(travel[model.joints[k].idx_q])
        arms[idx] = radius
    return arms, revolute


def tool_curvature_bounds(
    robot: RobotModel,
    constraints: Sequence[ToolConstraint],
    v_max: Array,
    a_max: Array,
    j_max: Array,
) -> Array:
    """Return a bound on the second time derivative of each constraint's tool vector.

    With lever arms ``R_j`` (:func:`_lever_arms`), ``W = sum_rev v_j``,
    ``Wd = sum_rev a_j``, ``V = sum_j v_j``, ``S = sum_j v_j R_j`` (tool point
    speed), ``A = sum_j a_j R_j``, ``P = A + W S + 2 S V`` (tool point
    acceleration): the tool axis ``R a`` has ``|(R a)''| <= Wd + 2 W^2``
    [1/s^2]; the tool point ``|p''| <= P`` [m/s^2]; the tool point's velocity
    ``u = J v`` has ``|u''| <= sum_j (jerk_j R_j + 2 a_j C1_j + v_j C2_j)``
    [m/s^3] with ``C1_j = W R_j + 2 S`` and ``C2_j = (Wd + W^2) R_j + 4 W S + 2 P``
    (each Jacobian column ``z_j x r_j`` and its derivatives). ``docs/tool.md``.

    Parameters
    ----------
    robot : RobotModel
        The robot in angle coordinates.
    constraints : sequence of ToolConstraint
        The constraints.
    v_max, a_max, j_max : ndarray, shape (nv,)
        Bounds on the joints' speeds, accelerations and jerks along the motion.

    Returns
    -------
    ndarray, shape (len(constraints),)
        ``K``: between two samples ``h`` apart, the vector leaves the straight
        line between its sampled values by at most ``K h^2 / 8``.
    """
    v = np.abs(np.asarray(v_max, dtype=float))
    a = np.abs(np.asarray(a_max, dtype=float))
    jerk = np.abs(np.asarray(j_max, dtype=float))
    out = []
    for c in constraints:
        arms, revolute = _lever_arms(robot, c.tool_frame(robot))
        on_chain = arms > 0
        w, wd = float(np.sum(v[revolute])), float(np.sum(a[revolute]))
        speed_sum = float(np.sum(v[on_chain]))
        s = float(np.sum(v * arms))
        p = float(np.sum(a * arms)) + w * s + 2.0 * s * speed_sum
        if isinstance(c, KeepAxis):
            out.append(wd + 2.0 * w * w)
        elif isinstance(c, NearLine):
            out.append(p)
        else:
            c1 = w * arms + 2.0 * s
            c2 = (wd + w * w) * arms + 4.0 * w * s + 2.0 * p
            out.append(float(np.sum((jerk * arms + 2.0 * a * c1 + v * c2)[on_chain])))
    return np.array(out, dtype=float)


def _between(constraint: ToolConstraint, m0: float, m1: float, deviation: float) -> float:
    """Bound on the measure between two samples whose vector deviates by ``deviation``.

    The measures are convex in the tool vector (a distance to a segment, a
    speed) or, for an axis, the cone of half-angle ``max(m0, m1) < pi/2`` is
    convex: the straight line between the samples keeps ``max(m0, m1)``; the
    deviation adds at most ``deviation`` (an angle ``asin(deviation / |chord|)``
    with ``|chord| >= cos((m0 + m1) / 2)``).
    """
    top = max(m0, m1)
    if not isinstance(constraint, KeepAxis):
        return top + deviation
    half = (m0 + m1) / 2
    if top >= math.pi / 2:
        return math.pi
    return top + math.asin(min(1.0, deviation / math.cos(half)))


@dataclass(frozen=True, slots=True, kw_only=True)
class ToolCertificate:
    """One tool constraint of a motion, certified between samples.

    Attributes
    ----------
    constraint : ToolConstraint
        The constraint.
    certified : bool
        Its measure stays at or below ``limit + tolerance`` at every time.
    tolerance : float
        Allowed excess, in the constraint's unit.
    upper_bound : float
        Certified bound on the largest measure (the sampled largest when not certified).
    worst_time, worst_value : float
        The sample with the largest measure [s] and its value.
    failures : tuple of (float, float)
        Samples above ``limit + tolerance`` (or where the bound could not be
        closed on the finest subinterval): time [s], value.
    n_samples : int
        Evaluations made.
    curvature_bound : float
        ``K`` of :func:`tool_curvature_bounds` used between samples.
    """

    constraint: ToolConstraint
    certified: bool
    tolerance: float
    upper_bound: float
    worst_time: float
    worst_value: float
    failures: tuple[tuple[float, float], ...]
    n_samples: int
    curvature_bound: float

    @property
    def value(self) -> float:
        """The certified bound, else the largest failing value (``inf``: bisection not closed)."""
        if self.certified:
            return self.upper_bound
        return max((v for _, v in self.failures), default=math.inf)

    def describe(self) -> str:
        """One line: ``keep axis: <= 0.3497 rad (limit 0.35 rad), certified``."""
        c = self.constraint
        if self.certified:
            bound = f"{self.upper_bound:.4g} {c.unit}"
            return f"{c.label}: <= {bound} (limit {c.limit:.4g} {c.unit}), certified"
        return (
            f"{c.label} {self.worst_value:.4g} {c.unit} > limit {c.limit:.4g} {c.unit} "
            f"at t = {self.worst_time:.4g} s"
        )


def _certify_one(
    constraint: ToolConstraint,
    measure: Callable[[float], float],
    times: Array,
    curvature: float,
    tolerance: float,
) -> ToolCertificate:
    """Bisect between samples until the second-order bound is within ``limit + tolerance``."""
    need = constraint.limit + tolerance
    failures: list[tuple[float, float]] = []
    worst = (-math.inf, 0.0)
    evaluations = 0
    shortest = 1e-6 * float(times[-1] - times[0])  # [s] a subinterval not split further

    def sample(t: float) -> float:
        nonlocal evaluations, worst
        evaluations += 1
        m = measure(t)
        worst = max(worst, (m, t))
        if m > need:
            failures.append((t, m))
        return m

    values = {float(t): sample(float(t)) for t in times}
    stack = [(float(times[i]), float(times[i + 1])) for i in range(len(times) - 1)][::-1]
    upper = -math.inf
    while stack and evaluations < _MAX_EVALUATIONS:
        t0, t1 = stack.pop()
        m0, m1 = values[t0], values[t1]
        bound = _between(constraint, m0, m1, curvature * (t1 - t0) ** 2 / 8)
        if bound <= need or m0 > need or m1 > need:
            upper = max(upper, bound)
            continue
        if t1 - t0 < shortest:  # not provable at this resolution: a failure where it is
            failures.append(((t0 + t1) / 2, bound))
            continue
        tm = (t0 + t1) / 2
        values[tm] = sample(tm)
        stack += [(tm, t1), (t0, tm)]
    certified = not failures and not stack
    return ToolCertificate(
        constraint=constraint,
        certified=certified,
        tolerance=tolerance,
        upper_bound=upper if certified else worst[0],
        worst_time=worst[1],
        worst_value=worst[0],
        failures=tuple(failures),
        n_samples=evaluations,
        curvature_bound=curvature,
    )


def _plan_bounds(trajectory: Trajectory, robot: RobotModel, per_interval: int) -> tuple[Array, ...]:
    """Joint speed, acceleration and jerk bounds of a plan, from samples inside each interval.

    Speeds: the larger of the velocity limits and 1.1 x the sampled largest;
    accelerations and jerks (finite differences of the accelerations): 1.1 x
    the sampled largest. Samples stay inside the intervals, where the
    transcription's interpolant is one polynomial (its acceleration may jump at a knot).
    """
    t = np.asarray(trajectory.t, dtype=float)
    inner = np.linspace(0.02, 0.98, per_interval)
    grid = t[:-1, None] + np.diff(t)[:, None] * inner[None, :]  # (n_intervals, k)
    flat = grid.ravel()
    speeds = np.abs(np.asarray(trajectory.velocity(flat), dtype=float)).max(axis=0)
    acc = np.asarray(trajectory.acceleration(flat), dtype=float).reshape(*grid.shape, -1)
    jerk = np.diff(acc, axis=1) / np.diff(grid, axis=1)[:, :, None]
    v_max = np.maximum(np.abs(robot.velocity_limit), 1.1 * speeds)
    return v_max, 1.1 * np.abs(acc).max(axis=(0, 1)), 1.1 * np.abs(jerk).max(axis=(0, 1))


def certify_plan_tool(
    trajectory: Trajectory,
    robot: RobotModel,
    constraints: Sequence[ToolConstraint],
    *,
    relative_tolerance: float = 1e-3,
    samples_per_interval: int = 4,
) -> tuple[ToolCertificate, ...]:
    """Certify each tool constraint of a plan at every time, not only at its knots.

    Joint speed, acceleration and jerk bounds come from the plan
    (:func:`_plan_bounds`); :func:`tool_curvature_bounds` turns them into a
    bound ``K`` on the tool vector's second derivative, and samples are
    bisected until ``max(m0, m1) + K h^2 / 8`` (for an axis its angle) proves
    the limit (``docs/tool.md``).

    Parameters
    ----------
    trajectory : Trajectory
        The plan (``trajectory(t)``, ``.velocity(t)``, ``.acceleration(t)``).
    robot : RobotModel
        The robot in angle coordinates.
    constraints : sequence of ToolConstraint
        The constraints.
    relative_tolerance : float
        Allowed excess as a fraction of each limit.
    samples_per_interval : int
        Samples per knot interval to start from (>= 1).

    Returns
    -------
    tuple of ToolCertificate
        One per constraint.
    """
    t = np.asarray(trajectory.t, dtype=float)
    k = max(int(samples_per_interval), 1)
    times = np.concatenate(
        [np.linspace(t[i], t[i + 1], k + 1)[:-1] for i in range(len(t) - 1)] + [t[-1:]]
    )
    v_max, a_max, j_max = _plan_bounds(trajectory, robot, 4 * k + 1)
    curvature = tool_curvature_bounds(robot, constraints, v_max, a_max, j_max)
    out = []
    for i, c in enumerate(constraints):

        def measure(time: float, c: ToolConstraint = c) -> float:
            q = np.asarray(trajectory(time), dtype=float)
            v = np.asarray(trajectory.velocity(time), dtype=float)
            return float(tool_measures(robot, (c,), q, v)[0, 0])

        out.append(
            _certify_one(c, measure, times, float(curvature[i]), relative_tolerance * c.limit)
        )
    return tuple(out)
