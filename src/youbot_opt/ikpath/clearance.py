r"""Clearance of the cyclic IK path: rows at the targets and along the legs, certified (#28).

The path is the straight line in joint space between consecutive configurations,
closing the cycle. :class:`IKClearance` holds one row per distinct leg step and pair: half
the sum of the step's two ball distances less the step's point-motion bound,
which makes coal's clearance at least the margin everywhere on the path.
:func:`require_path_clearance` refuses a start or a target inside an obstacle;
:func:`certify_path_clearance` checks a result with coal (docs/ikpath.md).

>>> rows = IKClearance.build(problem, Clearance(scene=scene, margin=0.01), 8)  # doctest: +SKIP
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import casadi as ca
import coal
import numpy as np

from youbot_opt._typing import Array
from youbot_opt.collision.clearance import (
    Clearance,
    ClearanceCertificate,
    certify_clearance,
    clearance_checker,
    point_speed_bounds,
    require_clearance,
)
from youbot_opt.collision.exact import ExactChecker
from youbot_opt.dynamics.symbolic import build_symbolic_model
from youbot_opt.exceptions import ParameterError
from youbot_opt.ikpath.targets import Target
from youbot_opt.robot.model import RobotModel

__all__ = [
    "DEFAULT_LEG_SAMPLES",
    "IKClearance",
    "certify_path_clearance",
    "path_legs",
    "require_path_clearance",
]

#: Interior samples per leg by default (K; K + 1 steps per leg).
DEFAULT_LEG_SAMPLES = 8
_ABS_EPS2 = 1e-6  # smoothing of |dq| in [rad^2]: sqrt(x^2 + eps^2) >= |x|, eps = 1e-3 rad


class ClearedPath(Protocol):
    """What the clearance reads of a :class:`~youbot_opt.ikpath.problem.CyclicIKProblem`."""

    @property
    def robot_model(self) -> RobotModel: ...
    @property
    def targets(self) -> tuple[Target, ...]: ...
    @property
    def neutral(self) -> Array: ...
    @property
    def n_targets(self) -> int: ...
    @property
    def n_joints(self) -> int: ...
    @property
    def active_v(self) -> Array: ...
    @property
    def clearance_rows(self) -> IKClearance | None: ...
    def configuration(self, theta: Array) -> Array: ...
    def as_configurations(self, x: Array, name: str = "x") -> Array: ...


@dataclass(frozen=True, slots=True, kw_only=True)
class IKClearance:
    r"""The clearance rows of one cyclic IK problem, built once.

    Each leg ``q_j -> q_{j+1}`` is cut into ``K + 1`` equal steps; every point
    of a link moves at most ``sum_i |dq_i| R_i`` [m] over a joint step ``dq``
    (:func:`~youbot_opt.collision.point_speed_bounds` at unit speeds), so on a
    step from sample ``a`` to ``b`` a pair keeps at least
    ``(d_a + d_b - sum_i |Delta q_i| R_i / (K + 1)) / 2`` with ``d`` the
    conservative ball distances (never above coal's). ``|x|`` is smoothed as
    ``sqrt(x^2 + 1e-6)`` (never below ``|x|``; it gives away at most
    ``R_i 1e-3 / (K + 1)`` m of clearance where ``dq_i = 0``, and its curvature
    there, ``1e3``, is one the augmented Lagrangian's BFGS can follow: with
    ``1e-12`` it was ``1e6`` and a start whose legs ended with a joint at rest
    took over a minute per inner solve).

    Each distinct row is built once (:func:`path_legs`): with two targets leg 1
    is leg 0 walked back, whose samples and steps are leg 0's, so only leg 0's
    rows are built; they hold both legs (a repeated row would leave its
    multipliers determined only as a sum).

    Attributes
    ----------
    spec : Clearance
        The scene, margin and self-collision choice.
    checker : ExactChecker
        coal's solids of the pairs (the certificate's).
    leg_samples : int
        Interior samples ``K`` per leg.
    legs : tuple of int
        The legs the rows are built on, in row order (:func:`path_legs`).
    rates : ndarray, shape (n_pairs, n)
        ``R``: bound [m/rad] (or [m/m]) on how far a point of either solid of a
        pair moves per unit step of each active joint.
    distance : casadi.Function
        Active angles ``theta (n,)`` -> ball distances ``(n_pairs,)`` [m].
    function : casadi.Function
        ``x (n s,)`` -> rows ``(len(legs) (K + 1) n_pairs,)`` [m], leg-major,
        then step, then pair; each held at or above ``spec.margin``.
    jacobian : casadi.Function
        ``x`` -> ``d rows / d x`` (dense).
    transposed_product : casadi.Function
        ``(x, w)`` -> ``(d rows / d x)^T w`` (reverse mode, without the dense
        Jacobian: the augmented Lagrangian's gradient).
    labels : tuple of str
        Per row: ``"leg j step k: a / b"`` (with two targets, leg 0's step ``k``
        is also leg 1's step ``K - k``).
    """

    spec: Clearance
    checker: ExactChecker
    leg_samples: int
    legs: tuple[int, ...]
    rates: Array
    distance: ca.Function
    function: ca.Function
    jacobian: ca.Function
    transposed_product: ca.Function
    labels: tuple[str, ...]

    @property
    def n_pairs(self) -> int:
        """Checked pairs."""
        return len(self.checker.model.pair_names)

    @staticmethod
    def build(problem: ClearedPath, spec: Clearance, leg_samples: int) -> IKClearance:
        """Build the rows of ``problem`` (its robot, active joints, targets' count)."""
        robot = problem.robot_model
        checker = clearance_checker(robot, spec)
        model = robot.model
        nv = model.nv
        active_v = problem.active_v
        unit = np.eye(nv)
        n_pairs = len(checker.model.pair_names)
        rates = np.zeros((n_pairs, problem.n_joints))
        if n_pairs:
            for i, iv in enumerate(active_v):
                rates[:, i] = point_speed_bounds(checker, robot, unit[int(iv)])
        rest = np.zeros(nv)  # the joints off the chain: the problem's neutral, as angles
        for j in range(1, model.njoints):
            joint = model.joints[j]
            if joint.nq == 1:
                rest[joint.idx_v] = problem.neutral[joint.idx_q]
            elif joint.nq == 2:
                c, s_ = problem.neutral[joint.idx_q], problem.neutral[joint.idx_q + 1]
                rest[joint.idx_v] = math.atan2(s_, c)
        theta = ca.SX.sym("theta", problem.n_joints)
        entries = [ca.SX(float(value)) for value in rest]
        for i, iv in enumerate(active_v):
            entries[int(iv)] = theta[i]
        if n_pairs:
            fk = build_symbolic_model(robot).forward_kinematics
            d_of_q = checker.model.configuration_function(fk)
            d_theta = d_of_q(ca.vertcat(*entries))
        else:
            d_theta = ca.SX(0, 1)
        distance = ca.Function("ik_clearance_distance", [theta], [d_theta], ["theta"], ["d"])
        s, n, k1 = problem.n_targets, problem.n_joints, leg_samples + 1
        x = ca.SX.sym("x", s * n)
        q = [x[j * n : (j + 1) * n] for j in range(s)]
        at_target = [distance(qj) for qj in q]  # once each: the ends of two legs
        rows, labels = [], []
        names = checker.model.pair_names
        rate = ca.DM(rates)
        legs = path_legs(s)
        for j in legs:
            qa, qb = q[j], q[(j + 1) % s]
            dq = qb - qa
            reach = (rate @ ca.sqrt(dq * dq + _ABS_EPS2)) / k1 if n_pairs else ca.SX(0, 1)
            inner = [distance(qa + (k / k1) * dq) for k in range(1, k1)]
            ds = [at_target[j], *inner, at_target[(j + 1) % s]]
            for k in range(k1):
                rows.append(0.5 * (ds[k] + ds[k + 1] - reach))
                labels += [f"leg {j} step {k}: {a} / {b}" for a, b in names]
        g = ca.vertcat(*rows) if n_pairs else ca.SX(0, 1)
        w = ca.SX.sym("w", g.shape[0])
        return IKClearance(
            spec=spec,
            checker=checker,
            leg_samples=leg_samples,
            legs=legs,
            rates=rates,
            distance=distance,
            function=ca.Function("ik_clearance", [x], [g], ["x"], ["rows"]),
            jacobian=ca.Function("ik_clearance_jac", [x], [ca.jacobian(g, x)], ["x"], ["jac"]),
            transposed_product=ca.Function(
                "ik_clearance_jtw", [x, w], [ca.jtimes(g, x, w, True)], ["x", "w"], ["jtw"]
            ),
            labels=tuple(labels),
        )

    def rows(self, x: Array) -> Array:
        """Return the rows [m] at the flat path ``x`` (to be >= ``spec.margin``)."""
        return np.asarray(self.function(np.asarray(x, dtype=float)), dtype=float).ravel()

    def rows_jacobian(self, x: Array) -> Array:
        """Return ``d rows / d x`` (dense, shape (n_rows, n s))."""
        return np.asarray(self.jacobian(np.asarray(x, dtype=float)), dtype=float)

    def rows_jacobian_transposed(self, x: Array, w: Array) -> Array:
        """Return ``(d rows / d x)^T w``, shape (n s,), for row weights ``w`` (n_rows,)."""
        out = self.transposed_product(np.asarray(x, dtype=float), np.asarray(w, dtype=float))
        return np.asarray(out, dtype=float).ravel()


def path_legs(n_targets: int) -> tuple[int, ...]:
    """Return the legs whose clearance rows are built, one per distinct set of samples.

    Leg ``j`` runs from ``q_j`` to ``q_{(j+1) mod s}``. Two legs sample the same
    configurations, whatever ``x``, only when they join the same two targets:
    for ``s = 2`` leg 1 is leg 0 walked back (its step ``k`` is leg 0's step
    ``K - k``, the same row), so leg 0 alone is built. For ``s >= 3`` the legs
    join distinct pairs of targets and each is built.

    Parameters
    ----------
    n_targets : int
        Number of targets ``s >= 2``.

    Returns
    -------
    tuple of int
        ``(0,)`` for ``s = 2``, else ``(0, ..., s - 1)``.
    """
    return (0,) if n_targets == 2 else tuple(range(n_targets))


def require_path_clearance(problem: ClearedPath, x0: Array | None) -> None:
    """Refuse a start or a target the clearance cannot hold, before solving.

    A configuration of the start ``x0`` (shape (s, n) or flat) whose link
    geometry penetrates an obstacle or the robot itself (coal), and a target
    point inside a world-fixed obstacle, are refused.

    Raises
    ------
    ParameterError
        ``start configuration 1: link geometry 'link2' penetrates obstacle 'disc'
        (...)``, or ``target 2 at (0, 4, 0) m is inside obstacle 'disc' (...)``.
    """
    rows = problem.clearance_rows
    if rows is None:
        return
    checker = rows.checker
    robot = problem.robot_model
    for j, placed in enumerate(checker.model.obstacles):
        if placed.joint != 0:
            continue
        solid = checker.obstacle_solids[j]
        where = coal.Transform3s(placed.rotation, placed.translation)
        for t, target in enumerate(problem.targets):
            point = coal.Sphere(1e-9)
            at = coal.Transform3s(np.eye(3), np.asarray(target.position, dtype=float))
            request, result = coal.DistanceRequest(), coal.DistanceResult()
            d = coal.distance(point, at, solid, where, request, result)
            if d < 0:
                raise ParameterError(
                    f"target {t} at {tuple(round(float(v), 6) for v in target.position)} m is "
                    f"inside obstacle {placed.obstacle.name!r} (depth {-d:.4g} m): no "
                    "configuration can meet it with clearance",
                    name=f"target {t}",
                    value=target.position,
                )
    if x0 is None:
        return
    configs = problem.as_configurations(x0, name="x0")
    for j, theta in enumerate(configs):
        require_clearance(
            checker, robot, problem.configuration(theta), what=f"start configuration {j}"
        )


def certify_path_clearance(
    problem: ClearedPath, x: Array, *, tolerance: float = 1e-3, margin: float | None = None
) -> ClearanceCertificate | None:
    """Certify the closed joint path through ``x`` with coal's exact distances.

    Time ``t`` in ``[j, j + 1]`` is leg ``j`` (``q_j`` to ``q_{j+1}``, the last
    leg back to ``q_0``); the joint speed bound is each joint's largest
    ``|dq|`` over the legs. Returns None without a clearance or without pairs.

    Parameters
    ----------
    problem : CyclicIKProblem (or any ClearedPath)
        The problem (its clearance and robot).
    x : ndarray, shape (n s,) or (s, n)
        The path in [rad].
    tolerance : float
        Allowed shortfall in [m] (ends the bisection).
    margin : float, optional
        Required clearance in [m] (default: the problem's).

    Returns
    -------
    ClearanceCertificate or None
        ``closest_time``: leg index plus the fraction along it.
    """
    rows = problem.clearance_rows
    if rows is None or rows.n_pairs == 0:
        return None
    q = problem.as_configurations(x)
    s = len(q)
    legs = np.roll(q, -1, axis=0) - q
    v_max = np.zeros(problem.robot_model.model.nv)
    v_max[problem.active_v] = np.max(np.abs(legs), axis=0)

    def motion(t: float) -> Array:
        j = min(int(math.floor(t)), s - 1)
        return problem.configuration(q[j] + (t - j) * legs[j])

    times = np.linspace(0.0, float(s), s * (rows.leg_samples + 1) + 1)
    return certify_clearance(
        rows.checker,
        problem.robot_model,
        motion,
        times,
        v_max=v_max,
        margin=rows.spec.margin if margin is None else margin,
        tolerance=tolerance,
    )
