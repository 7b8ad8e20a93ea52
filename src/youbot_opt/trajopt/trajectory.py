"""Joint-space trajectories on a time grid, callable at any time (toppra style).

A :class:`Trajectory` holds knot-major arrays (``q[k]`` at ``t[k]``) and the
interpolant of its transcription: ``"trapezoidal"`` (torque and velocity
linear, position quadratic; Betts, *Practical Methods for Optimal Control*,
sec. 4.6), ``"hermite_simpson"`` (torque quadratic, position and velocity
cubic Hermite) or ``"radau"`` (torque quadratic through the stages, position
and velocity cubic). Details: docs/design.md, "Module notes".

>>> q = trajectory(0.5)  # (nq,) [rad] at t = 0.5 s  # doctest: +SKIP
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError
from youbot_opt.trajopt import quadrature

__all__ = ["Trajectory", "Interpolation"]

Interpolation = Literal["trapezoidal", "hermite_simpson", "radau"]
_INTERPOLATIONS: tuple[str, ...] = ("trapezoidal", "hermite_simpson", "radau")
_STAGE_FIELDS: tuple[str, ...] = ("v_stages", "a_stages", "tau_stages")


def _as_matrix(name: str, value: object, rows: int | None, cols: int | None) -> Array:
    arr = np.array(value, dtype=float)
    if arr.ndim != 2 or (rows is not None and arr.shape[0] != rows):
        raise ParameterError(
            f"{name} must have shape ({rows}, n), got {arr.shape}", name=name, value=arr.shape
        )
    if cols is not None and arr.shape[1] != cols:
        raise ParameterError(
            f"{name} must have {cols} columns, got shape {arr.shape}", name=name, value=arr.shape
        )
    if not np.all(np.isfinite(arr)):
        raise ParameterError(f"{name} contains non-finite values", name=name)
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, slots=True, kw_only=True)
class Trajectory:
    """A joint trajectory sampled at knots, with its transcription's interpolant.

    Attributes
    ----------
    t : ndarray, shape (N,)
        Knot times in [s], strictly increasing.
    q : ndarray, shape (N, nq)
        Joint positions in [rad] (or [m] for prismatic joints).
    v : ndarray, shape (N, nv)
        Joint velocities in [rad/s].
    a : ndarray, shape (N, nv)
        Joint accelerations in [rad/s^2] (forward dynamics at the knots).
    tau : ndarray, shape (N, nv)
        Joint torques in [N m].
    tau_mid : ndarray, shape (N - 1, nv), optional
        Mid-interval torques in [N m] (Hermite–Simpson only).
    interpolation : {"trapezoidal", "hermite_simpson", "radau"}
        Which interpolant :meth:`__call__`, :meth:`velocity` and
        :meth:`torque` use between knots.
    v_stages, a_stages, tau_stages : ndarray, shape (N - 1, 2, nv), optional
        Velocities [rad/s], accelerations [rad/s^2] and torques [N m] at the
        two inner Radau nodes of each interval (``"radau"`` only; the third
        node is the interval's end knot, :mod:`youbot_opt.trajopt.quadrature`). The
        torque is the quadratic through the three stages, so it may jump at a
        knot: :meth:`torque` at a knot time gives the value of the interval
        that starts there, ``tau[k]`` (``k >= 1``) the one that ends there.
    """

    t: Array
    q: Array
    v: Array
    a: Array
    tau: Array
    tau_mid: Array | None = None
    interpolation: Interpolation = "trapezoidal"
    v_stages: Array | None = None
    a_stages: Array | None = None
    tau_stages: Array | None = None

    def __post_init__(self) -> None:
        t = np.array(self.t, dtype=float)
        if t.ndim != 1 or t.size < 2:
            raise ParameterError(f"t must be 1-D with >= 2 knots, got shape {t.shape}", name="t")
        if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0.0):
            raise ParameterError("t must be finite and strictly increasing [s]", name="t")
        t.setflags(write=False)
        object.__setattr__(self, "t", t)
        n = t.size
        q = _as_matrix("q", self.q, n, None)
        object.__setattr__(self, "q", q)
        for name in ("v", "a", "tau"):
            object.__setattr__(self, name, _as_matrix(name, getattr(self, name), n, None))
        nv = self.v.shape[1]
        for name in ("a", "tau"):
            if getattr(self, name).shape[1] != nv:
                raise ParameterError(f"{name} must have nv = {nv} columns", name=name)
        if self.interpolation not in _INTERPOLATIONS:
            raise ParameterError(
                f"interpolation must be one of {_INTERPOLATIONS}, got {self.interpolation!r}",
                name="interpolation",
                value=self.interpolation,
            )
        if self.interpolation == "hermite_simpson":
            if self.tau_mid is None:
                raise ParameterError("hermite_simpson trajectories need tau_mid", name="tau_mid")
            object.__setattr__(self, "tau_mid", _as_matrix("tau_mid", self.tau_mid, n - 1, nv))
        elif self.tau_mid is not None:
            raise ParameterError("tau_mid is only used by hermite_simpson", name="tau_mid")
        for name in _STAGE_FIELDS:
            value = getattr(self, name)
            if self.interpolation != "radau":
                if value is not None:
                    raise ParameterError(f"{name} is only used by radau", name=name)
                continue
            if value is None:
                raise ParameterError(f"radau trajectories need {name}", name=name)
            arr = np.array(value, dtype=float)
            if arr.shape != (n - 1, 2, nv):
                raise ParameterError(
                    f"{name} must have shape ({n - 1}, 2, {nv}), got {arr.shape}",
                    name=name,
                    value=arr.shape,
                )
            if not np.all(np.isfinite(arr)):
                raise ParameterError(f"{name} contains non-finite values", name=name)
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    # ------------------------------------------------------------------ sizes
    @property
    def n_knots(self) -> int:
        """Number of knots N."""
        return int(self.t.size)

    @property
    def duration(self) -> float:
        """Total duration ``t[-1] - t[0]`` in [s]."""
        return float(self.t[-1] - self.t[0])

    # ---------------------------------------------------------- interpolation
    def _locate(self, time: Array) -> tuple[NDArray[np.intp], Array, Array]:
        """Interval index k, local time s in [s] and interval length h in [s]."""
        if not np.all(np.isfinite(time)):
            raise ParameterError("query times must be finite [s]", name="time")
        tt = np.clip(time, self.t[0], self.t[-1])
        k = np.clip(np.searchsorted(self.t, tt, side="right") - 1, 0, self.n_knots - 2)
        h = self.t[k + 1] - self.t[k]
        return k, tt - self.t[k], h

    def __call__(self, time: float | Array) -> Array:
        """Joint positions at ``time`` [s]; shape (nq,) for a scalar, (M, nq) for (M,).

        Times outside ``[t[0], t[-1]]`` are clamped to the ends.
        """
        return self._eval(time, "q")

    def velocity(self, time: float | Array) -> Array:
        """Joint velocities in [rad/s] at ``time`` [s] (shape as :meth:`__call__`)."""
        return self._eval(time, "v")

    def torque(self, time: float | Array) -> Array:
        """Joint torques in [N m] at ``time`` [s] under the transcription's interpolant."""
        return self._eval(time, "tau")

    def acceleration(self, time: float | Array) -> Array:
        """Joint accelerations in [rad/s^2] at ``time`` [s]: d/dt of :meth:`velocity`.

        Trapezoidal: constant on each interval, ``(v[k+1] - v[k]) / h``;
        Hermite-Simpson: the derivative of the cubic Hermite through ``v`` and
        ``a`` (equal to ``a`` at the knots); Radau: the quadratic through the
        stage accelerations. At a knot time the interval that starts there is used.
        """
        return self._eval(time, "a")

    def interval_values(self, nodes: Array) -> Array:
        """``[q, v, tau]`` of each interval's own interpolant at local times ``nodes``.

        Parameters
        ----------
        nodes : ndarray, shape (M,)
            Local times ``s = (t - t[k]) / h[k]`` in [0, 1] (dimensionless).

        Returns
        -------
        ndarray, shape (N - 1, M, nq + 2 nv)
            Unlike :meth:`__call__` at a knot time, ``s = 1`` gives the end of
            interval ``k`` (the left limit where the torque jumps).
        """
        x = np.asarray(nodes, dtype=float).ravel()
        n, m = self.n_knots - 1, x.size
        k = np.repeat(np.arange(n), m)
        h = np.repeat(np.diff(self.t), m)[:, None]
        xx = np.tile(x, n)[:, None]
        parts = [self._local(k, xx, h, what) for what in ("q", "v", "tau")]
        return np.hstack(parts).reshape(n, m, -1)

    def _eval(self, time: float | Array, what: str) -> Array:
        scalar = np.ndim(time) == 0
        k, s, h = self._locate(np.atleast_1d(np.asarray(time, dtype=float)))
        out = self._local(k, (s / h)[:, None], h[:, None], what)
        return out[0] if scalar else out

    def _local(self, k: NDArray[np.intp], x: Array, h: Array, what: str) -> Array:
        """Evaluate ``what`` of intervals ``k`` at local times ``x`` (a column), lengths ``h``."""
        if self.interpolation == "radau":
            return self._radau(k, x, h, what)
        s = x * h
        q0, q1, v0, v1 = self.q[k], self.q[k + 1], self.v[k], self.v[k + 1]
        a0, a1 = self.a[k], self.a[k + 1]
        if what == "a":  # d/dt of the velocity interpolant
            if self.interpolation == "trapezoidal":
                return np.asarray(np.broadcast_to((v1 - v0) / h, v0.shape))
            dh00 = (6 * x**2 - 6 * x) / h
            dh10 = 3 * x**2 - 4 * x + 1
            dh01 = (-6 * x**2 + 6 * x) / h
            dh11 = 3 * x**2 - 2 * x
            return np.asarray(dh00 * v0 + dh10 * a0 + dh01 * v1 + dh11 * a1)
        if what == "tau":
            if self.interpolation == "trapezoidal":
                out = self.tau[k] + x * (self.tau[k + 1] - self.tau[k])
            else:
                assert self.tau_mid is not None
                u0, um, u1 = self.tau[k], self.tau_mid[k], self.tau[k + 1]
                out = u0 * (2 * x - 1) * (x - 1) + um * 4 * x * (1 - x) + u1 * x * (2 * x - 1)
        elif self.interpolation == "trapezoidal":
            if what == "v":
                out = v0 + x * (v1 - v0)
            else:
                # Integral of the linear velocity, plus a linear correction that is
                # zero when the position defect vanishes, so knots are interpolated.
                defect = q1 - q0 - 0.5 * h * (v0 + v1)
                out = q0 + v0 * s + (v1 - v0) * s**2 / (2 * h) + x * defect
        else:
            p0, p1, d0, d1 = (q0, q1, v0, v1) if what == "q" else (v0, v1, a0, a1)
            h00 = 2 * x**3 - 3 * x**2 + 1
            h10 = x**3 - 2 * x**2 + x
            h01 = -2 * x**3 + 3 * x**2
            h11 = x**3 - x**2
            out = h00 * p0 + h10 * h * d0 + h01 * p1 + h11 * h * d1
        return np.asarray(out)

    def _radau(self, k: NDArray[np.intp], x: Array, h: Array, what: str) -> Array:
        """Radau interpolants: ``x(s) = x_k + h sum_j I_j(s) x'_j``, torque through the stages."""
        stages, ends = {
            "q": (self.v_stages, self.v),
            "v": (self.a_stages, self.a),
            "a": (self.a_stages, self.a),
            "tau": (self.tau_stages, self.tau),
        }[what]
        assert stages is not None
        values = np.concatenate([stages[k], ends[k + 1][:, None, :]], axis=1)  # (M, 3, nv)
        xs = x[:, 0]
        if what in ("tau", "a"):  # a: d/dt of v = v_k + h sum_j I_j(s) a_j
            return np.einsum("mj,mjc->mc", quadrature.radau_basis(xs), values)
        start = self.q[k] if what == "q" else self.v[k]
        return start + h * np.einsum("mj,mjc->mc", quadrature.radau_integral(xs), values)
