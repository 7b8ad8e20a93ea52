"""Forward simulation of a planned trajectory with Pinocchio's numeric ABA.

Owns the code path :mod:`youbot_opt.trajopt.certify` and
:mod:`youbot_opt.trajopt.check` verify plans with, independent of the
collocation equations (spec ``trajopt.md``, "prove each trajectory by forward
simulation"): :func:`integrate_intervals` (one interval from every knot) and
:func:`simulate` (the whole motion, open loop or with :class:`PDGains`), all
integrated by SciPy's ``solve_ivp`` (DOP853, or Radau where the damping is
stiff: :func:`integration_method`), with the accelerations of
:func:`youbot_opt.dynamics.numeric.batched_aba`. Robots with ``nq == nv`` only.

>>> sim = simulate(result.trajectory, robot, gains=PDGains())  # doctest: +SKIP
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from youbot_opt._typing import Array
from youbot_opt.dynamics.numeric import (
    STIFF_RATIO,
    RobotLike,
    acting_damping,
    as_numeric_robot,
    batched_aba,
    damping_rate,
)
from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.model import RobotModel, as_robot_model
from youbot_opt.trajopt.trajectory import Trajectory

__all__ = [
    "PDGains",
    "Simulation",
    "integrate_intervals",
    "integration_method",
    "simulate",
    "sample_times",
]

_LOG = logging.getLogger(__name__)

DEFAULT_RTOL = 1e-10
"""Default relative tolerance of the integrator (DOP853)."""
DEFAULT_ATOL = 1e-12
"""Default absolute tolerance of the integrator, in [rad] and [rad/s]."""


class _Deadline(Exception):
    """Raised inside a right-hand side once the caller's wall-time deadline has passed."""


def _check_deadline(deadline: float | None) -> None:
    if deadline is not None and time.perf_counter() > deadline:
        raise _Deadline


def _check_dimensions(trajectory: Trajectory, robot: RobotModel) -> None:
    nq, nv = robot.nq, robot.nv
    if trajectory.q.shape[1] != nq or trajectory.v.shape[1] != nv:
        raise ParameterError(
            f"trajectory has nq = {trajectory.q.shape[1]}, nv = {trajectory.v.shape[1]} but "
            f"robot {robot.name!r} has nq = {nq}, nv = {nv}",
            name="trajectory",
            value=trajectory.q.shape,
        )


def integration_method(
    method: str, trajectory: Trajectory, robot: RobotLike, *, damping: bool = True
) -> str:
    """Return the ``solve_ivp`` method to use: ``method``, or for ``"auto"`` DOP853 or Radau.

    ``"auto"`` picks the implicit Radau method when the damping is stiff on the
    plan's grid, ``damping_rate * max(h) > STIFF_RATIO`` (:data:`STIFF_RATIO`),
    and the explicit DOP853 otherwise (every robot without stiff damping keeps
    the explicit integrator and its figures).
    """
    if method != "auto":
        return method
    h = float(np.max(np.diff(trajectory.t)))
    rate = damping_rate(robot, trajectory.q, damping=damping).rate
    return "Radau" if rate * h > STIFF_RATIO else "DOP853"


# Chebyshev–Lobatto nodes of degree 3 on [0, 1], and two check points.
_NODES = 0.5 * (1.0 - np.cos(np.pi * np.arange(4) / 3.0))
_CHECK = np.array([0.1, 0.6])
_FIT_RTOL = 1e-9


def _powers(s: float) -> Array:
    return np.array([1.0, s, s * s, s * s * s])


