"""Plain description of a fixed-base kinematic tree read from a ``pin.Model`` (internal).

The backends never touch Pinocchio's model objects while they build
expressions; they read this frozen snapshot instead. Only one-degree-of-freedom
revolute (bounded or continuous) and prismatic joints (constant motion
subspace, no bias acceleration) are accepted; anything else raises
:class:`ModelError`. A continuous joint is read as a revolute joint whose
coordinate is its unbounded angle (:mod:`youbot_opt.dynamics.coordinates`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from youbot_opt._typing import Array
from youbot_opt.dynamics.spatial_algebra import inertia_matrix
from youbot_opt.exceptions import ModelError, ParameterError

__all__ = ["JointSpec", "FrameSpec", "TreeSpec", "SUPPORTED_JOINTS", "as_pin_model", "read_tree"]

_REVOLUTE_AXES: dict[str, tuple[float, float, float]] = {
    "JointModelRX": (1.0, 0.0, 0.0),
    "JointModelRY": (0.0, 1.0, 0.0),
    "JointModelRZ": (0.0, 0.0, 1.0),
}
_CONTINUOUS_AXES: dict[str, tuple[float, float, float]] = {
    "JointModelRUBX": (1.0, 0.0, 0.0),
    "JointModelRUBY": (0.0, 1.0, 0.0),
    "JointModelRUBZ": (0.0, 0.0, 1.0),
}
_PRISMATIC_AXES: dict[str, tuple[float, float, float]] = {
    "JointModelPX": (1.0, 0.0, 0.0),
    "JointModelPY": (0.0, 1.0, 0.0),
    "JointModelPZ": (0.0, 0.0, 1.0),
}
SUPPORTED_JOINTS: tuple[str, ...] = (
    *_REVOLUTE_AXES,
    "JointModelRevoluteUnaligned",
    *_CONTINUOUS_AXES,
    "JointModelRevoluteUnboundedUnaligned",
    *_PRISMATIC_AXES,
    "JointModelPrismaticUnaligned",
)
"""Pinocchio joint short names the CasADi backends can transcribe (continuous ones in angle
coordinates: one unbounded angle in [rad] instead of Pinocchio's (cos, sin))."""
_PRISMATIC_JOINTS: frozenset[str] = frozenset({*_PRISMATIC_AXES, "JointModelPrismaticUnaligned"})


@dataclass(frozen=True, slots=True, kw_only=True)
class JointSpec:
    """One joint of the tree.

    Attributes
    ----------
    name : str
        Joint name in the model.
    kind : str
        ``"revolute"`` or ``"prismatic"``.
    axis : ndarray, shape (3,)
        Unit joint axis in the joint frame.
    parent : int
        Index of the parent joint (0 is the fixed universe).
    index_v : int
        Index of the joint's coordinate in ``q`` and ``v`` (angle coordinates:
        a continuous joint has one entry, its angle, in both).
    rotation, translation : ndarray, shapes (3, 3) and (3,)
        Placement of the joint frame in the parent joint frame at q = 0; [m].
    mass : float
        Mass of the body carried by the joint in [kg].
    inertia : ndarray, shape (6, 6)
        Spatial inertia of that body about the joint frame origin.
    armature : float
        Rotor inertia added to the diagonal of M, [kg m^2] or [kg].
    """

    name: str
    kind: str
    axis: Array
    parent: int
    index_v: int
    rotation: Array
    translation: Array
    mass: float
    inertia: Array
    armature: float


@dataclass(frozen=True, slots=True, kw_only=True)
class FrameSpec:
    """A frame attached to a joint: its parent joint and placement in it ([m])."""

    name: str
    parent_joint: int
    rotation: Array
    translation: Array


@dataclass(frozen=True, slots=True, kw_only=True)
class TreeSpec:
    """Snapshot of a fixed-base tree of 1-dof joints.

    Attributes
    ----------
    joints : tuple of JointSpec
        Joints 1..njoints-1 of the model, in Pinocchio's (topological) order;
        ``joints[i - 1]`` is model joint ``i``.
    frames : tuple of FrameSpec
        All operational frames of the model.
    gravity : ndarray, shape (6,)
        Gravity as a spatial motion (linear part first) in [m/s^2].
    damping : ndarray, shape (nv,)
        Viscous joint damping from ``model.damping`` in [N m s/rad] or [N s/m].
    nv : int
        Number of degrees of freedom (equal to the number of angle coordinates).
    """

    joints: tuple[JointSpec, ...]
    frames: tuple[FrameSpec, ...]
    gravity: Array
    damping: Array
    nv: int

    @property
    def nq(self) -> int:
        """Number of angle coordinates (nv; Pinocchio's nq adds one per continuous joint)."""
        return self.nv


def as_pin_model(model: object) -> pin.Model:
    """Return the ``pin.Model`` behind ``model`` (a ``pin.Model`` or anything with ``.model``).

    Parameters
    ----------
    model : pin.Model or RobotModel
        The model, or a wrapper holding it in its ``model`` attribute.

    Returns
    -------
    pin.Model
        The Pinocchio model.

    Raises
    ------
    ParameterError
        If neither ``model`` nor ``model.model`` is a ``pin.Model``.
    """
    if isinstance(model, pin.Model):
        return model
    inner = getattr(model, "model", None)
    if isinstance(inner, pin.Model):
        return inner
    raise ParameterError(
        f"expected a pin.Model or an object with a pin.Model in '.model' (e.g. RobotModel), "
        f"got {type(model).__name__}",
        name="model",
        value=type(model).__name__,
    )


def _joint_axis(joint: Any, kind_name: str) -> Array:
    if kind_name in _REVOLUTE_AXES:
        return np.array(_REVOLUTE_AXES[kind_name])
    if kind_name in _CONTINUOUS_AXES:
        return np.array(_CONTINUOUS_AXES[kind_name])
    if kind_name in _PRISMATIC_AXES:
        return np.array(_PRISMATIC_AXES[kind_name])
    axis = np.asarray(joint.extract().axis, dtype=float).reshape(3)
    return axis / np.linalg.norm(axis)


def read_tree(model: pin.Model) -> TreeSpec:
    """Read the joints, bodies, frames, gravity and damping of a fixed-base model.

    Parameters
    ----------
    model : pin.Model
        A model whose joints are all among :data:`SUPPORTED_JOINTS`.

    Returns
    -------
    TreeSpec
        The snapshot the backends build from.

    Raises
    ------
    ModelError
        If a joint has an unsupported type (free-flyer, spherical, planar,
        composite, mimic, ...), naming the joint and its type.
    """
    joints: list[JointSpec] = []
    for i in range(1, model.njoints):
        joint = model.joints[i]
        kind_name = joint.shortname()
        if kind_name not in SUPPORTED_JOINTS or joint.nv != 1:
            raise ModelError(
                f"joint {model.names[i]!r} has type {kind_name}, which the CasADi dynamics "
                f"backends do not support; supported joint types: {', '.join(SUPPORTED_JOINTS)}"
            )
        placement = model.jointPlacements[i]
        body = model.inertias[i]
        joints.append(
            JointSpec(
                name=str(model.names[i]),
                kind="prismatic" if kind_name in _PRISMATIC_JOINTS else "revolute",
                axis=_joint_axis(joint, kind_name),
                parent=int(model.parents[i]),
                index_v=int(joint.idx_v),
                rotation=np.array(placement.rotation, dtype=float),
                translation=np.array(placement.translation, dtype=float),
                mass=float(body.mass),
                inertia=inertia_matrix(body.mass, body.lever, body.inertia),
                armature=float(model.armature[joint.idx_v]),
            )
        )
    frames = tuple(
        FrameSpec(
            name=str(frame.name),
            parent_joint=int(frame.parentJoint),
            rotation=np.array(frame.placement.rotation, dtype=float),
            translation=np.array(frame.placement.translation, dtype=float),
        )
        for frame in model.frames
    )
    gravity = np.concatenate(
        [np.asarray(model.gravity.linear, dtype=float), np.asarray(model.gravity.angular)]
    )
    return TreeSpec(
        joints=tuple(joints),
        frames=frames,
        gravity=gravity,
        damping=np.array(model.damping, dtype=float),
        nv=int(model.nv),
    )
