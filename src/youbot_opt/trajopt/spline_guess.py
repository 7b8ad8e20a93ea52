"""Random feasible polynomial guesses: the study's initial guesses (spec ``trajopt.md``).

Per joint a polynomial of random degree 4 to 6 (Bernstein basis over
``s = t / T0``) that meets the start and goal states exactly and keeps
position and speed inside the (scaled) limits at every knot: the L1
projection of a random target onto that set, one small linear program per
joint. Torques from inverse dynamics. The reading of the study and the LP are
explained in docs/design.md, "Module notes".

>>> guess = random_spline_guess(robot, start, goal, 50, seed=0)  # doctest: +SKIP
"""

from __future__ import annotations

import logging
import math
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
import pinocchio as pin

from youbot_opt._checks import check_bound_scale, check_int, check_positive
from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.model import as_robot_model
from youbot_opt.trajopt.trajectory import Trajectory

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

    from youbot_opt.robot.model import RobotModel
    from youbot_opt.trajopt.problem import BoundaryState, JointBounds

    BoundaryLike = BoundaryState | tuple[ArrayLike, ArrayLike] | ArrayLike

__all__ = [
    "DEFAULT_DT",
    "DEFAULT_ORDERS",
    "SplineConstraints",
    "bernstein_derivative_matrix",
    "bernstein_matrix",
    "random_spline_guess",
    "spline_constraints",
]

_LOG = logging.getLogger(__name__)

DEFAULT_DT = 0.1  # [s]
"""The study's initial time step ``dt0`` in [s]."""
DEFAULT_ORDERS: tuple[int, ...] = (4, 5, 6)
"""Polynomial degrees drawn from (the study's "order 4 to 6")."""

_MARGIN = 1e-7
"""Relative margin (of the limit's half range) kept from the limits at interior knots,
so that the LP solver's feasibility tolerance (1e-7 absolute in HiGHS) cannot
push a knot outside them."""


def bernstein_matrix(degree: int, s: Array) -> Array:
    """Bernstein basis polynomials of ``degree`` at normalised times ``s``.

    Parameters
    ----------
    degree : int
        Polynomial degree ``p >= 0``.
    s : ndarray, shape (M,)
        Normalised times in [0, 1].

    Returns
    -------
    ndarray, shape (M, p + 1)
        ``B[k, j] = C(p, j) s_k^j (1 - s_k)^(p - j)``.
    """
    s = np.asarray(s, dtype=float)[:, None]
    j = np.arange(degree + 1)[None, :]
    binom = np.array([math.comb(degree, int(i)) for i in range(degree + 1)], dtype=float)
    return binom * s**j * (1.0 - s) ** (degree - j)


def _difference(degree: int) -> Array:
    """Forward-difference matrix D (p x (p + 1)): (D b)_j = b_{j+1} - b_j."""
    return np.eye(degree, degree + 1, k=1) - np.eye(degree, degree + 1)