class _IntervalPolynomials:
    """The plan's interpolants (q, v, tau) as cubic polynomials per interval.

    ``coef[k]`` has shape (4, nq + 2 nv): the coefficients of 1, s, s^2, s^3 of
    ``[q, v, tau]`` in the local normalised time ``s = (t - t[k]) / h[k]``.
    """

    def __init__(self, trajectory: Trajectory) -> None:
        self.t0 = trajectory.t[:-1]
        self.h = np.diff(trajectory.t)
        self.nq = trajectory.q.shape[1]
        self.nv = trajectory.v.shape[1]
        inv_vander = np.linalg.inv(np.vander(_NODES, 4, increasing=True))
        samples = self._sample(trajectory, _NODES)
        self.coef = np.einsum("ij,njc->nic", inv_vander, samples)
        check = self._sample(trajectory, _CHECK)
        fitted = np.stack([self.at(s) for s in _CHECK], axis=1)
        scale = 1.0 + np.max(np.abs(samples), axis=1, keepdims=True)
        if not np.all(np.abs(fitted - check) <= _FIT_RTOL * scale):
            raise ParameterError(
                f"the {trajectory.interpolation!r} interpolant is not a cubic polynomial in "
                "each interval; the simulation supports polynomial interpolants of degree <= 3",
                name="trajectory",
                value=trajectory.interpolation,
            )

    def _sample(self, trajectory: Trajectory, nodes: Array) -> Array:
        # each interval's own interpolant (at s = 1 too: Radau's torque jumps at knots)
        return trajectory.interval_values(nodes)

    def at(self, s: float) -> Array:
        """``[q, v, tau]`` of every interval at local time ``s``, shape (n, nq + 2 nv)."""
        return np.tensordot(_powers(s), self.coef, axes=(0, 1))

    def torques(self, s: float) -> Array:
        """Torques in [N m] of every interval at local time ``s``, shape (n, nv)."""
        return self.at(s)[:, self.nq + self.nv :]


@dataclass(frozen=True, slots=True, kw_only=True)
class PDGains:
    """PD tracking gains scaled by the joint-space inertia along the plan.

    In interval ``k`` the gain matrices are ``Kp = bandwidth**2 * M(qm)`` and
    ``Kd = 2 * damping_ratio * bandwidth * M(qm)``, with ``M(qm)`` the mass matrix
    (CRBA) at the plan's configuration in the middle of the interval, held
    constant over the interval. Then ``M^-1 Kp`` and ``M^-1 Kd`` are close to
    scalar, so the tracking error obeys approximately
    ``e'' + 2 zeta w e' + w**2 e = M^-1 * (torque the plan leaves unexplained)``
    on every joint alike. The controller is not computed-torque: no Coriolis,
    gravity or damping torque is added, so the feedback torque measures what the
    plan's own torque leaves unexplained. (Diagonal gains from the diagonal of M
    would be far stiffer than intended on the distal joints, whose effective
    inertia ``1 / (M^-1)_ii`` is much smaller than ``M_ii``: closed-loop poles
    near -1500 1/s for the youBot at 20 rad/s.)

    Attributes
    ----------
    bandwidth : float
        Closed-loop natural frequency ``w`` in [rad/s]. The default 20 rad/s is
        about three times the open-loop divergence rate of the youBot arm
        standing up (``sqrt(g / l)`` with ``l`` about 0.25 m).
    damping_ratio : float
        Damping ratio ``zeta`` of the closed loop (dimensionless), 1 = critical.
    """

    bandwidth: float = 20.0
    damping_ratio: float = 1.0

    def __post_init__(self) -> None:
        for name in ("bandwidth", "damping_ratio"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and np.isfinite(value) and value > 0.0):
                raise ParameterError(
                    f"{name} must be a positive finite number, got {value!r}",
                    name=name,
                    value=value,
                )

    def matrices(self, robot: RobotLike, q: Array) -> tuple[Array, Array]:
        """Gain matrices at configurations ``q``.

        Parameters
        ----------
        robot : RobotModel or pinocchio.Model
            The robot.
        q : ndarray, shape (M, nq)
            Configurations in [rad].

        Returns
        -------
        kp : ndarray, shape (M, nv, nv)
            Position gains in [N m/rad].
        kd : ndarray, shape (M, nv, nv)
            Velocity gains in [N m s/rad].
        """
        model = as_robot_model(robot).model
        data = model.createData()
        qs = np.atleast_2d(np.asarray(q, dtype=float))
        mass = np.array([pin.crba(model, data, qk) for qk in qs])
        # crba fills the upper triangle only.
        mass = np.triu(mass) + np.swapaxes(np.triu(mass, 1), 1, 2)
        w = self.bandwidth
        return w**2 * mass, 2.0 * self.damping_ratio * w * mass


