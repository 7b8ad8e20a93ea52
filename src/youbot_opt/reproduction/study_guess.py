"""The study's random starts read literally: LP vertices of a random objective.

Spec ``trajopt.md``, "How the study solved it": :func:`vertex_spline_guess`
solves, per joint, the LP of :mod:`youbot_opt.trajopt.spline_guess` with a
random cost vector, so each start is a vertex of the feasible polytope; from
these starts the study's second optimum (f = 11.070) reappears
(``docs/trajopt_reproduction.md``). The LP is written out in docs/design.md,
"Module notes".

>>> guess = vertex_spline_guess(problem, seed=0)  # doctest: +SKIP
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from scipy.optimize import linprog

from youbot_opt._checks import check_positive
from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError
from youbot_opt.trajopt.problem import TrajOptProblem
from youbot_opt.trajopt.spline_guess import DEFAULT_DT, DEFAULT_ORDERS, bernstein_matrix
from youbot_opt.trajopt.trajectory import Trajectory

__all__ = ["vertex_spline_guess"]

_MARGIN = 1e-7
"""Relative margin kept from the limits (HiGHS meets constraints to 1e-7 absolute)."""


def _derivative_matrix(degree: int, duration: float, order: int, s: Array) -> Array:
    """Matrix mapping control points to the ``order``-th time derivative at ``s``."""
    diff = np.eye(degree + 1)
    for k in range(order):
        d = degree - k
        step = np.zeros((d, d + 1))
        step[np.arange(d), np.arange(d)] = -1.0
        step[np.arange(d), np.arange(1, d + 1)] = 1.0
        diff = d / duration * step @ diff
    return bernstein_matrix(degree - order, s) @ diff


def _vertex(
    degree: int,
    s: Array,
    duration: float,
    boundary: tuple[float, float, float, float],
    limits: tuple[float, float, float],
    cost: Array,
) -> Array | None:
    """Control points minimising ``cost . b`` over the feasible set, or None if none."""
    q0, v0, q1, v1 = boundary
    lo, hi, vmax = limits
    pos = bernstein_matrix(degree, s)[1:-1]
    speed = _derivative_matrix(degree, duration, 1, s)
    q_margin, v_margin = _MARGIN * 0.5 * (hi - lo), _MARGIN * vmax
    a_ub = np.vstack([pos, -pos, speed, -speed])
    b_ub = np.concatenate([
        np.full(len(pos), hi - q_margin), np.full(len(pos), -lo - q_margin),
        np.full(2 * len(speed), vmax - v_margin),
    ])  # fmt: skip
    a_eq = np.zeros((4, degree + 1))
    a_eq[0, 0] = a_eq[1, degree] = 1.0
    a_eq[2, [0, 1]] = np.array([-1.0, 1.0]) * degree / duration
    a_eq[3, [degree - 1, degree]] = np.array([-1.0, 1.0]) * degree / duration
    res = linprog(
        cost, A_ub=a_ub, b_ub=b_ub, A_eq=a_eq, b_eq=[q0, q1, v0, v1],
        bounds=[(None, None)] * (degree + 1), method="highs",
    )  # fmt: skip
    return np.asarray(res.x, dtype=float) if res.status == 0 else None


def vertex_spline_guess(
    problem: TrajOptProblem,
    seed: int | np.random.Generator,
    *,
    dt: float = DEFAULT_DT,
    orders: tuple[int, ...] = DEFAULT_ORDERS,
) -> Trajectory:
    """Draw one of the study's random starts, read as the vertex of a random-cost LP.

    Parameters
    ----------
    problem : TrajOptProblem
        The problem (robot, start and goal states, knots, data-sheet bounds).
    seed : int or numpy.random.Generator
        Randomness; the same int gives the same guess.
    dt : float
        Time step of the guess in [s] (the study: 0.1).
    orders : tuple of int
        Polynomial degrees (>= 4) drawn from per joint (the study: 4, 5, 6).

    Returns
    -------
    Trajectory
        Knots ``t_k = k dt``; q [rad], v [rad/s], a [rad/s^2] of the polynomials
        and ``tau = RNEA(q, v, a)`` [N m].

    Raises
    ------
    ParameterError
        On a bad ``dt`` or ``orders``, or when no degree gives a bounded,
        feasible LP for a joint (too few knots, or a motion too long for the
        speed limit within ``(N - 1) dt``).
    """
    dt = check_positive(dt, "dt", unit="s")
    if not orders or any(not isinstance(p, int) or p < 4 for p in orders):
        raise ParameterError(
            f"orders must be polynomial degrees >= 4, got {orders!r}", name="orders", value=orders
        )
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    robot, n = problem.robot, problem.n_knots
    bounds = problem.bounds(1.0)
    q0, q1 = np.asarray(problem.start.q), np.asarray(problem.goal.q)
    v0, v1 = np.asarray(problem.start.velocity), np.asarray(problem.goal.velocity)
    duration = (n - 1) * float(dt)
    s = np.linspace(0.0, 1.0, n)
    q, v, a = (np.empty((n, q0.size)) for _ in range(3))
    for j in range(q0.size):
        candidates = sorted(set(orders))
        while candidates:
            p = int(rng.choice(candidates))
            points = _vertex(
                p, s, duration, (q0[j], v0[j], q1[j], v1[j]),
                (bounds.q_lower[j], bounds.q_upper[j], bounds.v_upper[j]), rng.normal(size=p + 1),
            )  # fmt: skip
            if points is not None:
                break
            candidates.remove(p)
        else:
            raise ParameterError(
                f"no polynomial of degree {sorted(set(orders))} gives a bounded, feasible LP for "
                f"joint {j} at {n} knots over {duration:.6g} s; raise n_knots or dt",
                name="orders",
                value=orders,
            )
        for row, out in enumerate((q, v, a)):
            out[:, j] = _derivative_matrix(p, duration, row, s) @ points
    data = robot.model.createData()
    tau = np.array([pin.rnea(robot.model, data, q[k], v[k], a[k]) for k in range(n)])
    t = np.arange(n, dtype=float) * float(dt)
    return Trajectory(t=t, q=q, v=v, a=a, tau=tau, interpolation="trapezoidal")
