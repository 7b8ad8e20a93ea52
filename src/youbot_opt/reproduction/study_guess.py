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
from youbot_opt.exceptions import ParameterError
from youbot_opt.trajopt.problem import TrajOptProblem
from youbot_opt.trajopt.spline_guess import (
    DEFAULT_DT,
    DEFAULT_ORDERS,
    bernstein_derivative_matrix,
    spline_constraints,
)
from youbot_opt.trajopt.trajectory import Trajectory

__all__ = ["vertex_spline_guess"]


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
            lp = spline_constraints(
                p, s, duration, (q0[j], v0[j], q1[j], v1[j]),
                (bounds.q_lower[j], bounds.q_upper[j], bounds.v_upper[j]),
            )  # fmt: skip
            # A vertex of the feasible set: the minimiser of a random linear cost.
            res = linprog(
                rng.normal(size=p + 1), A_ub=lp.a_ub, b_ub=lp.b_ub, A_eq=lp.a_eq, b_eq=lp.b_eq,
                bounds=[(None, None)] * (p + 1), method="highs",
            )  # fmt: skip
            if res.status == 0:
                points = np.asarray(res.x, dtype=float)
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
            out[:, j] = bernstein_derivative_matrix(p, duration, row, s) @ points
    data = robot.model.createData()
    tau = np.array([pin.rnea(robot.model, data, q[k], v[k], a[k]) for k in range(n)])
    t = np.arange(n, dtype=float) * float(dt)
    return Trajectory(t=t, q=q, v=v, a=a, tau=tau, interpolation="trapezoidal")