class Simulation(NamedTuple):
    """A simulated motion sampled on a time grid.

    Attributes
    ----------
    t : ndarray, shape (M,)
        Sample times in [s] (the knots and ``samples_per_interval - 1`` points
        between consecutive knots, see :func:`sample_times`).
    q : ndarray, shape (M, nq)
        Simulated positions in [rad]; NaN after a stop.
    v : ndarray, shape (M, nv)
        Simulated velocities in [rad/s]; NaN after a stop.
    tau_plan : ndarray, shape (M, nv)
        The plan's torque interpolant in [N m].
    tau_feedback : ndarray, shape (M, nv)
        Feedback torque in [N m] (zero for an open-loop simulation).
    stop_time : float or None
        Time in [s] at which the simulation stopped early (``stop_deviation``
        reached or integrator failure), ``None`` if it reached the end.
    message : str
        Why it stopped early ("" if it did not).
    """

    t: Array
    q: Array
    v: Array
    tau_plan: Array
    tau_feedback: Array
    stop_time: float | None
    message: str


def sample_times(t: Array, samples_per_interval: int) -> Array:
    """Knots plus ``samples_per_interval - 1`` equally spaced times inside each interval.

    Parameters
    ----------
    t : ndarray, shape (N,)
        Knot times in [s].
    samples_per_interval : int
        Number of sub-intervals per knot interval (>= 1).

    Returns
    -------
    ndarray, shape ((N - 1) * samples_per_interval + 1,)
        Sample times in [s]; sample ``k * samples_per_interval`` is knot ``k``.

    Raises
    ------
    ParameterError
        If ``samples_per_interval`` is not an integer >= 1.
    """
    if int(samples_per_interval) != samples_per_interval or samples_per_interval < 1:
        raise ParameterError(
            f"samples_per_interval must be an integer >= 1, got {samples_per_interval!r}",
            name="samples_per_interval",
            value=samples_per_interval,
        )
    m = int(samples_per_interval)
    t = np.asarray(t, dtype=float)
    frac = np.arange(m) / m
    inner = (t[:-1, None] + frac[None, :] * np.diff(t)[:, None]).ravel()
    return np.append(inner, t[-1])


