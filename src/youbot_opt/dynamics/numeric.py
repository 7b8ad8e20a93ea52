"""Numeric forward dynamics of knot stacks and the damping rate, with Pinocchio.

Owns what the solver, the result check and the certificate share:
:func:`batched_aba` (``a = ABA(q, v, tau - b v)``, the joint damping applied
as a torque) and :func:`damping_rate` (the fastest rate of the joint damping,
compared with a grid step by :data:`STIFF_RATIO`). Robots with ``nq == nv``
(continuous joints in angle coordinates) only.

>>> a = batched_aba(robot)(q, v, tau)  # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple, TypeAlias

import numpy as np
import pinocchio as pin

from youbot_opt._typing import Array
from youbot_opt.dynamics.coordinates import angle_robot
from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.model import RobotModel, as_robot_model

__all__ = [
    "AbaFunction",
    "DampingRate",
    "RobotLike",
    "STIFF_RATIO",
    "acting_damping",
    "as_numeric_robot",
    "batched_aba",
    "damping_rate",
]

AbaFunction = Callable[[Array, Array, Array], Array]
"""``f(q, v, tau) -> a`` on knot-major stacks (:func:`batched_aba`)."""

STIFF_RATIO = 100.0
"""Largest ``damping_rate * h`` (dimensionless, ``h`` the longest interval) that
``method="auto"`` integrates explicitly (DOP853); above it, Radau. An explicit
step is stable only for ``h_step * rate`` below about 3-6, so DOP853 would take
more than ~20 steps per interval for stability alone (docs/refinement.md,
"Stiff joint damping")."""
_RATE_SAMPLES = 16  # configurations (spread over the knots) at which damping_rate is evaluated


RobotLike: TypeAlias = RobotModel | pin.Model
"""A :class:`~youbot_opt.robot.model.RobotModel` or a bare ``pinocchio.Model`` (wrapped)."""


def as_numeric_robot(robot: RobotLike) -> RobotModel:
    """``robot`` as a RobotModel with nq == nv (continuous joints in angle coordinates)."""
    model = angle_robot(as_robot_model(robot))
    if model.nq != model.nv:
        raise ParameterError(
            f"robot {model.name!r} has nq = {model.nq} != nv = {model.nv}; forward "
            "simulation supports revolute, continuous and prismatic joints only",
            name="robot",
            value=(model.nq, model.nv),
        )
    return model


def acting_damping(robot: RobotModel, damping: bool) -> Array:
    """Joint damping [N m s/rad] that acts: the model's, or zeros."""
    b = np.array(robot.damping, dtype=float)
    return b if damping else np.zeros_like(b)


def batched_aba(robot: RobotLike, *, damping: bool = True) -> AbaFunction:
    """Forward dynamics ``(q, v, tau) -> ABA(q, v, tau - b v)`` of knot-major stacks.

    Pinocchio's numeric ABA (``abaInParallel`` when available, else one
    ``pin.aba`` call per row); the viscous damping ``b`` is applied as a torque
    because ``pin.aba`` ignores ``model.damping``.

    Parameters
    ----------
    robot : RobotModel or pinocchio.Model
        The robot (``nq == nv``).
    damping : bool, optional
        Apply the model's joint damping ``b`` [N m s/rad]; False uses ``b = 0``.

    Returns
    -------
    callable
        ``f(q, v, tau)`` taking arrays of shape (n, nv) -- positions [rad],
        velocities [rad/s], torques [N m] -- and returning accelerations
        [rad/s^2] of shape (n, nv) (shape (n,) when ``nv == 1`` and
        ``abaInParallel`` is used).

    Raises
    ------
    ParameterError
        If ``robot`` is not a robot or has ``nq != nv``.
    """
    robot = as_numeric_robot(robot)
    model, b = robot.model, acting_damping(robot, damping)
    if hasattr(pin, "abaInParallel"):
        pool = pin.ModelPool(model, 1)

        def batch(q: Array, v: Array, tau: Array) -> Array:
            # Pinocchio's batched ABA takes column-major (nv, n) stacks.
            out = pin.abaInParallel(1, pool, q.T, v.T, (tau - b * v).T)
            return np.asarray(out).reshape(q.shape[1], q.shape[0]).T  # 1-D when nv == 1

        return batch
    data = model.createData()

    def rows(q: Array, v: Array, tau: Array) -> Array:
        return np.array(
            [
                pin.aba(model, data, qk, vk, tk - b * vk)
                for qk, vk, tk in zip(q, v, tau, strict=True)
            ]
        )

    return rows


class DampingRate(NamedTuple):
    """The fastest rate of the joint damping (:func:`damping_rate`).

    Attributes
    ----------
    rate : float
        Largest eigenvalue of ``M(q)^-1 B`` in [1/s] (0 without damping).
    joint : str
        The joint that dominates that mode (largest component of its
        eigenvector), "" without damping.
    """

    rate: float
    joint: str


def damping_rate(robot: RobotLike, q: Array, *, damping: bool = True) -> DampingRate:
    """Fastest rate at which the joint damping relaxes the velocities, in [1/s].

    The largest eigenvalue of ``M(q)^-1 B`` (``B`` the diagonal viscous damping
    [N m s/rad], ``M`` the joint-space inertia with the rotor armature) over the
    configurations ``q``: the fastest damped velocity mode decays like
    ``exp(-rate t)``. ``1 / rate`` is the shortest time constant of the
    dynamics; a grid step ``h`` with ``rate * h >> 1`` does not resolve it (the
    dynamics are stiff on that grid). For one joint alone, ``rate = b / I``
    (damping over the inertia about the axis).

    Parameters
    ----------
    robot : RobotModel or pinocchio.Model
        The robot (``nq == nv``).
    q : ndarray, shape (M, nq) or (nq,)
        Configurations in [rad] (at most 16, spread over the rows, are used).
    damping : bool, optional
        Whether the damping acts; False gives rate 0.

    Returns
    -------
    DampingRate
        The rate in [1/s] and the joint that dominates it.
    """
    robot = as_numeric_robot(robot)
    b = acting_damping(robot, damping)
    if not np.any(b > 0.0):
        return DampingRate(0.0, "")
    qs = np.atleast_2d(np.asarray(q, dtype=float))
    rows = np.unique(np.linspace(0, qs.shape[0] - 1, min(_RATE_SAMPLES, qs.shape[0])).astype(int))
    model, data = robot.model, robot.model.createData()
    root_b = np.sqrt(b)
    best = DampingRate(0.0, "")
    for qk in qs[rows]:
        mass = pin.crba(model, data, qk)
        mass = np.triu(mass) + np.triu(mass, 1).T  # crba fills the upper triangle only
        # eig(M^-1 B) = eig(B^1/2 M^-1 B^1/2): symmetric, real and >= 0
        sym = root_b[:, None] * np.linalg.inv(mass) * root_b[None, :]
        values, vectors = np.linalg.eigh(0.5 * (sym + sym.T))
        if values[-1] > best.rate:
            joint = int(np.argmax(np.abs(vectors[:, -1])))
            best = DampingRate(float(values[-1]), robot.joint_names[joint])
    return best
