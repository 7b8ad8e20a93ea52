"""Initial guesses for trajectory solves: the straight line, and guess plumbing.

:func:`straight_line_guess` interpolates the joint positions linearly from the
start to the goal at constant velocity, with inverse-dynamics torques; the
random feasible splines of the study are :mod:`youbot_opt.trajopt.spline_guess`.
:func:`resolve_guess` turns what a caller passed as ``guess`` (nothing, a
:class:`~youbot_opt.trajopt.trajectory.Trajectory`, or a previous result) into a
trajectory the transcription can sample.

>>> guess = straight_line_guess(problem, duration=4.9)  # doctest: +SKIP
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError
from youbot_opt.trajopt.problem import BoundaryState, TrajOptProblem
from youbot_opt.trajopt.trajectory import Trajectory

if TYPE_CHECKING:
    from youbot_opt.trajopt.result import TrajOptResult

__all__ = ["DEFAULT_GUESS_DURATION", "straight_line_guess", "resolve_guess", "inverse_dynamics"]

DEFAULT_GUESS_DURATION = 4.9  # [s]
"""Duration of the default guess: the study's 49 steps of ``dt0 = 0.1`` s.

Kept fixed when the number of knots changes, so guesses at every resolution
describe the same motion.
"""


def inverse_dynamics(problem: TrajOptProblem, q: Array, v: Array, a: Array) -> Array:
    """Joint torques in [N m] of knot-major states, ``RNEA(q, v, a) + b * v``.

    Parameters
    ----------
    problem : TrajOptProblem
        Supplies the robot and whether its damping ``b`` [N m s/rad] applies.
    q, v, a : ndarray, shape (N, nv)
        Positions [rad], velocities [rad/s], accelerations [rad/s^2].

    Returns
    -------
    ndarray, shape (N, nv)
        Torques in [N m].
    """
    model = problem.robot.model
    data = model.createData()
    damping = np.asarray(problem.robot.damping, dtype=float) if problem.damping else 0.0
    return np.array(
        [
            pin.rnea(model, data, qk, vk, ak) + damping * vk
            for qk, vk, ak in zip(q, v, a, strict=True)
        ]
    )


def straight_line_guess(
    problem: TrajOptProblem,
    *,
    duration: float | None = None,
    start: BoundaryState | None = None,
    goal: BoundaryState | None = None,
) -> Trajectory:
    """Constant-velocity straight line in joint space from start to goal.

    The torques are those of inverse dynamics (Pinocchio's RNEA plus the joint
    damping) along the line.

    Parameters
    ----------
    problem : TrajOptProblem
        The problem (knots, robot, boundary states).
    duration : float, optional
        Guess duration in [s]; defaults to the problem's fixed duration, else
        :data:`DEFAULT_GUESS_DURATION`.
    start, goal : BoundaryState, optional
        Override the problem's boundary states.

    Returns
    -------
    Trajectory
        Trapezoidal trajectory on ``n_knots`` uniform knots, zero acceleration,
        inverse-dynamics torques. Its boundary velocities are the line's
        velocity, not the boundary states' (the NLP imposes those).

    Raises
    ------
    ParameterError
        If ``duration`` is not finite and > 0.
    """
    start = start or problem.start
    goal = goal or problem.goal
    total = duration if duration is not None else (problem.duration or DEFAULT_GUESS_DURATION)
    if not np.isfinite(total) or total <= 0.0:
        raise ParameterError(f"guess duration must be > 0 [s], got {total!r}", name="duration")
    n = problem.n_knots
    t = np.linspace(0.0, total, n)
    q = start.q + np.outer(t / total, goal.q - start.q)
    v = np.tile((goal.q - start.q) / total, (n, 1))
    a = np.zeros_like(q)
    return Trajectory(t=t, q=q, v=v, a=a, tau=inverse_dynamics(problem, q, v, a))


def resolve_guess(
    problem: TrajOptProblem,
    guess: Trajectory | TrajOptResult | None,
    *,
    start: BoundaryState | None = None,
    goal: BoundaryState | None = None,
) -> Trajectory:
    """Return the trajectory a solve starts from.

    Parameters
    ----------
    problem : TrajOptProblem
        The problem being solved.
    guess : None, Trajectory, or an object with a ``trajectory`` attribute
        ``None`` gives :func:`straight_line_guess`; a previous
        :class:`~youbot_opt.trajopt.result.TrajOptResult` warm-starts from its solution.
    start, goal : BoundaryState, optional
        Boundary states of this solve (for the straight line).

    Returns
    -------
    Trajectory
        A trajectory with ``nv`` columns (resampled to the problem's knots by
        the transcription).

    Raises
    ------
    ParameterError
        If the guess is of the wrong type or has the wrong number of joints.
    """
    if guess is None:
        return straight_line_guess(problem, start=start, goal=goal)
    traj = guess if isinstance(guess, Trajectory) else getattr(guess, "trajectory", None)
    if not isinstance(traj, Trajectory):
        raise ParameterError(
            "guess must be None, a Trajectory or a result with a trajectory, "
            f"got {type(guess).__name__}",
            name="guess",
        )
    if traj.q.shape[1] != problem.nv or traj.v.shape[1] != problem.nv:
        raise ParameterError(
            f"guess has {traj.q.shape[1]} joints, the robot has {problem.nv}",
            name="guess",
            value=traj.q.shape,
        )
    return traj