def integrate_intervals(
    trajectory: Trajectory,
    robot: RobotLike,
    *,
    damping: bool = True,
    rtol: float = DEFAULT_RTOL,
    atol: float = DEFAULT_ATOL,
    method: str = "auto",
    deadline: float | None = None,
) -> tuple[Array, Array]:
    """Integrate every interval from its left knot's state under the plan's torque.

    Interval ``k`` starts at ``(q[k], v[k])`` at time ``t[k]`` and runs to
    ``t[k + 1]`` under ``trajectory.torque(t)``. The intervals are stacked into one
    ODE in normalised time ``s in [0, 1]`` (``t = t[k] + s h[k]``), so the
    integrator's error norm is taken over all intervals together.

    Parameters
    ----------
    trajectory : Trajectory
        The plan, with N knots.
    robot : RobotModel or pinocchio.Model
        The robot the plan is for (``nq == nv``).
    damping : bool, optional
        Apply the robot's joint damping ``b`` [N m s/rad] (``tau - b v``).
    rtol : float, optional
        Relative tolerance of ``solve_ivp``.
    atol : float, optional
        Absolute tolerance of ``solve_ivp`` in [rad] and [rad/s].
    method : str, optional
        ``solve_ivp`` method; ``"auto"`` (default) is DOP853, or Radau with the
        block-diagonal Jacobian pattern when the damping is stiff on the grid
        (:func:`integration_method`).
    deadline : float, optional
        A ``time.perf_counter()`` value [s] after which the integration stops
        (then the result is NaN, as for a failure).

    Returns
    -------
    q_end : ndarray, shape (N - 1, nq)
        Simulated positions in [rad] at ``t[1:]`` (NaN if the integrator failed).
    v_end : ndarray, shape (N - 1, nv)
        Simulated velocities in [rad/s] at ``t[1:]`` (NaN if the integrator failed).

    Raises
    ------
    ParameterError
        If the trajectory and the robot disagree in size or the robot is unsupported.
    """
    from scipy import sparse  # SciPy: only when the certificate integrates
    from scipy.integrate import solve_ivp

    robot = as_numeric_robot(robot)
    _check_dimensions(trajectory, robot)
    batch = batched_aba(robot, damping=damping)
    polys = _IntervalPolynomials(trajectory)
    nv = robot.nv
    h = polys.h
    n = h.size

    def rhs(s: float, x: Array) -> Array:
        _check_deadline(deadline)
        state = x.reshape(n, 2 * nv)
        q, v = state[:, :nv], state[:, nv:]
        acc = batch(q, v, polys.torques(s))
        return (np.hstack([v, acc]) * h[:, None]).ravel()

    x0 = np.hstack([trajectory.q[:-1], trajectory.v[:-1]]).ravel()
    method = integration_method(method, trajectory, robot, damping=damping)
    extra = {}
    if method in ("Radau", "BDF"):  # intervals are independent: a block-diagonal Jacobian
        extra["jac_sparsity"] = sparse.block_diag([np.ones((2 * nv, 2 * nv))] * n, format="csc")
    try:
        sol = solve_ivp(rhs, (0.0, 1.0), x0, method=method, rtol=rtol, atol=atol, **extra)
    except _Deadline:
        _LOG.warning("local integration stopped: time limit reached")
        nan = np.full((n, nv), np.nan)
        return nan, nan.copy()
    if not sol.success:
        _LOG.warning("local integration failed: %s", sol.message)
        nan = np.full((n, nv), np.nan)
        return nan, nan.copy()
    end = sol.y[:, -1].reshape(n, 2 * nv)
    _LOG.debug("local integration (%s): %d intervals, %d RHS evaluations", method, n, sol.nfev)
    return end[:, :nv], end[:, nv:]