def _boundary_state(name: str, value: Any, nq: int) -> tuple[Array, Array]:
    """(q, v) from a pair, an object with ``.q``/``.v``, or a bare q vector (v = 0)."""
    if hasattr(value, "q"):
        q, v = value.q, getattr(value, "v", None)
    elif isinstance(value, tuple | list) and len(value) == 2 and np.ndim(value[0]) == 1:
        q, v = value
    else:
        q, v = value, None
    try:
        q = np.array(q, dtype=float)
        v = np.zeros(nq) if v is None else np.array(v, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ParameterError(
            f"{name} must be a (q, v) pair, an object with .q and .v, or a q vector; got {value!r}",
            name=name,
        ) from exc
    for what, arr in (("q", q), ("v", v)):
        if arr.shape != (nq,) or not np.all(np.isfinite(arr)):
            raise ParameterError(
                f"{name}.{what} must be a finite vector of shape ({nq},), got {arr!r}",
                name=f"{name}.{what}",
                value=arr,
            )
    return q, v


def _check_inside(name: str, x: Array, lo: Array, hi: Array, unit: str, where: str) -> None:
    bad = np.flatnonzero((x < lo) | (x > hi))
    if bad.size:
        j = int(bad[0])
        raise ParameterError(
            f"{name}[{j}] = {x[j]:.6g} {unit} is outside the limits [{lo[j]:.6g}, {hi[j]:.6g}] "
            f"{unit} ({where}); no guess can meet it",
            name=name,
            value=float(x[j]),
        )


class SplineConstraints(NamedTuple):
    """Linear constraints on the ``p + 1`` Bernstein control points of one joint's polynomial.

    ``a_ub @ b <= b_ub`` and ``a_eq @ b == b_eq``, as :func:`scipy.optimize.linprog`
    takes them (see :func:`spline_constraints`).
    """

    a_ub: Array
    b_ub: Array
    a_eq: Array
    b_eq: Array


def bernstein_derivative_matrix(degree: int, duration: float, order: int, s: Array) -> Array:
    """Matrix mapping Bernstein control points to the ``order``-th time derivative at ``s``.

    Parameters
    ----------
    degree : int
        Polynomial degree ``p >= order``.
    duration : float
        Duration ``T`` of the polynomial in [s] (``t = s T``).
    order : int
        Derivative order (0: the position itself).
    s : ndarray, shape (M,)
        Normalised times in [0, 1].

    Returns
    -------
    ndarray, shape (M, p + 1)
        ``d^order/dt^order`` of the polynomial at ``s`` is this matrix times the
        control points: ``p!/(p - order)! / T^order * B_{p - order}(s) D^order``
        with ``D`` the forward difference.
    """
    diff = np.eye(degree + 1)
    for k in range(order):
        d = degree - k
        step = np.zeros((d, d + 1))
        step[np.arange(d), np.arange(d)] = -1.0
        step[np.arange(d), np.arange(1, d + 1)] = 1.0
        diff = d / duration * step @ diff
    return bernstein_matrix(degree - order, s) @ diff


def spline_constraints(
    degree: int,
    s: Array,
    duration: float,
    boundary: tuple[float, float, float, float],
    limits: tuple[float, float, float],
) -> SplineConstraints:
    """Constraints of one joint's polynomial: boundary states exactly, limits at the knots.

    Equalities: position and speed at ``s = 0`` and ``s = 1`` (4 rows).
    Inequalities: the position within ``[lo, hi]`` at the interior knots and
    ``|speed| <= vmax`` at every knot, each tightened by a relative margin
    (``1e-7`` of the half range, of ``vmax``) so that the LP solver's
    feasibility tolerance (1e-7 absolute in HiGHS) cannot push a knot outside
    the limits; rows of an infinite limit are left out.

    Parameters
    ----------
    degree : int
        Polynomial degree ``p``.
    s : ndarray, shape (N,)
        Normalised knot times in [0, 1], ``s[0] = 0`` and ``s[-1] = 1``.
    duration : float
        Duration ``T0`` in [s].
    boundary : tuple of float
        ``(q0, v0, q1, v1)``: start and goal position [rad] and speed [rad/s].
    limits : tuple of float
        ``(lo, hi, vmax)``: position limits [rad] and speed limit [rad/s].

    Returns
    -------
    SplineConstraints
        Rows in the order: upper and lower position rows, upper and lower speed rows.
    """
    q0, v0, q1, v1 = boundary
    lo, hi, vmax = limits
    p = degree
    position = bernstein_matrix(p, s)[1:-1]
    speed = bernstein_derivative_matrix(p, duration, 1, s)
    q_margin = _MARGIN * 0.5 * (hi - lo) if math.isfinite(hi - lo) else 0.0
    v_margin = _MARGIN * vmax if math.isfinite(vmax) else 0.0
    rows = [
        (matrix, np.full(matrix.shape[0], bound - margin))
        for matrix, bound, margin in (
            (position, hi, q_margin),
            (-position, -lo, q_margin),
            (speed, vmax, v_margin),
            (-speed, vmax, v_margin),
        )
        if math.isfinite(bound)
    ]
    a_ub = np.vstack([r[0] for r in rows]) if rows else np.zeros((0, p + 1))
    b_ub = np.concatenate([r[1] for r in rows]) if rows else np.zeros(0)
    a_eq = np.zeros((4, p + 1))
    a_eq[0, 0] = a_eq[1, p] = 1.0
    a_eq[2, [0, 1]] = np.array([-1.0, 1.0]) * p / duration
    a_eq[3, [p - 1, p]] = np.array([-1.0, 1.0]) * p / duration
    return SplineConstraints(a_ub, b_ub, a_eq, np.array([q0, q1, v0, v1]))


def _nearest_points(lp: SplineConstraints, target: Array) -> Array | None:
    """Control points within ``lp`` nearest ``target`` in L1, or None if the LP is infeasible."""
    from scipy.optimize import linprog  # SciPy: only when a spline start is drawn

    n = target.size
    # Variables (b, e): minimise sum(e) with -e <= b - target <= e.
    eye = np.eye(n)
    a_ub = np.vstack([
        np.hstack([eye, -eye]), np.hstack([-eye, -eye]),
        np.hstack([lp.a_ub, np.zeros_like(lp.a_ub)]),
    ])  # fmt: skip
    res = linprog(
        np.concatenate([np.zeros(n), np.ones(n)]),
        A_ub=a_ub, b_ub=np.concatenate([target, -target, lp.b_ub]),
        A_eq=np.hstack([lp.a_eq, np.zeros_like(lp.a_eq)]), b_eq=lp.b_eq,
        bounds=[(None, None)] * n + [(0.0, None)] * n, method="highs",
    )  # fmt: skip
    if res.status != 0:
        _LOG.debug("spline LP of degree %d: %s", n - 1, res.message)
        return None
    return np.array(res.x[:n], dtype=float)


def random_spline_guess(
    robot: RobotModel | pin.Model,
    start: BoundaryLike,
    goal: BoundaryLike,
    n_knots: int,
    *,
    seed: int | np.random.Generator | None,
    dt: float | None = None,
    bound_scale: float = 1.0,
    orders: tuple[int, ...] = DEFAULT_ORDERS,
    bounds: JointBounds | None = None,
    damping: bool = True,
) -> Trajectory:
    """Draw a random polynomial motion per joint within the knot limits (the study's guesses).

    Parameters
    ----------
    robot : RobotModel or pinocchio.Model
        The robot (limits, damping and inertia).
    start, goal : BoundaryState, (q, v) pair, or q vector
        Boundary states: positions in [rad], velocities in [rad/s] (zero for a
        bare q vector).
    n_knots : int
        Number of knots N >= 2.
    seed : int, numpy.random.Generator or None
        Randomness; the same int gives the same guess (``None``: fresh entropy).
    dt : float, optional
        Time step in [s]; the guess lasts ``T0 = (N - 1) dt``. Default:
        ``DEFAULT_GUESS_DURATION / (N - 1)`` (4.9 s in all, the study's
        :data:`DEFAULT_DT` = 0.1 s at 50 knots), the default of multistart.
    bound_scale : float, optional
        Factor > 0 applied to the position (about zero) and speed limits, as
        :meth:`youbot_opt.trajopt.problem.TrajOptProblem.bounds` does by default.
    orders : tuple of int, optional
        Polynomial degrees (>= 3) drawn from, independently per joint.
    bounds : JointBounds, optional
        Explicit scaled bounds (``q_lower``, ``q_upper``, ``v_upper`` are used);
        overrides ``bound_scale``.
    damping : bool, optional
        Add the joint damping torque ``b v`` to the inverse dynamics.

    Returns
    -------
    Trajectory
        Trapezoidal-interpolated knots ``t_k = k dt``; q, v, a are the
        polynomials and their derivatives at the knots, and
        ``tau = RNEA(q, v, a) + b v``.

    Raises
    ------
    ParameterError
        On bad arguments, a start or goal outside the scaled limits, or when no
        degree in ``orders`` admits a polynomial within the knot limits (for
        example, a motion too long for the speed limit in ``T0``).
    """
    view = as_robot_model(robot)
    nq = view.model.nq
    n_knots = check_int(n_knots, "n_knots", minimum=2)
    if dt is None:
        from youbot_opt.trajopt.guess import DEFAULT_GUESS_DURATION

        dt = DEFAULT_GUESS_DURATION / (int(n_knots) - 1)
    dt = check_positive(dt, "dt", unit="s")
    bound_scale = check_bound_scale(bound_scale)
    orders = tuple(orders)
    if not orders or any(
        isinstance(p, bool) or not isinstance(p, int | np.integer) or p < 3 for p in orders
    ):
        raise ParameterError(
            f"orders must be a non-empty tuple of polynomial degrees >= 3, got {orders!r}",
            name="orders",
            value=orders,
        )
    q0, v0 = _boundary_state("start", start, nq)
    q1, v1 = _boundary_state("goal", goal, nq)
    if bounds is None:
        scaled = view.bounds(bound_scale)
        lower, upper, vmax = scaled.q_lower, scaled.q_upper, scaled.v_upper
    else:
        lower = np.asarray(bounds.q_lower, dtype=float)
        upper = np.asarray(bounds.q_upper, dtype=float)
        vmax = np.asarray(bounds.v_upper, dtype=float)
    for name, x, lo, hi, unit in (
        ("start.q", q0, lower, upper, "rad"),
        ("goal.q", q1, lower, upper, "rad"),
        ("start.v", v0, -vmax, vmax, "rad/s"),
        ("goal.v", v1, -vmax, vmax, "rad/s"),
    ):
        where = "the given bounds" if bounds is not None else f"bound_scale = {bound_scale:g}"
        _check_inside(name, x, lo, hi, unit, where)

    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    n = int(n_knots)
    duration = (n - 1) * float(dt)
    s = np.linspace(0.0, 1.0, n)
    q, v, a = np.empty((n, nq)), np.empty((n, nq)), np.empty((n, nq))
    for j in range(nq):
        span = max(abs(q1[j] - q0[j]), math.pi)
        lo_t = lower[j] if math.isfinite(lower[j]) else min(q0[j], q1[j]) - span
        hi_t = upper[j] if math.isfinite(upper[j]) else max(q0[j], q1[j]) + span
        candidates = sorted(set(int(p) for p in orders))
        points = None
        while candidates:
            p = int(rng.choice(candidates))
            target = rng.uniform(lo_t, hi_t, p + 1)
            boundary = (q0[j], v0[j], q1[j], v1[j])
            lp = spline_constraints(p, s, duration, boundary, (lower[j], upper[j], vmax[j]))
            points = _nearest_points(lp, target)
            if points is not None:
                # Impose the boundary conditions exactly (the LP meets them to its tolerance).
                points[0], points[p] = q0[j], q1[j]
                points[1] = q0[j] + v0[j] * duration / p
                points[p - 1] = q1[j] - v1[j] * duration / p
                break
            candidates.remove(p)
        if points is None:
            need = abs(q1[j] - q0[j]) / duration
            raise ParameterError(
                f"no polynomial of degree {sorted(set(orders))} moves joint {j} from "
                f"q = {q0[j]:.6g} rad, v = {v0[j]:.6g} rad/s to q = {q1[j]:.6g} rad, "
                f"v = {v1[j]:.6g} rad/s in T0 = {duration:.6g} s within [{lower[j]:.6g}, "
                f"{upper[j]:.6g}] rad and |v| <= {vmax[j]:.6g} rad/s at {n} knots (mean speed "
                f"needed {need:.3g} rad/s); raise n_knots or dt, or relax bound_scale",
                name="goal",
                value=float(q1[j]),
            )
        diff = _difference(p)
        q[:, j] = bernstein_matrix(p, s) @ points
        v[:, j] = (p / duration) * bernstein_matrix(p - 1, s) @ (diff @ points)
        a[:, j] = (
            (p * (p - 1) / duration**2)
            * bernstein_matrix(p - 2, s)
            @ (_difference(p - 1) @ diff @ points)
        )
        _LOG.debug("joint %d: degree %d", j, p)

    model, data = view.model, view.model.createData()
    b = view.damping if damping else np.zeros(nq)
    tau = np.array([pin.rnea(model, data, q[k], v[k], a[k]) + b * v[k] for k in range(n)])
    t = np.arange(n, dtype=float) * float(dt)
    return Trajectory(t=t, q=q, v=v, a=a, tau=tau, interpolation="trapezoidal")
