"""Clearance of a trajectory problem and of a plan, with coal's exact geometry (#28 items 4-5).

:func:`check_boundary_clearance` refuses a problem whose start or goal is
closer than the margin to an obstacle or to the robot itself, before any
solve, naming the link and the obstacle. :func:`certify_plan_clearance`
certifies a planned motion between its knots with
:func:`youbot_opt.collision.certify_clearance` (the point-speed bound of
``docs/scene.md``, from the plan's joint speeds).

>>> check_boundary_clearance(problem, checker, margin=0.01)  # doctest: +SKIP
"""

from __future__ import annotations

import numpy as np

from youbot_opt.collision.clearance import (
    ClearanceCertificate,
    certify_clearance,
    require_clearance,
)
from youbot_opt.collision.exact import ExactChecker
from youbot_opt.robot.model import RobotModel
from youbot_opt.trajopt.problem import TrajOptProblem
from youbot_opt.trajopt.trajectory import Trajectory

__all__ = ["check_boundary_clearance", "certify_plan_clearance"]


def check_boundary_clearance(
    problem: TrajOptProblem, checker: ExactChecker, *, margin: float = 0.0
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

    Raises
    ------
    ParameterError
        ``start: link geometry 'forearm_link_0' penetrates obstacle 'pillar'
        (distance -0.02 m, margin 0.01 m; ...)``: the closest offending pair;
        the error's ``name`` is ``"start"`` or ``"goal"``.
    """
    require_clearance(checker, problem.robot, problem.start.q, margin=margin, what="start")
    require_clearance(checker, problem.robot, problem.goal.q, margin=margin, what="goal")


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
