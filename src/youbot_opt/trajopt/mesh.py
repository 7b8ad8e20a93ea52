r"""The collocation mesh: each interval's error, and the next mesh from it.

:func:`collocation_error` puts the state interpolant the transcription implies
back into the dynamics (Pinocchio's ``pin.aba``, not the NLP's) and integrates
``|x'_interp - f(x_interp, tau_interp)|`` over each interval (composite
Gauss-Legendre), relative to Betts' scale ``1 + max_k(|x_i|, |x_i'|)`` (Betts,
*Practical Methods for Optimal Control*, ch. 4). :func:`split_grid` turns the
errors into the next mesh at ``e ~ h^m`` (:data:`ERROR_EXPONENTS`, the exponents
seen: :func:`observed_exponents`). Rationale: docs/refinement.md.

>>> collocation_error(result).max  # doctest: +SKIP
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from youbot_opt._checks import check_int
from youbot_opt._typing import Array
from youbot_opt.dynamics.numeric import RobotLike, batched_aba
from youbot_opt.exceptions import ParameterError
from youbot_opt.trajopt import quadrature
from youbot_opt.trajopt.result import TrajOptResult

__all__ = [
    "CollocationError",
    "ERROR_EXPONENTS",
    "MOVED",
    "ORDERS",
    "collocation_error",
    "interval_errors",
    "observed_exponents",
    "predicted_knots",
    "solution_moved",
    "split_grid",
    "switching_intervals",
]

ORDERS: dict[str, int] = {"trapezoidal": 2, "hermite_simpson": 4, "radau": 5}
"""Order ``p`` of each transcription: the local error of an interval of length
``h`` scales as ``h^(p + 1)`` (Betts, ch. 4)."""


@dataclass(frozen=True, slots=True)
class CollocationError:
    """Per-interval collocation error of one solution.

    Attributes
    ----------
    method : str
        Transcription whose interpolant was used.
    t : ndarray, shape (N,)
        Knot times [s].
    absolute : ndarray, shape (N - 1, 2 nv)
        ``integral |residual| dt`` over each interval, per state component:
        positions first in [rad], then velocities in [rad/s].
    scale : ndarray, shape (2 nv,)
        Betts' scale ``1 + max over knots of (|x_i|, |x_i'|)`` per component.
    relative : ndarray, shape (N - 1,)
        ``max_i absolute[k, i] / scale[i]`` of each interval (dimensionless).
    order : int
        The transcription's order ``p`` (:data:`ORDERS`).
    """

    method: str
    t: Array
    absolute: Array
    scale: Array
    relative: Array
    order: int

    @property
    def max(self) -> float:
        """Largest relative interval error."""
        return float(np.max(self.relative))

    @property
    def worst_interval(self) -> int:
        """Index of the interval with the largest relative error."""
        return int(np.argmax(self.relative))

    @property
    def steps(self) -> Array:
        """Interval lengths [s]."""
        return np.diff(self.t)


def interval_errors(
    method: str,
    t: Array,
    q: Array,
    v: Array,
    tau: Array,
    robot: RobotLike,
    *,
    mid: tuple[Array, Array, Array] | None = None,
    stages: tuple[Array, Array, Array] | None = None,
    damping: bool = True,
    segments: int = 4,
    points: int = 5,
) -> CollocationError:
    """Collocation error of knot arrays under ``method``'s interpolant.

    Parameters
    ----------
    method : {"trapezoidal", "hermite_simpson", "radau"}
        The transcription whose interpolant is used.
    t : ndarray, shape (N,)
        Strictly increasing knot times [s].
    q, v, tau : ndarray, shape (N, nv)
        Knot positions [rad], velocities [rad/s] and torques [N m].
    robot : RobotModel or pinocchio.Model
        The robot; its accelerations come from ``pin.aba``.
    mid : (q_mid, v_mid, tau_mid), each (N - 1, nv), optional
        Mid-interval values; required by Hermite-Simpson.
    stages : (q, v, tau) at the two inner Radau nodes, each (N - 1, 2, nv), optional
        Stage values; required by Radau.
    damping : bool
        Apply the robot's viscous joint damping.
    segments, points : int
        Composite Gauss-Legendre rule: ``segments`` equal pieces of each
        interval, ``points`` nodes each (exact for polynomials of degree
        ``2 points - 1``; the pieces localise the kinks of ``|residual|``).

    Returns
    -------
    CollocationError
        Absolute and relative errors per interval.

    Raises
    ------
    ParameterError
        On an unknown method, missing midpoints, bad shapes or times.
    """
    if method not in ORDERS:
        raise ParameterError(
            f"method must be one of {sorted(ORDERS)}, got {method!r}", name="method", value=method
        )
    segments = check_int(segments, "segments", minimum=1)
    points = check_int(points, "points", minimum=1)
    t = np.asarray(t, dtype=float).ravel()
    q, v, tau = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (q, v, tau))
    n, nv = q.shape
    if t.shape != (n,) or v.shape != (n, nv) or tau.shape != (n, nv) or n < 2:
        raise ParameterError(
            f"need t (N,) and q, v, tau (N, nv) with N >= 2, got {t.shape}, {q.shape}, "
            f"{v.shape}, {tau.shape}",
            name="t",
        )
    h = np.diff(t)
    if not np.all(h > 0.0):
        raise ParameterError("knot times must be strictly increasing", name="t")
    aba = batched_aba(robot, damping=damping)

    def accel(qq: Array, vv: Array, tt: Array) -> Array:
        return np.asarray(aba(qq, vv, tt), dtype=float).reshape(qq.shape)

    a = accel(q, v, tau)
    s, w = quadrature.gauss_legendre(segments, points)
    basis, integral = quadrature.collocation_basis(method, s)  # (S, 2 or 3)
    if method == "hermite_simpson":
        if mid is None:
            raise ParameterError("Hermite-Simpson needs the midpoint values", name="mid")
        qm, vm, taum = (np.asarray(x, dtype=float).reshape(n - 1, nv) for x in mid)
        am = accel(qm, vm, taum)
        # columns of the derivative polynomials: (interval, node-of-poly, joint)
        dq = np.stack([v[:-1], vm, v[1:]], axis=1)
        dv = np.stack([a[:-1], am, a[1:]], axis=1)
        ctrl = np.stack([tau[:-1], taum, tau[1:]], axis=1)
        ctrl_basis = basis
    elif method == "radau":
        if stages is None:
            raise ParameterError("Radau needs the stage values", name="stages")
        qs, vs, taus = (np.asarray(x, dtype=float).reshape(n - 1, 2, nv) for x in stages)
        as_ = accel(qs.reshape(-1, nv), vs.reshape(-1, nv), taus.reshape(-1, nv))
        end = np.s_[1:, None, :]
        dq = np.concatenate([vs, v[end]], axis=1)
        dv = np.concatenate([as_.reshape(n - 1, 2, nv), a[end]], axis=1)
        ctrl = np.concatenate([taus, tau[end]], axis=1)
        ctrl_basis = basis
    else:
        dq = np.stack([v[:-1], v[1:]], axis=1)
        dv = np.stack([a[:-1], a[1:]], axis=1)
        ctrl = np.stack([tau[:-1], tau[1:]], axis=1)
        ctrl_basis = basis
    hk = h[:, None, None]
    # interpolants at the quadrature nodes: (interval, node, joint)
    q_s = q[:-1, None, :] + hk * np.einsum("sc,kcj->ksj", integral, dq)
    v_s = v[:-1, None, :] + hk * np.einsum("sc,kcj->ksj", integral, dv)
    dq_s = np.einsum("sc,kcj->ksj", basis, dq)
    dv_s = np.einsum("sc,kcj->ksj", basis, dv)
    tau_s = np.einsum("sc,kcj->ksj", ctrl_basis, ctrl)
    shape = q_s.shape
    a_s = accel(q_s.reshape(-1, nv), v_s.reshape(-1, nv), tau_s.reshape(-1, nv)).reshape(shape)
    res_q = np.abs(dq_s - v_s)  # q' of the interpolant minus its velocity [rad/s]
    res_v = np.abs(dv_s - a_s)  # v' of the interpolant minus the dynamics [rad/s^2]
    absolute = (
        np.concatenate([np.einsum("s,ksj->kj", w, res_q), np.einsum("s,ksj->kj", w, res_v)], axis=1)
        * h[:, None]
    )
    scale = 1.0 + np.concatenate(
        [
            np.maximum(np.max(np.abs(q), axis=0), np.max(np.abs(v), axis=0)),
            np.maximum(np.max(np.abs(v), axis=0), np.max(np.abs(a), axis=0)),
        ]
    )
    relative = np.max(absolute / scale, axis=1)
    for arr in (t, absolute, scale, relative):
        arr.setflags(write=False)
    return CollocationError(method, t, absolute, scale, relative, ORDERS[method])


def collocation_error(
    result: TrajOptResult, *, segments: int = 4, points: int = 5
) -> CollocationError:
    """Collocation error of a solve result (see :func:`interval_errors`).

    Raises
    ------
    ParameterError
        If the result has no trajectory or its transcription has no error rule.
    """
    if result.trajectory is None:
        raise ParameterError("the result has no trajectory (non-finite iterate)", name="result")
    values = result.variables
    mid = stages = None
    if result.method == "hermite_simpson":
        mid = (values["q_mid"], values["v_mid"], values["tau_mid"])
    elif result.method == "radau":
        stages = tuple(
            np.stack([values[f"{x}_stage1"], values[f"{x}_stage2"]], axis=1)
            for x in ("q", "v", "tau")
        )
    return interval_errors(
        result.method, result.trajectory.t, values["q"], values["v"], values["tau"],
        result.problem.robot, mid=mid, stages=stages, damping=result.problem.damping,  # type: ignore[arg-type]
        segments=segments, points=points,
    )  # fmt: skip


ERROR_EXPONENTS: dict[str, int] = {"trapezoidal": 3, "hermite_simpson": 4, "radau": 4}
"""Exponent ``m`` of the interval error estimate, ``e ~ h^m``: ``p + 1 = 3`` for
trapezoidal collocation (order 2); 4 for Hermite-Simpson, whose residual along
its cubic is ``|a_k - 2 a_m + a_{k+1}| h^2 / 48 ~ h^4`` (derived in
tests/trajopt/test_refine.py), one power below its O(h^5) state error; 4 for
Radau IIA too: its cubic satisfies the dynamics at three nodes, so the residual
between them is ``O(h^3)`` and its integral ``O(h^4)`` (stage order 3), below
the method's order 5 at the knots."""


