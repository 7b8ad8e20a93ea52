"""A plan sampled at a controller's rate: :class:`SampledTrajectory`, :func:`sample_trajectory`.

The samples are the plan's own interpolants (:class:`~youbot_opt.trajopt.trajectory.Trajectory`:
trapezoidal, Hermite-Simpson or Radau) evaluated on a uniform clock from 0 with
step ``1 / rate_hz``, the plan's end appended when the duration is not a whole
number of steps; never another spline. Accelerations are the time derivative
of the velocity interpolant (:meth:`Trajectory.acceleration`). The writers are
in :mod:`youbot_opt.trajopt.export.files` and :mod:`youbot_opt.trajopt.export.ros2`.

>>> samples = result.sample(500.0)  # doctest: +SKIP
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.model import JointUnits, RobotModel
from youbot_opt.trajopt.trajectory import Trajectory

__all__ = [
    "SampledTrajectory",
    "acceleration_unit",
    "coordinate_names",
    "sample_times",
    "sample_trajectory",
]

_FIELDS = ("q", "v", "a", "tau")


def acceleration_unit(units: JointUnits) -> str:
    """Return the acceleration unit of a joint coordinate: ``"rad/s^2"`` or ``"m/s^2"``."""
    return f"{units.velocity}^2"


def coordinate_names(robot: RobotModel) -> tuple[str, ...]:
    """Return one name per velocity coordinate: the joint's name, ``name_i`` for a multi-DoF joint.

    Parameters
    ----------
    robot : RobotModel
        The robot (names as in its URDF).

    Returns
    -------
    tuple of str
        ``nv`` names, in velocity order.
    """
    names: list[str] = []
    for joint, name in zip(robot.model.joints[1:], robot.model.names[1:], strict=True):
        n = int(joint.nv)
        names += [str(name)] if n == 1 else [f"{name}_{i}" for i in range(n)]
    return tuple(names)


def _matrix(name: str, value: object, rows: int, cols: int) -> Array:
    arr = np.array(value, dtype=float)
    if arr.shape != (rows, cols):
        raise ParameterError(
            f"{name} must have shape ({rows}, {cols}), got {arr.shape}", name=name, value=arr.shape
        )
    if not np.all(np.isfinite(arr)):
        raise ParameterError(f"{name} contains non-finite values", name=name)
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, slots=True, kw_only=True)
class SampledTrajectory:
    """A plan at a controller's rate: what a joint trajectory controller is sent.

    Attributes
    ----------
    time : ndarray, shape (M,)
        Time from the start in [s], 0 first, strictly increasing, step ``1 / rate_hz``
        (the last step shorter when the plan's duration is not a multiple of it).
    q : ndarray, shape (M, nv)
        Joint positions in [rad] (or [m] for a prismatic joint).
    v : ndarray, shape (M, nv)
        Joint velocities in [rad/s] (or [m/s]).
    a : ndarray, shape (M, nv)
        Joint accelerations in [rad/s^2] (or [m/s^2]).
    tau : ndarray, shape (M, nv)
        Joint efforts in [N m] (or [N]).
    joint_names : tuple of str
        One name per coordinate (:func:`coordinate_names`), as in the URDF.
    units : tuple of JointUnits
        Units of each coordinate (:meth:`RobotModel.joint_units`).
    rate_hz : float
        Sampling rate in [Hz].
    robot : str
        Robot name.
    interpolation : str
        The plan's interpolant the samples were taken from.
    """

    time: Array
    q: Array
    v: Array
    a: Array
    tau: Array
    joint_names: tuple[str, ...]
    units: tuple[JointUnits, ...]
    rate_hz: float
    robot: str = ""
    interpolation: str = ""

    def __post_init__(self) -> None:
        t = np.array(self.time, dtype=float)
        if t.ndim != 1 or t.size < 2:
            raise ParameterError(f"time must be 1-D with >= 2 samples, got {t.shape}", name="time")
        if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0.0):
            raise ParameterError("time must be finite and strictly increasing [s]", name="time")
        t.setflags(write=False)
        object.__setattr__(self, "time", t)
        names = tuple(str(n) for n in self.joint_names)
        object.__setattr__(self, "joint_names", names)
        units = tuple(JointUnits(*u) for u in self.units)
        object.__setattr__(self, "units", units)
        if len(units) != len(names):
            raise ParameterError(
                f"units has {len(units)} entries for {len(names)} joint names", name="units"
            )
        for name in _FIELDS:
            object.__setattr__(self, name, _matrix(name, getattr(self, name), t.size, len(names)))
        rate = float(self.rate_hz)
        if not (math.isfinite(rate) and rate > 0.0):
            raise ParameterError(f"rate_hz must be > 0 [Hz], got {rate!r}", name="rate_hz")
        object.__setattr__(self, "rate_hz", rate)

    @property
    def n_samples(self) -> int:
        """Number of samples M."""
        return int(self.time.size)

    @property
    def duration(self) -> float:
        """Time of the last sample in [s]."""
        return float(self.time[-1])

    def as_trajectory(self) -> Trajectory:
        """Return the samples as a trapezoidal :class:`Trajectory` (knots at the samples).

        This is how a controller that interpolates linearly between the
        samples sees the plan; :func:`youbot_opt.trajopt.certify.certify` checks it.
        """
        return Trajectory(t=self.time, q=self.q, v=self.v, a=self.a, tau=self.tau)


def sample_times(duration: float, rate_hz: float) -> Array:
    """Return the clock ``0, 1/rate_hz, ...`` [s] up to and with ``duration`` [s]."""
    step = 1.0 / rate_hz
    n = int(math.floor(duration * rate_hz + 1e-9))
    times = np.arange(n + 1, dtype=float) * step
    if duration - times[-1] > 1e-9 * max(1.0, duration):
        return np.append(times, float(duration)).astype(np.float64)
    times[-1] = duration
    return times


def sample_trajectory(
    trajectory: Trajectory, robot: RobotModel, rate_hz: float
) -> SampledTrajectory:
    """Sample a plan at ``rate_hz`` with its transcription's own interpolants.

    Parameters
    ----------
    trajectory : Trajectory
        The plan (knot-major, ``nq == nv`` angle coordinates).
    robot : RobotModel
        The robot it was planned for (joint names and units).
    rate_hz : float
        Controller rate in [Hz], > 0; at least two samples are always taken
        (the start and the end).

    Returns
    -------
    SampledTrajectory
        Time from the start [s], q, v, a, tau at each sample.

    Raises
    ------
    ParameterError
        If ``rate_hz`` is not finite and > 0, or the trajectory does not match the robot.
    """
    try:
        rate = float(rate_hz)
    except (TypeError, ValueError) as exc:
        raise ParameterError(
            f"rate_hz must be a number [Hz], got {rate_hz!r}", name="rate_hz"
        ) from exc
    if not (math.isfinite(rate) and rate > 0.0):
        raise ParameterError(f"rate_hz must be finite and > 0 [Hz], got {rate!r}", name="rate_hz")
    names = coordinate_names(robot)
    if trajectory.q.shape[1] != len(names) or trajectory.v.shape[1] != len(names):
        raise ParameterError(
            f"the trajectory has {trajectory.q.shape[1]} coordinates, robot {robot.name!r} "
            f"has {len(names)} ({', '.join(names)})",
            name="trajectory",
        )
    rel = sample_times(trajectory.duration, rate)
    clock = trajectory.t[0] + rel
    clock[-1] = trajectory.t[-1]
    return SampledTrajectory(
        time=rel,
        q=trajectory(clock),
        v=trajectory.velocity(clock),
        a=trajectory.acceleration(clock),
        tau=trajectory.torque(clock),
        joint_names=names,
        units=robot.joint_units(),
        rate_hz=rate,
        robot=robot.name,
        interpolation=trajectory.interpolation,
    )
