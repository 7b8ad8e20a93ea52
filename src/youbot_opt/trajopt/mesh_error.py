r"""Collocation-error estimate per interval: :func:`collocation_error`.

The state interpolant the transcription implies is put back into the dynamics
(Pinocchio's ``pin.aba``, not the NLP's) and the residual
``|x'_interp - f(x_interp, tau_interp)|`` is integrated over each interval by
composite Gauss-Legendre quadrature: the absolute local error in state units
([rad], [rad/s]), made relative by Betts' scale ``1 + max_k(|x_i|, |x_i'|)``
(Betts, *Practical Methods for Optimal Control*, ch. 4). The interpolants,
rationale and measurements: docs/refinement.md, "The collocation-error estimate".

>>> collocation_error(result).max  # doctest: +SKIP
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from youbot_opt._checks import check_int
from youbot_opt._typing import Array
from youbot_opt.dynamics.numeric import RobotLike, batched_aba
from youbot_opt.exceptions import ParameterError
from youbot_opt.trajopt import quadrature
from youbot_opt.trajopt.result import TrajOptResult

__all__ = ["CollocationError", "ORDERS", "collocation_error", "interval_errors"]

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
