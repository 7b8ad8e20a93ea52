"""A payload carried by the robot: :class:`Payload`, added to the Pinocchio model's inertias.

A rigid body fixed in a frame of the robot (the tip by default): mass [kg],
centre of mass [m] and inertia about it [kg m^2] in that frame (libfranka's
``setLoad``). :func:`add_payload` adds it to the frame's parent joint, so every
dynamics backend sees it: a point mass ``m`` changes ``M(q)`` by ``m J^T J`` and
the gravity torque by ``-m J^T g``. Attach it with :meth:`RobotModel.with_payload
<youbot_opt.robot.model.RobotModel.with_payload>` or ``load_model(payload=...)``;
:class:`~youbot_opt.robot.source.RobotSource` records it. Guide: docs/payload.md.

>>> robot = load_model("youbot").with_payload(Payload(mass=0.5))  # doctest: +SKIP
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from youbot_opt._checks import to_float
from youbot_opt._typing import JSONDict
from youbot_opt.exceptions import ParameterError

__all__ = ["Payload", "add_payload"]

_INERTIA_TOL = 1e-12  # [kg m^2] round-off allowed in the symmetry and triangle checks


def _vector3(name: str, value: object) -> tuple[float, float, float]:
    try:
        arr = np.array(value, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise ParameterError(f"{name} must be 3 numbers, got {value!r}", name=name) from exc
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise ParameterError(f"{name} must be 3 finite numbers, got {value!r}", name=name)
    return (float(arr[0]), float(arr[1]), float(arr[2]))


def _inertia(value: object) -> tuple[tuple[float, ...], ...]:
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ParameterError(
            f"inertia must be 3 or 3x3 numbers in [kg m^2], got {value!r}", name="inertia"
        ) from exc
    if arr.shape == (3,):
        arr = np.diag(arr)
    elif arr.shape == (9,):  # a 3x3 matrix, row by row
        arr = arr.reshape(3, 3)
    elif arr.shape == (6,):  # ixx, ixy, ixz, iyy, iyz, izz (the URDF's order)
        xx, xy, xz, yy, yz, zz = arr
        arr = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
    if arr.shape != (3, 3) or not np.all(np.isfinite(arr)):
        raise ParameterError(
            "inertia must be finite: 3 principal moments, 6 values (ixx ixy ixz iyy iyz izz) "
            f"or a 3x3 matrix (9 values, row by row) in [kg m^2], got {value!r}",
            name="inertia",
        )
    if np.max(np.abs(arr - arr.T)) > _INERTIA_TOL:
        raise ParameterError(f"inertia must be symmetric, got {arr.tolist()}", name="inertia")
    moments = np.linalg.eigvalsh(0.5 * (arr + arr.T))
    if moments[0] < -_INERTIA_TOL or moments[0] + moments[1] < moments[2] - _INERTIA_TOL:
        raise ParameterError(
            f"inertia is not a rigid body's: principal moments {moments.tolist()} [kg m^2] must "
            "be >= 0 and each at most the sum of the other two",
            name="inertia",
        )
    return tuple(tuple(float(x) for x in row) for row in arr)


def _mass(value: object) -> float:
    try:
        mass = to_float(value)
    except (TypeError, ValueError) as exc:
        raise ParameterError(f"mass must be a number [kg], got {value!r}") from exc
    if not (math.isfinite(mass) and mass >= 0.0):
        raise ParameterError(
            f"payload mass must be finite and >= 0 [kg], got {value!r}", name="mass"
        )
    return mass


def _frame(value: object) -> str | None:
    if value is not None and (not isinstance(value, str) or not value):
        raise ParameterError(f"frame must be a frame name, got {value!r}", name="frame")
    return value


@dataclass(frozen=True, slots=True, kw_only=True)
class Payload:
    """A rigid payload fixed in a frame of the robot.

    Attributes
    ----------
    mass : float
        Mass in [kg], >= 0.
    com : tuple of 3 float
        Centre of mass in [m], in ``frame`` (default: the frame's origin).
    inertia : tuple of 3 tuples of 3 float
        Rotational inertia about the centre of mass in [kg m^2], in ``frame``'s
        axes, a symmetric 3x3 matrix (default 0: a point mass). Given as 3
        principal moments, the 6 values ``ixx ixy ixz iyy iyz izz``, 9 values
        row by row or a 3x3 array; it must be a rigid body's (moments >= 0,
        triangle inequality).
        Plain tuples, so that payloads compare and hash.
    frame : str or None
        The robot frame carrying it; None: the robot's tip frame (resolved
        when attached, so an attached payload always names its frame).
    """

    mass: float
    com: tuple[float, float, float] = (0.0, 0.0, 0.0)
    inertia: tuple[tuple[float, ...], ...] = ((0.0, 0.0, 0.0),) * 3
    frame: str | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "mass", _mass(self.mass))
        object.__setattr__(self, "com", _vector3("com", self.com))
        object.__setattr__(self, "inertia", _inertia(self.inertia))
        _frame(self.frame)

    def spatial_inertia(self) -> pin.Inertia:
        """Return the payload as a ``pinocchio.Inertia`` in its frame."""
        return pin.Inertia(self.mass, np.array(self.com), np.array(self.inertia, dtype=float))

    def to_json(self) -> JSONDict:
        """JSON-ready form: ``mass`` [kg], ``com`` [m], ``inertia`` [kg m^2] (3x3), ``frame``."""
        return {
            "mass": self.mass,
            "com": list(self.com),
            "inertia": [list(row) for row in self.inertia],
            "frame": self.frame,
        }

    @classmethod
    def from_json(cls, data: Mapping[str, object]) -> Payload:
        """Inverse of :meth:`to_json`.

        Raises
        ------
        KeyError, TypeError, ValueError
            If ``data`` is not such a form (``ParameterError`` is a ValueError).
        """
        mass = _mass(data["mass"])  # checked in the constructor's order
        com = _vector3("com", data.get("com", (0.0, 0.0, 0.0)))
        inertia = _inertia(data.get("inertia", np.zeros((3, 3))))
        return cls(mass=mass, com=com, inertia=inertia, frame=_frame(data.get("frame")))


def add_payload(model: pin.Model, frame_id: int, payload: Payload) -> pin.Model:
    """Return a copy of ``model`` whose frame ``frame_id`` carries ``payload``.

    The payload's spatial inertia, moved from the frame to its parent joint
    (``jMf.act``), is added to that joint's body inertia.

    Parameters
    ----------
    model : pinocchio.Model
        The robot's model (not modified).
    frame_id : int
        Index of the carrying frame in ``model.frames``.
    payload : Payload
        The payload.

    Returns
    -------
    pinocchio.Model
        The copy, with the payload in ``inertias[parent joint]``.
    """
    new = pin.Model(model)
    frame = model.frames[frame_id]
    joint = int(frame.parentJoint)
    new.inertias[joint] = model.inertias[joint] + frame.placement.act(payload.spatial_inertia())
    return new