def simulate(
    trajectory: Trajectory,
    robot: RobotLike,
    *,
    damping: bool = True,
    gains: PDGains | None = None,
    samples_per_interval: int = 20,
    stop_deviation: float | None = None,
    rtol: float = DEFAULT_RTOL,
    atol: float = DEFAULT_ATOL,
    method: str = "auto",
    deadline: float | None = None,
) -> Simulation:
    """Simulate the whole motion from the first knot, open loop or with PD tracking.

    The torque applied is ``trajectory.torque(t)`` plus, when ``gains`` is given,
    ``Kp (trajectory(t) - q) + Kd (trajectory.velocity(t) - v)`` (see
    :class:`PDGains`). The integration restarts at every knot (the interpolants
    have kinks there), the state being carried over.

    Parameters
    ----------
    trajectory : Trajectory
        The plan, with N knots.
    robot : RobotModel or pinocchio.Model
        The robot (``nq == nv``).
    damping : bool, optional
        Apply the robot's joint damping ``b`` [N m s/rad] (``tau - b v``).
    gains : PDGains, optional
        Feedback gains; ``None`` simulates open loop.
    samples_per_interval : int, optional
        Output samples per knot interval (see :func:`sample_times`).
    stop_deviation : float, optional
        Stop once ``max_i |q_i - q_plan_i(t)|`` reaches this value in [rad];
        ``None`` never stops early.
    rtol, atol : float, optional
        Integrator tolerances (``atol`` in [rad] and [rad/s]).
    method : str, optional
        ``solve_ivp`` method; ``"auto"`` (default): DOP853, or Radau when the
        damping is stiff on the grid (:func:`integration_method`).
    deadline : float, optional
        A ``time.perf_counter()`` value [s] after which the simulation stops
        (``stop_time`` and ``message`` say where), as for an integrator failure.

    Returns
    -------
    Simulation
        The simulated states and torques at :func:`sample_times`.

    Raises
    ------
    ParameterError
        If sizes disagree, the robot or interpolant is unsupported, or
        ``stop_deviation`` is not positive.
    """
    from scipy.integrate import solve_ivp  # SciPy: only when the certificate integrates

    robot = as_numeric_robot(robot)
    _check_dimensions(trajectory, robot)
    if stop_deviation is not None and not stop_deviation > 0.0:
        raise ParameterError(
            f"stop_deviation must be > 0 [rad] or None, got {stop_deviation!r}",
            name="stop_deviation",
            value=stop_deviation,
        )
    model, data = robot.model, robot.model.createData()
    nv = model.nv
    method = integration_method(method, trajectory, robot, damping=damping)
    polys = _IntervalPolynomials(trajectory)
    m = int(samples_per_interval)
    times = sample_times(trajectory.t, m)
    n = trajectory.n_knots - 1
    if gains is None:
        kp = kd = np.zeros((n, nv, nv))
    else:
        kp, kd = gains.matrices(robot, trajectory(polys.t0 + 0.5 * polys.h))
    gain = np.concatenate([kp, kd], axis=2)  # (n, nv, 2 nv) acting on [q, v]
    # Net joint torque tau_plan + K (x_plan - x) - b v = (closed-loop cubic in s) - K' x.
    net_coef = polys.coef[:, :, 2 * nv :] + np.einsum(
        "kij,ksj->ksi", gain, polys.coef[:, :, : 2 * nv]
    )
    gain_state = gain.copy()
    gain_state[:, :, nv:] += np.diag(acting_damping(robot, damping))
    q_coef = polys.coef[:, :, :nv]
    states = np.full((times.size, 2 * nv), np.nan)
    states[0] = np.concatenate([trajectory.q[0], trajectory.v[0]])
    stop_time: float | None = None
    message = ""

    for k in range(n):
        t0, h = polys.t0[k], polys.h[k]

        def rhs(t: float, x: Array, k: int = k, t0: float = t0, h: float = h) -> Array:
            _check_deadline(deadline)
            tau = _powers((t - t0) / h) @ net_coef[k] - gain_state[k] @ x
            return np.concatenate([x[nv:], pin.aba(model, data, x[:nv], x[nv:], tau)])

        events = None
        if stop_deviation is not None:

            def deviation(t: float, x: Array, k: int = k, t0: float = t0, h: float = h) -> float:
                q_plan = _powers((t - t0) / h) @ q_coef[k]
                return float(np.max(np.abs(x[:nv] - q_plan)) - stop_deviation)

            deviation.terminal = True  # type: ignore[attr-defined]
            deviation.direction = 1.0  # type: ignore[attr-defined]
            events = deviation
        t_eval = times[k * m + 1 : (k + 1) * m + 1]
        span = (trajectory.t[k], trajectory.t[k + 1])
        try:
            sol = solve_ivp(
                rhs, span, states[k * m], method=method, rtol=rtol, atol=atol, t_eval=t_eval,
                events=events,
            )  # fmt: skip
        except _Deadline:
            stop_time = float(span[0])
            message = f"time limit reached in interval {k}"
            _LOG.warning("simulation stopped: %s", message)
            break
        y = np.asarray(sol.y, dtype=float).reshape(2 * nv, -1)  # [] if stopped before t_eval
        got = y.shape[1]
        states[k * m + 1 : k * m + 1 + got] = y.T
        if sol.status == 1:
            stop_time = float(sol.t_events[0][0])
            message = f"deviation from the plan reached {stop_deviation:g} rad"
            break
        if not sol.success or got != m:
            stop_time = float(sol.t[-1]) if sol.t.size else float(span[0])
            message = f"integrator failed in interval {k}: {sol.message}"
            _LOG.warning("simulation stopped: %s", message)
            break
    q, v = states[:, :nv], states[:, nv:]
    tau_plan = trajectory.torque(times)
    # Sample j belongs to interval (j - 1) // m (sample 0 to interval 0).
    interval = np.maximum(np.arange(times.size) - 1, 0) // m
    error = np.hstack([trajectory(times) - q, trajectory.velocity(times) - v])
    tau_fb = np.einsum("jab,jb->ja", gain[interval], error)
    return Simulation(
        t=times, q=q, v=v, tau_plan=tau_plan, tau_feedback=tau_fb, stop_time=stop_time,
        message=message,
    )  # fmt: skip
