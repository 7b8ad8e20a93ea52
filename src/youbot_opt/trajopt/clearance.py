"""Clearance of a trajectory problem and of a plan, with coal's exact geometry (#28 items 4-5).

:func:`clearance_constraint`: a problem's :class:`~youbot_opt.collision.clearance.Clearance`
as the NLP's path constraint (conservative ball distances >= the margin).
:func:`check_boundary_clearance` refuses a start or goal closer than the margin
to an obstacle or the robot itself, before any solve, naming link and obstacle.
:func:`certify_plan_clearance` certifies a plan between its knots with
:func:`youbot_opt.collision.certify_clearance` (point-speed bound, ``docs/scene.md``).

>>> check_boundary_clearance(problem, checker, margin=0.01)  # doctest: +SKIP
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from youbot_opt._typing import Array
from youbot_opt.collision.clearance import (
    ClearanceCertificate,
    certify_clearance,
    clearance_checker,
    collision_model,
    require_clearance,
)
from youbot_opt.collision.exact import ExactChecker
from youbot_opt.dynamics.symbolic import build_symbolic_model
from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.model import RobotModel
from youbot_opt.trajopt.problem import TrajOptProblem
from youbot_opt.trajopt.trajectory import Trajectory
from youbot_opt.trajopt.transcription.path import PathConstraint

__all__ = [
    "check_boundary_clearance",
    "certify_plan_clearance",
    "clearance_constraint",
    "knot_clearance",
    "require_model_clearance",
]


def require_model_clearance(
    problem: TrajOptProblem,
    constraint: PathConstraint,
    *,
    checker: ExactChecker | None = None,
    start: Array | None = None,
    goal: Array | None = None,
) -> None:
    """Refuse a start or goal whose bounding-ball distance is below the margin (no end window).

    Without an end window (``Clearance(end_window=0)``) the NLP holds the
    conservative ball distances (never above coal's) at every knot, the first
    and last included, and those are fixed: a pair whose balls overshoot its
    geometry by more than its coal clearance minus the margin makes the NLP
    infeasible from the start, whatever coal says. With an end window
    (``constraint.end_window`` > 0, the default) such a pair's rows ramp up from
    the end's own ball distance (:class:`~youbot_opt.trajopt.transcription.path.PathRamp`)
    and nothing is refused here.

    Parameters
    ----------
    problem : TrajOptProblem
        The problem (its clearance made ``constraint``).
    constraint : PathConstraint
        The problem's clearance rows (:func:`clearance_constraint`).
    checker : ExactChecker, optional
        Coal's solids for the message's exact distance (built when not given).
    start, goal : ndarray, shape (nq,), optional
        Configurations [rad] ([m] for prismatic joints) that replace the
        problem's (a solve's overridden boundary states).

    Raises
    ------
    ParameterError
        Naming the state, the pair, the ball and coal distances and the margin
        (and the ways out: a smaller margin, ``self_collision=False`` or the
        pair disabled).
    """
    assert problem.clearance is not None
    if constraint.end_window > 0:
        return
    ends = (
        ("start", problem.start.q if start is None else start),
        ("goal", problem.goal.q if goal is None else goal),
    )
    for what, q in ends:
        zero = np.zeros(problem.nv)
        model = np.asarray(constraint.function(q, zero), dtype=float).ravel()
        bad = np.flatnonzero(model < constraint.lower)
        if bad.size == 0:
            continue
        i = int(bad[np.argmin(model[bad] - constraint.lower[bad])])
        if checker is None:
            checker = clearance_checker(problem.robot, problem.clearance)
        exact = checker.distances(problem.robot, q)
        raise ParameterError(
            f"{what}: the bounding balls of pair {constraint.labels[i]!r} are "
            f"{model[i]:.4g} m apart (coal: {float(exact[i]):.4g} m), below the margin "
            f"{problem.clearance.margin:g} m the NLP holds at every knot with end_window=0: the "
            "balls overshoot the geometry; use an end window (Clearance(end_window=0.1)), a "
            "smaller margin, disable the pair, or leave self-collision out",
            name=what,
            value=float(model[i]),
        )


def knot_clearance(problem: TrajOptProblem, q: Array) -> tuple[float, tuple[str, str], int] | None:
    """Return coal's smallest clearance [m] over the knots, its pair and its knot.

    Parameters
    ----------
    problem : TrajOptProblem
        A problem with a clearance (None is returned without one, or without pairs).
    q : ndarray, shape (n, nv)
        Knot configurations in [rad] ([m] for prismatic joints).

    Returns
    -------
    tuple of (float, (str, str), int) or None
        Distance in [m], the pair's names and the knot index.
    """
    spec = problem.clearance
    if spec is None:
        return None
    checker = clearance_checker(problem.robot, spec)
    names = checker.model.pair_names
    if not names:
        return None
    d = np.array([checker.distances(problem.robot, qk) for qk in np.asarray(q, dtype=float)])
    k, i = np.unravel_index(int(np.argmin(d)), d.shape)
    return float(d[k, i]), names[int(i)], int(k)


def clearance_constraint(problem: TrajOptProblem) -> PathConstraint | None:
    """Return the NLP's clearance path constraint of ``problem`` (None without a clearance).

    Rows: every checked pair's conservative distance [m] (never above coal's
    exact one), held at or above ``problem.clearance.margin``; the exact
    clearance is then at least the margin at every point the transcription
    constrains (knots and interior points) -- but within the clearance's
    ``end_window`` of a fixed end where the pair's balls lack the margin there,
    whose rows ramp up from the end's ball distance (coal's certificate judges
    the plan there as everywhere).

    Parameters
    ----------
    problem : TrajOptProblem
        The problem; its robot in angle coordinates is the kinematics'.

    Returns
    -------
    PathConstraint or None
        ``"clearance"``: ``(q, v) -> d (n_pairs,)`` [m] with lower bound the
        margin; None when the problem has no clearance or no pair to check.
    """
    spec = problem.clearance
    if spec is None:
        return None
    model = collision_model(problem.robot, spec)
    if model.n_pairs == 0:
        return None
    distances = model.configuration_function(build_symbolic_model(problem.robot).forward_kinematics)
    q = ca.SX.sym("q", problem.nv)
    v = ca.SX.sym("v", problem.nv)
    function = ca.Function("clearance", [q, v], [distances(q)], ["q", "v"], ["distance"])
    return PathConstraint(
        name="clearance",
        function=function,
        lower=np.full(model.n_pairs, spec.margin),
        upper=np.full(model.n_pairs, np.inf),
        labels=tuple(f"{a} / {b}" for a, b in model.pair_names),
        end_window=spec.end_window,
    )


def check_boundary_clearance(
    problem: TrajOptProblem,
    checker: ExactChecker,
    *,
    margin: float = 0.0,
    start: Array | None = None,
    goal: Array | None = None,
) -> None:
    """Refuse a problem whose start or goal lacks ``margin`` [m] of clearance.

    Parameters
    ----------
    problem : TrajOptProblem
        The problem (its robot is the checker's).
    checker : ExactChecker
        The coal solids of the robot's collision model in the scene.
    margin : float
        Required clearance in [m].
    start, goal : ndarray, shape (nq,), optional
        Configurations [rad] ([m] for prismatic joints) that replace the
        problem's (a solve's overridden boundary states).

    Raises
    ------
    ParameterError
        ``start: link geometry 'forearm_link_0' penetrates obstacle 'pillar'
        (distance -0.02 m, margin 0.01 m; ...)``: the closest offending pair;
        the error's ``name`` is ``"start"`` or ``"goal"``.
    """
    q0 = problem.start.q if start is None else start
    q1 = problem.goal.q if goal is None else goal
    require_clearance(checker, problem.robot, q0, margin=margin, what="start")
    require_clearance(checker, problem.robot, q1, margin=margin, what="goal")


def certify_plan_clearance(
    trajectory: Trajectory,
    robot: RobotModel,
    checker: ExactChecker,
    *,
    margin: float = 0.0,
    tolerance: float = 1e-3,
    samples_per_interval: int = 4,
) -> ClearanceCertificate:
    """Certify a plan's clearance at every time, not only at its knots.

    The plan's joint speeds are bounded by the larger of the robot's velocity
    limits and the largest speed of the plan sampled ``4 x`` more densely
    than ``samples_per_interval``, times 1.1; the certificate bisects between
    samples until the speed bound proves the margin or an exact sample fails.

    Parameters
    ----------
    trajectory : Trajectory
        The plan (callable: ``trajectory(t)`` -> q).
    robot : RobotModel
        The robot.
    checker : ExactChecker
        The coal solids and pairs.
    margin : float
        Required clearance in [m].
    tolerance : float
        Allowed shortfall in [m].
    samples_per_interval : int
        Samples per knot interval to start from (>= 1).

    Returns
    -------
    ClearanceCertificate
        Certified, or the failing samples (time, pair, distance).
    """
    t = np.asarray(trajectory.t, dtype=float)
    k = max(int(samples_per_interval), 1)
    times = np.concatenate(
        [np.linspace(t[i], t[i + 1], k + 1)[:-1] for i in range(len(t) - 1)] + [t[-1:]]
    )
    dense = np.linspace(t[0], t[-1], 4 * k * (len(t) - 1) + 1)
    speeds = np.abs(np.asarray(trajectory.velocity(dense), dtype=float)).max(axis=0)
    v_max = np.maximum(np.abs(robot.velocity_limit), 1.1 * speeds)
    return certify_clearance(
        checker,
        robot,
        lambda time: np.asarray(trajectory(time), dtype=float),
        times,
        v_max=v_max,
        margin=margin,
        tolerance=tolerance,
    )
