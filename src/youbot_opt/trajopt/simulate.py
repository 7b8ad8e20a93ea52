"""Forward simulation of a planned trajectory with Pinocchio's numeric ABA.

Owns the code path :mod:`youbot_opt.trajopt.certify` and
:mod:`youbot_opt.trajopt.check` verify plans with, independent of the
collocation equations (spec ``trajopt.md``, "prove each trajectory by forward
simulation"): :func:`integrate_intervals` (one interval from every knot) and
:func:`simulate` / :func:`simulate_batch` (the whole motion, open loop or with
:class:`PDGains`), integrated by :class:`~youbot_opt.dynamics.dop853.Dop853`, or
:class:`~youbot_opt.dynamics.radau5.Radau5` where the damping is stiff
(:func:`integration_method`), with Pinocchio's ABA. Robots with ``nq == nv``.

>>> sim = simulate(result.trajectory, robot, gains=PDGains())  # doctest: +SKIP
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from youbot_opt._typing import Array
from youbot_opt.dynamics.dop853 import Dop853
from youbot_opt.dynamics.numeric import (
    STIFF_RATIO,
    RobotLike,
    acting_damping,
    as_numeric_robot,
    batched_aba,
    damping_rate,
)
from youbot_opt.dynamics.radau5 import Radau5
from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.model import RobotModel, as_robot_model
from youbot_opt.trajopt.trajectory import Trajectory

__all__ = [
    "PDGains",
    "Simulation",
    "integrate_intervals",
    "integration_method",
    "simulate",
    "simulate_batch",
    "sample_times",
]

_LOG = logging.getLogger(__name__)

DEFAULT_RTOL = 1e-10
"""Default relative tolerance of the integrator (DOP853)."""
DEFAULT_ATOL = 1e-12
"""Default absolute tolerance of the integrator, in [rad] and [rad/s]."""


_OWN_METHODS = ("DOP853", "Radau")
"""Methods integrated by our own steppers (:class:`Dop853`, :class:`Radau5`); any
other ``solve_ivp`` method name goes to SciPy, restarted at every knot."""


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
        Relative tolerance of the integrator.
    atol : float, optional
        Absolute tolerance of the integrator in [rad] and [rad/s].
    method : str, optional
        ``"DOP853"`` (:class:`~youbot_opt.dynamics.dop853.Dop853`, SciPy's
        algorithm without SciPy), ``"Radau"``
        (:class:`~youbot_opt.dynamics.radau5.Radau5`, likewise, with the
        analytic block-diagonal Jacobian), another ``solve_ivp`` method (SciPy),
        or ``"auto"`` (default): DOP853, or Radau when the damping is stiff on
        the grid (:func:`integration_method`).
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
    robot = as_numeric_robot(robot)
    _check_dimensions(trajectory, robot)
    batch = batched_aba(robot, damping=damping)
    polys = _IntervalPolynomials(trajectory)
    nv = robot.nv
    h = polys.h
    n = h.size
    # the torque coefficients as one (4, n nv) block: powers(s) @ block = all torques at s
    tau_block = polys.coef[:, :, polys.nq + nv :].transpose(1, 0, 2).reshape(4, n * nv)
    rate = np.repeat(h, 2 * nv).reshape(n, 2 * nv)  # d/ds = h d/dt

    def rhs(s: float, x: Array) -> Array:
        state = x.reshape(n, 2 * nv)
        out = np.empty((n, 2 * nv))
        out[:, :nv] = state[:, nv:]
        out[:, nv:] = batch(state[:, :nv], state[:, nv:], (_powers(s) @ tau_block).reshape(n, nv))
        out *= rate
        return out.reshape(x.shape)

    x0 = np.hstack([trajectory.q[:-1], trajectory.v[:-1]]).reshape(1, -1)
    method = integration_method(method, trajectory, robot, damping=damping)
    nan = np.full((n, nv), np.nan)
    if method in _OWN_METHODS:
        if _passed(deadline):
            _LOG.warning("local integration stopped: time limit reached")
            return nan, nan.copy()
        stepper: Dop853 | Radau5
        if method == "Radau":
            jac = _IntervalJacobian(robot, tau_block, h, damping)
            stepper = Radau5(rhs, jac, 0.0, x0, rtol=rtol, atol=atol, t_bound=1.0)
        else:
            stepper = Dop853(rhs, 0.0, x0, rtol=rtol, atol=atol, t_bound=1.0)
        while stepper.t < 1.0:
            if _passed(deadline):
                _LOG.warning("local integration stopped: time limit reached")
                return nan, nan.copy()
            if not stepper.step(1.0):
                _LOG.warning("local integration failed: %s", stepper.message)
                return nan, nan.copy()
        end, nfev = stepper.y.reshape(n, 2 * nv), stepper.nfev
    else:
        from scipy import sparse  # SciPy: only for its implicit methods (stiff damping)
        from scipy.integrate import solve_ivp

        def rhs_flat(s: float, x: Array) -> Array:
            _check_deadline(deadline)
            return rhs(s, x).ravel()

        extra = {}
        if method in ("Radau", "BDF"):  # intervals are independent: a block-diagonal Jacobian
            extra["jac_sparsity"] = sparse.block_diag([np.ones((2 * nv, 2 * nv))] * n, format="csc")
        try:
            sol = solve_ivp(
                rhs_flat, (0.0, 1.0), x0.ravel(), method=method, rtol=rtol, atol=atol, **extra
            )
        except _Deadline:
            _LOG.warning("local integration stopped: time limit reached")
            return nan, nan.copy()
        if not sol.success:
            _LOG.warning("local integration failed: %s", sol.message)
            return nan, nan.copy()
        end, nfev = sol.y[:, -1].reshape(n, 2 * nv), sol.nfev
    _LOG.debug("local integration (%s): %d intervals, %d RHS evaluations", method, n, nfev)
    return end[:, :nv], end[:, nv:]


def _passed(deadline: float | None) -> bool:
    return deadline is not None and time.perf_counter() > deadline


def _state_jacobian(da_dq: Array, da_dv: Array, minv: Array, dtau_dx: Array) -> Array:
    """``d[v, a]/d[q, v]`` (2 nv, 2 nv) of ``a = ABA(q, v, tau(q, v))``, ``tau`` affine in x."""
    nv = da_dq.shape[0]
    out = np.zeros((2 * nv, 2 * nv))
    out[:nv, nv:] = np.eye(nv)
    out[nv:, :nv] = da_dq
    out[nv:, nv:] = da_dv
    out[nv:] += minv @ dtau_dx
    return out


class _IntervalJacobian:
    """The analytic Jacobian blocks of :func:`integrate_intervals`' stacked ODE.

    Interval k's block is ``h[k] d[v, a]/d[q, v]`` with Pinocchio's ABA
    derivatives (``computeABADerivatives``: da/dq, da/dv and M^-1) and the
    damping torque ``-b v`` (``dtau/dv = -b``): one derivative call per interval,
    where finite differences would need 2 nv batched ABA calls.
    """

    def __init__(self, robot: RobotModel, tau_block: Array, h: Array, damping: bool) -> None:
        self.model, self.data = robot.model, robot.model.createData()
        self.nv = nv = robot.nv
        self.b = acting_damping(robot, damping)
        self.tau_block, self.h = tau_block, h
        self.dtau_dx = np.zeros((nv, 2 * nv))
        self.dtau_dx[:, nv:] = -np.diag(self.b)

    def __call__(self, s: float, x: Array) -> Array:
        nv, n = self.nv, self.h.size
        state = x.reshape(n, 2 * nv)
        tau = (_powers(s) @ self.tau_block).reshape(n, nv) - self.b * state[:, nv:]
        blocks = np.empty((n, 2 * nv, 2 * nv))
        for k in range(n):
            da_dq, da_dv, minv = pin.computeABADerivatives(
                self.model, self.data, state[k, :nv], state[k, nv:], tau[k]
            )
            blocks[k] = self.h[k] * _state_jacobian(da_dq, da_dv, minv, self.dtau_dx)
        return blocks


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
    :class:`PDGains`). No integrator step crosses a knot (the interpolants have
    kinks there): each interval is integrated from the state reached at its
    left knot (:func:`simulate_batch` with one simulation).

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
        ``"DOP853"`` (:class:`~youbot_opt.dynamics.dop853.Dop853`), ``"Radau"``
        (:class:`~youbot_opt.dynamics.radau5.Radau5`, with the analytic
        Jacobian), another ``solve_ivp`` method (SciPy, restarted at every
        knot), or ``"auto"`` (default): DOP853, or Radau when the damping is
        stiff on the grid (:func:`integration_method`).
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
    return simulate_batch(
        trajectory, robot, damping=damping, gains=(gains,), stop_deviation=(stop_deviation,),
        samples_per_interval=samples_per_interval, rtol=rtol, atol=atol, method=method,
        deadline=deadline,
    )[0]  # fmt: skip


def simulate_batch(
    trajectory: Trajectory,
    robot: RobotLike,
    *,
    gains: Sequence[PDGains | None],
    stop_deviation: Sequence[float | None],
    damping: bool = True,
    samples_per_interval: int = 20,
    rtol: float = DEFAULT_RTOL,
    atol: float = DEFAULT_ATOL,
    method: str = "auto",
    deadline: float | None = None,
) -> tuple[Simulation, ...]:
    """Simulate the motion several times at once: one simulation per entry of ``gains``.

    Simulation ``i`` is :func:`simulate` with ``gains[i]`` and
    ``stop_deviation[i]``. With DOP853 or Radau the simulations are one stacked ODE
    (one integrator for all, common steps, each simulation's error held to
    the tolerances: the integrator's overhead is paid once); a simulation that
    stops leaves the stack, and if the stack's step fails, each simulation
    goes on alone (each fails alone). Other methods run the simulations one
    after another.

    Parameters
    ----------
    trajectory : Trajectory
        The plan, with N knots.
    robot : RobotModel or pinocchio.Model
        The robot (``nq == nv``).
    gains : sequence of PDGains or None
        Feedback gains of each simulation (``None``: open loop).
    stop_deviation : sequence of float or None
        Each simulation's stop deviation in [rad] (see :func:`simulate`).
    damping, samples_per_interval, rtol, atol, method, deadline
        As :func:`simulate`, for every simulation.

    Returns
    -------
    tuple of Simulation
        One per entry of ``gains``, in order.

    Raises
    ------
    ParameterError
        As :func:`simulate`, or if ``gains`` and ``stop_deviation`` are empty or
        differ in length.
    """
    robot = as_numeric_robot(robot)
    _check_dimensions(trajectory, robot)
    gains, stops = tuple(gains), tuple(stop_deviation)
    if not gains or len(gains) != len(stops):
        raise ParameterError(
            f"gains and stop_deviation must have one entry per simulation, got "
            f"{len(gains)} and {len(stops)}",
            name="stop_deviation",
            value=stops,
        )
    for stop in stops:
        if stop is not None and not stop > 0.0:
            raise ParameterError(
                f"stop_deviation must be > 0 [rad] or None, got {stop!r}",
                name="stop_deviation",
                value=stop,
            )
    method = integration_method(method, trajectory, robot, damping=damping)
    polys = _IntervalPolynomials(trajectory)
    times = sample_times(trajectory.t, samples_per_interval)
    loops = [_ClosedLoop(trajectory, robot, polys, g, damping) for g in gains]
    if method in _OWN_METHODS:
        march = _March(
            trajectory, robot, polys, loops, stops, times, int(samples_per_interval),
            rtol=rtol, atol=atol, deadline=deadline, stiff=method == "Radau",
        )  # fmt: skip
        march.run()
        results = [
            (march.states[i], march.stop_time[i], march.message[i]) for i in range(len(loops))
        ]
    else:
        results = [
            _simulate_scipy(
                trajectory, robot, polys, loop, stop, times, int(samples_per_interval),
                method=method, rtol=rtol, atol=atol, deadline=deadline,
            )
            for loop, stop in zip(loops, stops, strict=True)
        ]  # fmt: skip
    nv = robot.nv
    tau_plan = trajectory.torque(times)
    # Sample j belongs to interval (j - 1) // m (sample 0 to interval 0).
    interval = np.maximum(np.arange(times.size) - 1, 0) // int(samples_per_interval)
    plan = np.hstack([trajectory(times), trajectory.velocity(times)])
    out = []
    for i, (loop, (states, stop_time, message)) in enumerate(zip(loops, results, strict=True)):
        tau_fb = np.einsum("jab,jb->ja", loop.gain[interval], plan - states)
        out.append(
            Simulation(
                t=times if i == 0 else times.copy(),
                q=states[:, :nv],
                v=states[:, nv:],
                tau_plan=tau_plan if i == 0 else tau_plan.copy(),
                tau_feedback=tau_fb,
                stop_time=stop_time,
                message=message,
            )
        )
    return tuple(out)


class _ClosedLoop:
    """One simulation's torque law per interval: ``tau = poly(s) @ net[k] - state_gain[k] @ x``.

    ``gain[k]`` (nv, 2 nv) is the PD feedback on ``[q, v]`` (zero open loop);
    the net joint torque ``tau_plan + K (x_plan - x) - b v`` is the closed-loop
    cubic ``net[k]`` (4, nv) in the local time s minus ``state_gain[k] @ x``
    (``K`` plus the damping on ``v``).
    """

    def __init__(
        self,
        trajectory: Trajectory,
        robot: RobotModel,
        polys: _IntervalPolynomials,
        gains: PDGains | None,
        damping: bool,
    ) -> None:
        nv, n = robot.nv, trajectory.n_knots - 1
        if gains is None:
            kp = kd = np.zeros((n, nv, nv))
        else:
            kp, kd = gains.matrices(robot, trajectory(polys.t0 + 0.5 * polys.h))
        self.gain = np.concatenate([kp, kd], axis=2)  # (n, nv, 2 nv) acting on [q, v]
        self.net = polys.coef[:, :, 2 * nv :] + np.einsum(
            "kij,ksj->ksi", self.gain, polys.coef[:, :, : 2 * nv]
        )
        self.state_gain = self.gain.copy()
        self.state_gain[:, :, nv:] += np.diag(acting_damping(robot, damping))


class _March:
    """The simulations of :func:`simulate_batch` as one stacked ODE, knot to knot.

    Rows of the stack are the simulations still running (``active``). Steps end
    on every knot (the torque law changes there), the step size carried over
    (and for Radau the Jacobian and its factorisations); samples inside a step
    come from the dense output. ``stiff``: :class:`Radau5` with the analytic
    Jacobian (:meth:`_jac`), else :class:`Dop853`.
    """

    def __init__(
        self,
        trajectory: Trajectory,
        robot: RobotModel,
        polys: _IntervalPolynomials,
        loops: list[_ClosedLoop],
        stops: tuple[float | None, ...],
        times: Array,
        m: int,
        *,
        rtol: float,
        atol: float,
        deadline: float | None,
        stiff: bool = False,
    ) -> None:
        self.t = trajectory.t
        self.stiff = stiff
        self.polys, self.m, self.times = polys, m, times
        self.stops = stops
        self.rtol, self.atol, self.deadline = rtol, atol, deadline
        self.nv = nv = robot.nv
        self.model, self.data = robot.model, robot.model.createData()  # damping: in state_gain
        # torque = [1, s, s^2, s^3, q, v] @ law[k, run]: the cubic, then minus the state gain
        self.law = np.stack(
            [np.concatenate([lp.net, -lp.state_gain.transpose(0, 2, 1)], axis=1) for lp in loops],
            axis=1,
        )  # (n, runs, 4 + 2 nv, nv)
        self.q_coef = polys.coef[:, :, :nv]
        runs = len(loops)
        self.states = [np.full((times.size, 2 * nv), np.nan) for _ in range(runs)]
        x0 = np.concatenate([trajectory.q[0], trajectory.v[0]])
        for states in self.states:
            states[0] = x0
        self.stop_time: list[float | None] = [None] * runs
        self.message = [""] * runs
        # the interval being integrated: set by _select
        self._t0 = self._h = 0.0
        self._law = self.law[0]
        self._z = np.ones((runs, self.law.shape[2]))  # [1, s, s^2, s^3, q, v] of each row

    # ------------------------------------------------------------ the ODE
    def _select(self, k: int, rows: list[int]) -> None:
        self._t0, self._h = float(self.polys.t0[k]), float(self.polys.h[k])
        self._law = self.law[k, rows]
        self._z = np.ones((len(rows), self.law.shape[2]))

    def _torques(self, t: float, x: Array) -> list[Array]:
        """Return the torque law's torques in [N m] at time ``t`` [s], one a row of ``x``."""
        law, z = self._law, self._z
        s = (t - self._t0) / self._h
        z[:, 1] = s
        z[:, 2] = s * s
        z[:, 3] = s * s * s
        z[:, 4:] = x
        return [z[i] @ law[i] for i in range(x.shape[0])]

    def _rhs(self, t: float, x: Array) -> Array:
        nv, model, data = self.nv, self.model, self.data
        out = np.empty_like(x)
        out[:, :nv] = x[:, nv:]
        # one pin.aba a row: faster than a batch of one or two
        for i, tau in enumerate(self._torques(t, x)):
            out[i, nv:] = pin.aba(model, data, x[i, :nv], x[i, nv:], tau)
        return out

    def _jac(self, t: float, x: Array) -> Array:
        """Jacobian blocks of :meth:`_rhs`, one a row: ABA derivatives and the torque law."""
        nv, model, data, law = self.nv, self.model, self.data, self._law
        blocks = np.empty((x.shape[0], 2 * nv, 2 * nv))
        for i, tau in enumerate(self._torques(t, x)):
            da_dq, da_dv, minv = pin.computeABADerivatives(model, data, x[i, :nv], x[i, nv:], tau)
            blocks[i] = _state_jacobian(da_dq, da_dv, minv, law[i, 4:].T)  # dtau/dx = law's
        return blocks

    def _stepper(
        self, t: float, x: Array, t_bound: float, h_abs: float | None, f0: Array | None = None
    ) -> Dop853 | Radau5:
        """Return a new stepper for the rows selected (:meth:`_select`)."""
        if self.stiff:
            return Radau5(
                self._rhs, self._jac, t, x, rtol=self.rtol, atol=self.atol, t_bound=t_bound,
                first_step=h_abs, f0=f0,
            )  # fmt: skip
        return Dop853(
            self._rhs, t, x, rtol=self.rtol, atol=self.atol, t_bound=t_bound, first_step=h_abs,
            f0=f0,
        )  # fmt: skip

    def _deviation(self, k: int, t: float, q: Array) -> float:
        """``max_i |q_i - q_plan_i(t)|`` in [rad] in interval ``k``."""
        q_plan = _powers((t - self.polys.t0[k]) / self.polys.h[k]) @ self.q_coef[k]
        return float(np.max(np.abs(q - q_plan)))

    # ------------------------------------------------------------ the march
    def run(self) -> None:
        """Integrate every simulation to the end, or to its stop."""
        x0 = np.stack([s[0] for s in self.states])
        self._march(list(range(len(self.states))), 0, float(self.t[0]), x0, None, 0)

    def _march(
        self, rows: list[int], k_start: int, t: float, x: Array, h_abs: float | None, done: int
    ) -> None:
        """Integrate ``rows`` from state ``x`` at time ``t`` in interval ``k_start`` on.

        ``h_abs`` is the first step size (None: chosen); samples up to ``done``
        are filled.
        """
        m, nv, knots = self.m, self.nv, self.t
        stepper: Dop853 | Radau5 | None = None
        for k in range(k_start, knots.size - 1):
            if _passed(self.deadline):
                for r in rows:
                    self.states[r][k * m + 1 :] = np.nan
                    self._stop(r, float(knots[k]), f"time limit reached in interval {k}")
                return
            self._select(k, rows)
            t_end = float(knots[k + 1])
            if stepper is None:
                stepper = self._stepper(t, x, t_end, h_abs)
            else:
                stepper.refresh()  # the torque law of interval k
                done = k * m
            g_old = [self._gap(r, k, stepper.t, stepper.y[i, :nv]) for i, r in enumerate(rows)]
            while stepper.t < t_end:
                if _passed(self.deadline):
                    for r in rows:
                        self.states[r][k * m + 1 :] = np.nan
                        self._stop(r, float(knots[k]), f"time limit reached in interval {k}")
                    return
                if not stepper.step(t_end):
                    if len(rows) > 1:  # each simulation alone: it fails alone, or goes on
                        h = stepper.h_abs if math.isfinite(stepper.h_abs) else None
                        for i, r in enumerate(rows):
                            self._march([r], k, stepper.t, stepper.y[i : i + 1].copy(), h, done)
                        return
                    r = rows[0]
                    reached = self.times[done] if done > k * m else knots[k]
                    self._stop(
                        r, float(reached), f"integrator failed in interval {k}: {stepper.message}"
                    )
                    return
                upto = k * m + int(np.searchsorted(self.times[k * m + 1 : (k + 1) * m + 1],
                                                   stepper.t, side="right"))  # fmt: skip
                stopped = self._events(rows, k, stepper, g_old)
                self._sample(rows, stepper, done, upto, stopped)
                done = upto
                if stopped:
                    rows_left = [r for r in rows if r not in stopped]
                    if not rows_left:
                        return
                    keep = [i for i, r in enumerate(rows) if r not in stopped]
                    self._select(k, rows_left)
                    stepper = self._stepper(
                        stepper.t, stepper.y[keep], t_end, stepper.h_abs, stepper.f[keep]
                    )
                    g_old = [g for i, g in enumerate(g_old) if i in keep]
                    rows = rows_left

    def _gap(self, r: int, k: int, t: float, q: Array) -> float:
        """Return simulation ``r``'s stop event: deviation minus stop (< 0 before), or -inf."""
        stop = self.stops[r]
        return -math.inf if stop is None else self._deviation(k, t, q) - stop

    def _events(
        self, rows: list[int], k: int, stepper: Dop853 | Radau5, g_old: list[float]
    ) -> dict[int, float]:
        """Return the simulations that reached their stop in the last step: row -> time [s]."""
        nv = self.nv
        stopped: dict[int, float] = {}
        for i, r in enumerate(rows):
            if self.stops[r] is None:
                continue
            g_new = self._gap(r, k, stepper.t, stepper.y[i, :nv])
            if g_old[i] <= 0.0 <= g_new:
                root = self._root(r, i, k, stepper)
                stopped[r] = root
                self._stop(r, root, f"deviation from the plan reached {self.stops[r]:g} rad")
            g_old[i] = g_new
        return stopped

    def _root(self, r: int, i: int, k: int, stepper: Dop853 | Radau5) -> float:
        """Return the time [s] in the last step at which simulation ``r`` (row ``i``) stopped.

        Bisection on the dense output to SciPy's event tolerance (4 eps,
        absolute and relative): ``gap(lo) <= 0 <= gap(hi)``.
        """
        lo, hi = stepper.t_old, stepper.t
        nv = self.nv
        while hi - lo > _ROOT_TOL * (1.0 + abs(hi)):
            mid = 0.5 * (lo + hi)
            if mid <= lo or mid >= hi:
                break
            q = stepper.dense(np.array([mid]))[0, i, :nv]
            if self._gap(r, k, mid, q) < 0.0:
                lo = mid
            else:
                hi = mid
        return 0.5 * (lo + hi)

    def _sample(
        self,
        rows: list[int],
        stepper: Dop853 | Radau5,
        done: int,
        upto: int,
        stopped: dict[int, float],
    ) -> None:
        """Fill samples ``done + 1 .. upto`` (those in the last step) of each row.

        A simulation stopped in the step gets the samples up to its stop time only.
        """
        if upto <= done:
            return
        times = self.times[done + 1 : upto + 1]
        inside = times < stepper.t
        values = np.empty((times.size, len(rows), 2 * self.nv))
        if np.any(inside):
            values[inside] = stepper.dense(times[inside])
        values[~inside] = stepper.y
        for i, r in enumerate(rows):
            keep = times <= stopped.get(r, math.inf)
            self.states[r][done + 1 : upto + 1][keep] = values[keep, i]

    def _stop(self, r: int, time: float, message: str) -> None:
        self.stop_time[r] = time
        self.message[r] = message
        if message.startswith(("time limit", "integrator failed")):
            _LOG.warning("simulation stopped: %s", message)


_ROOT_TOL = 4.0 * np.finfo(float).eps  # SciPy's event tolerance


def _simulate_scipy(
    trajectory: Trajectory,
    robot: RobotModel,
    polys: _IntervalPolynomials,
    loop: _ClosedLoop,
    stop_deviation: float | None,
    times: Array,
    m: int,
    *,
    method: str,
    rtol: float,
    atol: float,
    deadline: float | None,
) -> tuple[Array, float | None, str]:
    """One simulation with ``solve_ivp`` restarted at every knot: states, stop time, message."""
    from scipy.integrate import solve_ivp  # SciPy: only for its implicit methods (stiff damping)

    model, data = robot.model, robot.model.createData()
    nv = model.nv
    n = trajectory.n_knots - 1
    net_coef, gain_state, q_coef = loop.net, loop.state_gain, polys.coef[:, :, :nv]
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
            stop_time = float(sol.t[-1]) if len(sol.t) else float(span[0])  # t: [] if none
            message = f"integrator failed in interval {k}: {sol.message}"
            _LOG.warning("simulation stopped: %s", message)
            break
    return states, stop_time, message