def split_grid(
    t: Array, errors: Array, tolerance: float, exponent: float | Array, max_pieces: int
) -> tuple[Array, NDArray[np.intp]]:
    """Split the intervals whose error exceeds ``tolerance``.

    Interval ``k`` with error ``e_k > tolerance`` becomes
    ``min(max_pieces, ceil((e_k / tolerance)^(1 / m_k)))`` (at least 2)
    equal pieces, the count that brings ``e ~ h^m_k`` within the tolerance;
    ``exponent`` is ``m``, one for all intervals or one per interval
    (:func:`observed_exponents`).

    Returns
    -------
    fractions : ndarray
        The new grid's interval fractions of ``T`` (summing to 1).
    parent : ndarray of int
        For each new interval, the index of the interval it came from.
    """
    h = np.diff(np.asarray(t, dtype=float))
    ratio = np.asarray(errors, dtype=float) / tolerance
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        pieces = np.ceil(ratio ** (1.0 / np.asarray(exponent, dtype=float)))
    pieces = np.where(ratio > 1.0, np.clip(pieces, 2, max_pieces), 1).astype(np.intp)
    parent = np.repeat(np.arange(h.size), pieces)
    fractions = np.repeat(h / pieces, pieces)
    return fractions / fractions.sum(), parent


def observed_exponents(
    parent_errors: Array,
    errors: Array,
    parent: NDArray[np.intp],
    exponent: float | Array,
    stretch: float = 1.0,
) -> Array:
    """Per-interval error exponents seen in the last split (Betts' order reduction).

    A piece of an interval split into ``p`` pieces should have the error
    ``e_parent / p^m``; where the solution is not smooth (a torque switching
    between bounds) it falls more slowly. The exponent each piece showed,
    ``log(e_parent / e_piece) / log(p)``, clipped to ``[1, m]``, predicts its
    next split (Betts, *Practical Methods for Optimal Control*, sec. 4.7.4,
    estimates the order reduction the same way). Unsplit intervals keep their
    parent's exponent. The grid is kept as fractions of the duration, so when
    the new solve's duration is ``stretch`` times the old one every interval
    is ``stretch`` times longer: the parent's error is first carried to the
    new duration, ``e_parent stretch^m``.

    Parameters
    ----------
    parent_errors : ndarray, shape (n_old,)
        Relative errors of the previous grid's intervals.
    errors : ndarray, shape (n_new,)
        Relative errors of the new grid's intervals.
    parent : ndarray of int, shape (n_new,)
        Each new interval's interval on the previous grid (:func:`split_grid`).
    exponent : float or ndarray, shape (n_old,)
        The exponents the previous split assumed (the method's at most).
    stretch : float
        New duration over old duration (1: the same ``T``).

    Returns
    -------
    ndarray, shape (n_new,)
        The exponent of each new interval.
    """
    m_old = np.broadcast_to(np.asarray(exponent, dtype=float), parent_errors.shape)[parent]
    pieces = np.bincount(parent, minlength=parent_errors.size)[parent]
    m_max = float(np.max(m_old, initial=1.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        seen = np.log(parent_errors[parent] * stretch**m_old / errors) / np.log(pieces)
    seen = np.clip(np.nan_to_num(seen, nan=m_max, posinf=m_max), 1.0, m_max)
    return np.where(pieces > 1, seen, m_old)


MOVED = 0.01
"""Relative change of the duration ``T`` between two rounds above which the
solution has moved: its features (bound switches, the fast transients of a
light or damped joint) are no longer where the previous grid's fractions of
``T`` put them, so the fall of the error from the old grid to the new one
measures the move, not the error's order, and :func:`refine` does not trust
:func:`observed_exponents` across it (docs/refinement.md, "A solution that moves")."""


def solution_moved(old_duration: float, new_duration: float) -> bool:
    """Return True when the duration changed by more than :data:`MOVED` (relative).

    Parameters
    ----------
    old_duration, new_duration : float
        ``T`` [s] of the previous and the new round.
    """
    stretch = new_duration / old_duration if old_duration > 0.0 else math.inf
    return not (math.isfinite(stretch) and abs(stretch - 1.0) <= MOVED)


def switching_intervals(result: TrajOptResult, relative: float = 1e-6) -> NDArray[np.bool_]:
    """Intervals at whose two knots a different set of joint bounds is active.

    A position, velocity or torque bound counts as active at a knot when the
    value is within ``relative`` of the bound's range from it. Where the active
    set changes inside an interval the solution's derivative jumps there, and
    the interval's error falls more slowly than the method's ``h^m`` (Betts,
    sec. 4.7.4: order reduction at constraint switches); :func:`refine` splits
    such intervals of the first grid as if ``m = 1``, the lowest exponent
    :func:`observed_exponents` allows.

    Returns
    -------
    ndarray of bool, shape (n_knots - 1,)
        True where the active set changes across the interval.
    """
    bounds = result.bounds()
    active = []
    for name, lower, upper in (
        ("q", bounds.q_lower, bounds.q_upper),
        ("v", bounds.v_lower, bounds.v_upper),
        ("tau", bounds.tau_lower, bounds.tau_upper),
    ):
        x = np.asarray(result.variables[name], dtype=float)
        span = np.asarray(upper - lower, dtype=float)
        margin = relative * np.where(np.isfinite(span), span, 0.0)
        active.append((upper - x <= margin) | (x - lower <= margin))  # never at an infinite one
    switches = np.hstack(active)
    return np.any(switches[1:] != switches[:-1], axis=1)


def predicted_knots(errors: Array, tolerance: float, exponent: float | Array) -> int:
    """Knots a grid would need for every interval to reach ``tolerance``, at ``e ~ h^m``.

    Interval ``k`` needs ``max(1, ceil((e_k / tolerance)^(1 / m_k)))`` pieces
    (:func:`split_grid` without its cap on pieces per round).
    """
    ratio = np.asarray(errors, dtype=float) / tolerance
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        pieces = np.ceil(ratio ** (1.0 / np.asarray(exponent, dtype=float)))
    pieces = np.where(ratio > 1.0, np.maximum(pieces, 2.0), 1.0)
    return int(min(np.sum(pieces), 1e15)) + 1
