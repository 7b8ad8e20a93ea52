"""Angle coordinates for continuous joints: one unbounded angle per joint instead of (cos, sin).

Pinocchio stores a continuous (revolute-unbounded) joint as ``(cos θ, sin θ)``
(``nq = 2``, ``nv = 1``). The dynamics backends and the trajectory optimiser
use the angle θ itself, so that ``q`` has ``nv`` entries and a planner may turn
the joint past ±π (docs/design.md, "Continuous joints"). This module converts
between the two (:func:`to_pin_configuration`, :func:`from_pin_configuration`)
and builds the equivalent model whose continuous joints are plain revolute
joints without position limits (:func:`angle_model`, :func:`angle_robot`).

Example: ``q_pin = to_pin_configuration(model, theta)``; ``pin.aba(model, data, q_pin, v, tau)``.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike

from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.model import RobotModel

__all__ = [
    "CONTINUOUS_JOINTS",
    "angle_model",
    "angle_robot",
    "continuous_joints",
    "from_pin_configuration",
    "to_pin_configuration",
]

CONTINUOUS_JOINTS: tuple[str, ...] = (
    "JointModelRUBX",
    "JointModelRUBY",
    "JointModelRUBZ",
    "JointModelRevoluteUnboundedUnaligned",
)
"""Pinocchio short names of continuous joints (``nq = 2``, ``nv = 1``)."""

_BOUNDED = {
    "JointModelRUBX": pin.JointModelRX,
    "JointModelRUBY": pin.JointModelRY,
    "JointModelRUBZ": pin.JointModelRZ,
}


def continuous_joints(model: pin.Model) -> tuple[int, ...]:
    """Return the indices (in ``model.joints``) of the continuous joints of ``model``."""
    return tuple(
        i for i in range(1, model.njoints) if model.joints[i].shortname() in CONTINUOUS_JOINTS
    )


def _angle_vector(model: pin.Model, q: ArrayLike, name: str, size: int) -> Array:
    arr = np.asarray(q, dtype=float).reshape(-1)
    if arr.shape != (size,):
        raise ParameterError(
            f"{name} must have shape ({size},) for model {model.name!r}, got {arr.shape}",
            name=name,
            value=arr.shape,
        )
    return arr


def to_pin_configuration(model: pin.Model, q: ArrayLike) -> Array:
    """Pinocchio configuration (nq,) of the angle coordinates ``q`` (nv,).

    Parameters
    ----------
    model : pin.Model
        The model with its continuous joints.
    q : array_like, shape (nv,)
        One coordinate per degree of freedom, in [rad] or [m]; a continuous
        joint's entry is its angle θ (any real number).

    Returns
    -------
    ndarray, shape (nq,)
        The configuration with ``(cos θ, sin θ)`` for each continuous joint.
    """
    theta = _angle_vector(model, q, "q", model.nv)
    if model.nq == model.nv:
        return theta.copy()
    out = np.empty(model.nq)
    for i in range(1, model.njoints):
        joint = model.joints[i]
        if joint.shortname() in CONTINUOUS_JOINTS:
            angle = theta[joint.idx_v]
            out[joint.idx_q : joint.idx_q + 2] = (np.cos(angle), np.sin(angle))
        else:
            out[joint.idx_q : joint.idx_q + joint.nq] = theta[joint.idx_v : joint.idx_v + joint.nv]
    return out


def from_pin_configuration(model: pin.Model, q_pin: ArrayLike) -> Array:
    """Angle coordinates (nv,) of a Pinocchio configuration (nq,); angles in (-π, π]."""
    x = _angle_vector(model, q_pin, "q_pin", model.nq)
    if model.nq == model.nv:
        return x.copy()
    out = np.empty(model.nv)
    for i in range(1, model.njoints):
        joint = model.joints[i]
        if joint.shortname() in CONTINUOUS_JOINTS:
            c, s = x[joint.idx_q : joint.idx_q + 2]
            out[joint.idx_v] = np.arctan2(s, c)
        else:
            out[joint.idx_v : joint.idx_v + joint.nv] = x[joint.idx_q : joint.idx_q + joint.nq]
    return out


def angle_model(model: pin.Model) -> pin.Model:
    """Equivalent model whose continuous joints are revolute joints without position limits.

    The kinematic tree, joint and frame indices, inertias, limits, damping,
    friction and armature are those of ``model``; each continuous joint
    becomes the revolute joint about the same axis with position limits
    ``±inf``, so ``q`` of the new model is the angle coordinates of ``model``
    and ``pin.aba``/``pin.rnea``/``pin.crba`` of both agree (tested).

    Parameters
    ----------
    model : pin.Model
        Any fixed-base model; returned as a copy if it has no continuous joint.

    Returns
    -------
    pin.Model
        A new model with ``nq == nv`` for the former continuous joints.
    """
    if not continuous_joints(model):
        return model.copy()
    new = pin.Model()
    new.name = model.name
    new.gravity = model.gravity
    lower = np.empty(model.nv)
    upper = np.empty(model.nv)
    for i in range(1, model.njoints):
        joint = model.joints[i]
        short = joint.shortname()
        iq, iv = joint.idx_q, joint.idx_v
        if short in CONTINUOUS_JOINTS:
            bounded = _BOUNDED.get(short)
            joint_model = (
                bounded()
                if bounded is not None
                else pin.JointModelRevoluteUnaligned(joint.extract().axis)
            )
            lower[iv], upper[iv] = -np.inf, np.inf
        else:
            joint_model = joint.extract()
            lower[iv : iv + joint.nv] = model.lowerPositionLimit[iq : iq + joint.nq]
            upper[iv : iv + joint.nv] = model.upperPositionLimit[iq : iq + joint.nq]
        jid = new.addJoint(
            int(model.parents[i]), joint_model, model.jointPlacements[i], str(model.names[i])
        )
        new.inertias[jid] = model.inertias[jid]
    for frame in list(model.frames)[1:]:
        new.addFrame(pin.Frame(frame), False)
    new.lowerPositionLimit = lower
    new.upperPositionLimit = upper
    for name in (
        "velocityLimit",
        "lowerVelocityLimit",
        "upperVelocityLimit",
        "effortLimit",
        "lowerEffortLimit",
        "upperEffortLimit",
        "damping",
        "friction",
        "lowerDryFrictionLimit",
        "upperDryFrictionLimit",
        "armature",
        "rotorInertia",
        "rotorGearRatio",
    ):
        setattr(new, name, np.array(getattr(model, name), dtype=float))
    return new


def angle_robot(robot: RobotModel) -> RobotModel:
    """``robot`` with its model replaced by :func:`angle_model` (itself if nothing to replace).

    Geometry (visual, collision) is kept: joint and frame indices are unchanged.
    """
    if not continuous_joints(robot.model):
        return robot
    return robot.replace(model=angle_model(robot.model))
