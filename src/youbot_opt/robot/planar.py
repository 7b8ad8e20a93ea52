"""A planar chain as a robot: study 2's arms (spec ``ikpath.md``, "The arm").

A :class:`PlanarChain` is ``n`` revolute joints about the plane normal (z),
segment ``i`` of length ``l_i`` ending at the tip frame, in the study's angle
convention up to a constant offset (see the class). :meth:`PlanarChain.robot`
is the chain as a :class:`~youbot_opt.robot.model.RobotModel`;
:func:`chain_from_robot` reads the chain back from a robot that moves in a
plane (the youBot arm: :func:`youbot_chain`).

>>> PlanarChain(lengths=[3, 2, 2]).tip_position([0.0, 0.0, 0.0])  # doctest: +SKIP
array([7., 0.])
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike

from youbot_opt._checks import check_shape
from youbot_opt._typing import Array
from youbot_opt.exceptions import ModelError, ParameterError
from youbot_opt.robot.load import load_model
from youbot_opt.robot.model import RobotModel

__all__ = [
    "Plane",
    "PlanarChain",
    "TipKinematics",
    "as_configuration",
    "chain_from_robot",
    "motion_plane",
    "youbot_chain",
]

_PIN_INF = float(np.finfo(float).max)  # Pinocchio's "no limit" value
_PARALLEL_TOL = 1e-12  # [-] largest |a x n| of a unit joint axis a parallel to the normal n
_LINK_RGBA = np.array([0.95, 0.55, 0.1, 1.0])
_JOINT_RGBA = np.array([0.2, 0.2, 0.2, 1.0])


class TipKinematics(NamedTuple):
    """Tip position and its Jacobian at one configuration.

    Attributes
    ----------
    position : ndarray, shape (2,)
        Tip position in the chain's plane, in [m] (the length unit of the chain).
    jacobian : ndarray, shape (2, n)
        d position / d q in [m/rad].
    """

    position: Array
    jacobian: Array


class Plane(NamedTuple):
    """The plane a frame moves in: the robot is planar for that frame.

    Attributes
    ----------
    normal : ndarray, shape (3,)
        Unit normal in the world: the common axis of the joints.
    offset : float
        ``normal . p`` in [m] for every point ``p`` of the plane.
    basis : ndarray, shape (3, 2)
        The plane's coordinate axes in the world (orthonormal); a point's
        plane coordinates are ``basis.T @ p`` in [m].
    """

    normal: Array
    offset: float
    basis: Array

    def distance(self, point: ArrayLike) -> float:
        """Distance in [m] of a world point from the plane."""
        return abs(float(self.normal @ np.asarray(point, dtype=float)) - self.offset)


def motion_plane(model: pin.Model, frame_id: int, q: ArrayLike) -> Plane | None:
    """Return the plane a frame moves in, or None if its robot is not planar.

    A robot is planar for a frame when every joint that moves the frame is
    revolute (or continuous) and their axes are parallel (within 1e-12) to one
    world direction ``n``: turning about axes parallel to ``n`` keeps ``n . p``
    of every point, so the frame's origin stays in the plane normal to ``n``
    through its position at ``q``, at any configuration. ``n`` is the first
    joint's axis; the plane coordinates ``(e1, e2)`` have ``e1 x e2 = n`` (a
    positive angle turns counter-clockwise): the two world axes other than
    ``n`` when ``n`` is one (a chain about +z moves in (x, y), the youBot arm
    about -y in (x, z)), else the projection of world x (or y) and ``n x e1``.

    Parameters
    ----------
    model : pinocchio.Model
        The robot.
    frame_id : int
        The frame that visits the targets.
    q : array_like, shape (nq,)
        Any configuration of the model.

    Returns
    -------
    Plane or None
        The plane, or None (a prismatic joint, or axes not parallel).
    """
    data = model.createData()
    qv = np.asarray(q, dtype=float)
    pin.computeJointJacobians(model, data, qv)
    pin.updateFramePlacements(model, data)
    support = [j for j in model.supports[model.frames[frame_id].parentJoint] if j > 0]
    if not support:
        return None
    axes = []
    for j in support:
        joint = model.joints[j]
        if joint.nv != 1:
            return None
        jac = np.reshape(pin.getJointJacobian(model, data, j, pin.WORLD), (6, model.nv))
        column = jac[:, joint.idx_v]  # (a 1-DoF model returns shape (6,))
        axis = np.asarray(column[3:], dtype=float)
        if abs(float(np.linalg.norm(axis)) - 1.0) > _PARALLEL_TOL:  # prismatic (no turn)
            return None
        axes.append(axis)
    normal = axes[0]
    if any(float(np.linalg.norm(np.cross(a, normal))) > _PARALLEL_TOL for a in axes[1:]):
        return None
    k = int(np.argmax(np.abs(normal)))
    if abs(abs(float(normal[k])) - 1.0) <= _PARALLEL_TOL:  # a world axis: the other two
        normal = np.eye(3)[k] * np.sign(normal[k])
        basis = np.eye(3)[:, [i for i in range(3) if i != k]]
        if float(np.cross(basis[:, 0], basis[:, 1]) @ normal) < 0.0:  # turn counter-clockwise
            basis = basis[:, ::-1].copy()
    else:
        helper = np.eye(3)[0] if abs(float(normal[0])) < 0.9 else np.eye(3)[1]
        e1 = helper - (helper @ normal) * normal
        e1 /= np.linalg.norm(e1)
        basis = np.column_stack([e1, np.cross(normal, e1)])
    normal = normal.copy()
    offset = float(normal @ data.oMf[frame_id].translation)
    for arr in (normal, basis):
        arr.setflags(write=False)
    return Plane(normal=normal, offset=offset, basis=basis)


def as_configuration(q: ArrayLike, n: int, name: str = "q") -> Array:
    """Return ``q`` as a finite float vector of length ``n``.

    Parameters
    ----------
    q : array_like, shape (n,)
        Joint angles in [rad].
    n : int
        Expected length.
    name : str
        Argument name used in the error message.

    Returns
    -------
    ndarray, shape (n,)
        A float copy of ``q``.

    Raises
    ------
    ParameterError
        If ``q`` has another shape or non-finite entries.
    """
    return check_shape(q, (n,), name)


def _vector(name: str, value: ArrayLike | None, n: int, default: float) -> Array:
    """Broadcast a scalar or length-``n`` sequence to a read-only float vector."""
    if value is None:
        arr = np.full(n, default)
    else:
        try:
            arr = np.broadcast_to(np.asarray(value, dtype=float), (n,)).copy()
        except (ValueError, TypeError) as exc:
            raise ParameterError(
                f"{name} must be a scalar or have shape ({n},), got {np.shape(value)}",
                name=name,
                value=value,
            ) from exc
    if np.any(np.isnan(arr)):
        raise ParameterError(f"{name} contains NaN: {arr}", name=name, value=arr)
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class PlanarChain:
    r"""An n-link planar revolute chain with an optional box of joint limits.

    Segment ``i`` runs from joint ``i`` to joint ``i + 1``; the joint
    coordinates ``q`` follow the study's convention up to a constant offset:

    .. math::

        \theta = q + \text{angle\_offset}, \qquad
        F(\theta) = b + \sum_i l_i (\cos\phi_i, \sin\phi_i), \quad
        \phi_i = \theta_1 + \dots + \theta_i,

    so ``theta_1`` is the absolute angle of segment 1 from the x axis and the
    others are relative to the previous segment. With the defaults
    (``base = 0``, ``angle_offset = 0``) ``q`` *is* the study's ``theta``; the
    offsets let a real arm (the youBot, angles from the vertical, mounted off
    the platform origin) be the same kind of object
    (:func:`chain_from_robot`). Forward kinematics and
    the tip Jacobian come from Pinocchio (``computeFrameJacobian`` in
    ``LOCAL_WORLD_ALIGNED``, rows x and y).

    Attributes
    ----------
    lengths : ndarray, shape (n,)
        Segment lengths in [m] (any length unit; all positions use it), > 0.
    q_lower, q_upper : ndarray, shape (n,)
        Joint limits in [rad]; a scalar is broadcast. ``None``, ``-inf`` in
        ``q_lower`` and ``+inf`` in ``q_upper`` mean "no limit" on that side;
        ``+inf`` as a lower or ``-inf`` as an upper limit (an empty range) and
        NaN are rejected, and ``q_lower <= q_upper`` is required.
    base : ndarray, shape (2,)
        Position of joint 1 in the plane, in [m].
    angle_offset : ndarray, shape (n,)
        ``theta - q`` in [rad]: the study's angles are ``q + angle_offset``.
    name : str
        Model name.
    tip_frame : str
        Name of the tip frame of :attr:`model`.
    model : pinocchio.Model
        The chain (``JointModelRZ`` joints), built from the fields above.
    visual_model : pinocchio.GeometryModel
        Cylinders along the segments and small spheres at the joints (coal shapes).
    tip_frame_id : int
        Index of :attr:`tip_frame` in :attr:`model`.
    """

    lengths: Array
    q_lower: Array = None  # type: ignore[assignment]
    q_upper: Array = None  # type: ignore[assignment]
    base: Array = None  # type: ignore[assignment]
    angle_offset: Array = None  # type: ignore[assignment]
    name: str = "planar_chain"
    tip_frame: str = "tip"
    model: pin.Model = field(init=False, repr=False)
    visual_model: pin.GeometryModel = field(init=False, repr=False)
    tip_frame_id: int = field(init=False, repr=False)

    def __post_init__(self) -> None:
        lengths = np.array(self.lengths, dtype=float)
        if lengths.ndim != 1 or lengths.size < 1:
            raise ParameterError(
                f"lengths must be a non-empty 1-D sequence, got shape {lengths.shape}",
                name="lengths",
                value=self.lengths,
            )
        if not np.all(np.isfinite(lengths)) or np.any(lengths <= 0.0):
            raise ParameterError(
                f"lengths must be finite and > 0, got {lengths.tolist()}",
                name="lengths",
                value=lengths,
            )
        lengths.setflags(write=False)
        n = lengths.size
        lower = _vector("q_lower", self.q_lower, n, -np.inf)
        upper = _vector("q_upper", self.q_upper, n, np.inf)
        for key, arr, empty, side in (
            ("q_lower", lower, np.inf, "lower"),
            ("q_upper", upper, -np.inf, "upper"),
        ):
            wrong = np.flatnonzero(arr == empty)
            if wrong.size:
                i = int(wrong[0])
                raise ParameterError(
                    f"{key}[{i}] = {arr[i]} leaves joint {i} no value; {key} must be finite, "
                    f"or {-empty} (or None) for no {side} limit",
                    name=key,
                    value=arr,
                )
        bad = np.flatnonzero(lower > upper)
        if bad.size:
            i = int(bad[0])
            raise ParameterError(
                f"q_lower[{i}] = {lower[i]} > q_upper[{i}] = {upper[i]}; "
                "each lower limit must not exceed its upper limit",
                name="q_lower",
                value=lower,
            )
        base = np.array((0.0, 0.0) if self.base is None else self.base, dtype=float)
        if base.shape != (2,) or not np.all(np.isfinite(base)):
            raise ParameterError(
                f"base must be a finite 2-vector, got {self.base!r}", name="base", value=self.base
            )
        base.setflags(write=False)
        offset = _vector("angle_offset", self.angle_offset, n, 0.0)
        if not np.all(np.isfinite(offset)):
            raise ParameterError(
                f"angle_offset must be finite, got {offset}", name="angle_offset", value=offset
            )
        for key, val in (
            ("lengths", lengths),
            ("q_lower", lower),
            ("q_upper", upper),
            ("base", base),
            ("angle_offset", offset),
        ):
            object.__setattr__(self, key, val)
        model, visual, tip_id = _build_models(self)
        object.__setattr__(self, "model", model)
        object.__setattr__(self, "visual_model", visual)
        object.__setattr__(self, "tip_frame_id", tip_id)

    def __reduce__(self) -> tuple[Any, ...]:
        """Pickle by the defining fields; the Pinocchio models are rebuilt on load."""
        return (_rebuild, (self._spec(),))

    def _spec(self) -> dict[str, Any]:
        return {
            "lengths": self.lengths,
            "q_lower": self.q_lower,
            "q_upper": self.q_upper,
            "base": self.base,
            "angle_offset": self.angle_offset,
            "name": self.name,
            "tip_frame": self.tip_frame,
        }

    @property
    def n(self) -> int:
        """Number of joints (``nq == nv``)."""
        return int(self.lengths.size)

    @property
    def bounded(self) -> bool:
        """Whether any joint limit is finite."""
        return bool(np.any(np.isfinite(self.q_lower)) or np.any(np.isfinite(self.q_upper)))

    @property
    def package_dirs(self) -> tuple[()]:
        """Mesh search paths (none: the visuals are primitive shapes)."""
        return ()

    @property
    def reach(self) -> tuple[float, float]:
        """Inner and outer radius in [m] of the workspace without joint limits.

        The workspace is the annulus ``r_min <= |p - base| <= r_max`` with
        ``r_max = sum l`` and ``r_min = max(0, l_m - sum_{i != m} l_i)``.
        """
        total = float(np.sum(self.lengths))
        longest = float(np.max(self.lengths))
        return max(0.0, 2.0 * longest - total), total

    def with_limits(self, q_lower: ArrayLike | None, q_upper: ArrayLike | None) -> PlanarChain:
        """Return a copy with other joint limits (``None`` = unlimited) in [rad]."""
        spec = self._spec()
        spec.update(q_lower=q_lower, q_upper=q_upper)
        return PlanarChain(**spec)

    def create_data(self) -> pin.Data:
        """Return a fresh ``pinocchio.Data`` for :attr:`model`."""
        return self.model.createData()

    def robot(self) -> RobotModel:
        """Return the chain as a :class:`~youbot_opt.robot.model.RobotModel`.

        Its Pinocchio model and visual model are :attr:`model` and
        :attr:`visual_model` (not copied), the tip frame :attr:`tip_frame`;
        no collision geometry, no file.
        """
        return RobotModel(
            name=self.name,
            model=self.model,
            visual_model=self.visual_model,
            collision_model=pin.GeometryModel(),
            urdf_path=None,
            package_dirs=(),
            tip_frame=self.tip_frame,
        )

    def kinematics(self, q: ArrayLike, data: pin.Data | None = None) -> TipKinematics:
        """Tip position and Jacobian from Pinocchio.

        Parameters
        ----------
        q : array_like, shape (n,)
            Joint angles in [rad].
        data : pinocchio.Data, optional
            Work space from :meth:`create_data` (reuse it in loops).

        Returns
        -------
        TipKinematics
            Position (2,) in [m] and Jacobian (2, n) in [m/rad].
        """
        qv = as_configuration(q, self.n)
        data = self.create_data() if data is None else data
        jac = pin.computeFrameJacobian(
            self.model, data, qv, self.tip_frame_id, pin.LOCAL_WORLD_ALIGNED
        )
        jac = np.reshape(jac, (6, self.n))  # a 1-joint model returns shape (6,)
        return TipKinematics(data.oMf[self.tip_frame_id].translation[:2].copy(), jac[:2].copy())

    def tip_position(self, q: ArrayLike, data: pin.Data | None = None) -> Array:
        """Tip position ``F(q)`` in [m], shape (2,), by Pinocchio forward kinematics."""
        qv = as_configuration(q, self.n)
        data = self.create_data() if data is None else data
        pin.framesForwardKinematics(self.model, data, qv)
        return data.oMf[self.tip_frame_id].translation[:2].copy()

    def tip_jacobian(self, q: ArrayLike, data: pin.Data | None = None) -> Array:
        """Tip Jacobian ``dF/dq`` in [m/rad], shape (2, n), from Pinocchio."""
        return self.kinematics(q, data).jacobian

    def joint_positions(self, q: ArrayLike, data: pin.Data | None = None) -> Array:
        """Positions in [m] of joints 1..n and the tip, shape (n + 1, 2), for drawing."""
        qv = as_configuration(q, self.n)
        data = self.create_data() if data is None else data
        pin.framesForwardKinematics(self.model, data, qv)
        pts = [data.oMi[j].translation[:2] for j in range(1, self.n + 1)]
        pts.append(data.oMf[self.tip_frame_id].translation[:2])
        return np.array(pts)

    def theta(self, q: ArrayLike) -> Array:
        """Return the study's angles ``theta = q + angle_offset`` in [rad]."""
        return as_configuration(q, self.n) + self.angle_offset


def _rebuild(spec: dict[str, Any]) -> PlanarChain:
    return PlanarChain(**spec)


def _build_models(chain: PlanarChain) -> tuple[pin.Model, pin.GeometryModel, int]:
    """Build the kinematic model and a primitive-shape visual model of ``chain``."""
    model = pin.Model()
    model.name = chain.name
    visual = pin.GeometryModel()
    radius = 0.04 * float(np.mean(chain.lengths))  # [m] drawing radius of the links
    along_x = pin.SE3(pin.utils.rotate("y", math.pi / 2.0), np.zeros(3))
    parent = 0
    placement = pin.SE3(pin.utils.rotate("z", float(chain.angle_offset[0])), np.r_[chain.base, 0.0])
    for i, length in enumerate(chain.lengths):
        jid = model.addJoint(parent, pin.JointModelRZ(), placement, f"joint_{i + 1}")
        model.addJointFrame(jid, -1)
        body = pin.SE3(along_x.rotation, np.array([length / 2.0, 0.0, 0.0]))
        link = pin.GeometryObject(f"link_{i + 1}", jid, body, coal.Cylinder(radius, float(length)))
        link.meshColor = _LINK_RGBA
        visual.addGeometryObject(link)
        ball = pin.GeometryObject(
            f"joint_{i + 1}_ball", jid, pin.SE3.Identity(), coal.Sphere(1.5 * radius)
        )
        ball.meshColor = _JOINT_RGBA
        visual.addGeometryObject(ball)
        parent = jid
        nxt = float(chain.angle_offset[i + 1]) if i + 1 < chain.n else 0.0
        placement = pin.SE3(pin.utils.rotate("z", nxt), np.array([length, 0.0, 0.0]))
    tip_id = model.addFrame(pin.Frame(chain.tip_frame, parent, placement, pin.FrameType.OP_FRAME))
    tip_ball = pin.GeometryObject("tip_ball", parent, placement, coal.Sphere(radius))
    tip_ball.meshColor = _JOINT_RGBA
    visual.addGeometryObject(tip_ball)
    model.lowerPositionLimit = np.where(np.isfinite(chain.q_lower), chain.q_lower, -_PIN_INF)
    model.upperPositionLimit = np.where(np.isfinite(chain.q_upper), chain.q_upper, _PIN_INF)
    return model, visual, int(tip_id)


_CHECK_TOL = 1e-10  # [m] largest accepted tip mismatch between chain and robot


def chain_from_robot(
    robot: RobotModel, frame: str | None = None, *, name: str | None = None
) -> PlanarChain:
    """Build the planar chain equivalent to a robot that is planar for ``frame``.

    The robot must be planar for the frame (:func:`motion_plane`: revolute
    joints about parallel axes) and every joint that moves it must turn the
    same way about the plane normal ``n``. The chain's coordinates are the
    robot's joint angles and its positions the plane coordinates; its base,
    lengths and ``angle_offset`` are read from the joint origins and the frame
    at ``q = 0``, its limits are the robot's (continuous joints and limits
    beyond 1e10: none), and it is then checked against Pinocchio's placement of
    the frame at 20 seeded configurations (1e-10 m). The youBot arm (joints
    about the platform's -y, plane (x, z)) is a chain with ``base = (a, h) =
    (0.184, 0.147)`` m and ``angle_offset = (pi/2, 0, 0)``: q = 0 points up
    and a positive angle turns towards -x (spec ``trajopt.md``).

    Parameters
    ----------
    robot : RobotModel
        A loaded robot (``load_model("youbot")``).
    frame : str, optional
        The frame (default ``robot.tip_frame``).
    name : str, optional
        Chain name (default: the robot's).

    Returns
    -------
    PlanarChain
        Coordinates ``q`` equal the robot's angles of the joints that move the
        frame; positions are plane coordinates in [m].

    Raises
    ------
    ModelError
        If the robot is not a planar revolute chain for the frame (the message
        says why).
    """
    model: pin.Model = robot.model
    frame = robot.tip_frame if frame is None else frame
    fid = robot.frame_id(frame)
    support = [j for j in model.supports[model.frames[fid].parentJoint] if j > 0]
    q0 = pin.neutral(model)
    plane = motion_plane(model, fid, q0)
    if plane is None or any(model.joints[j].nq != 1 for j in support):
        raise ModelError(
            f"robot {robot.name!r} is not a planar revolute chain for frame {frame!r}: its "
            "joints are not all revolute about parallel axes"
        )
    data = model.createData()
    pin.computeJointJacobians(model, data, q0)
    pin.updateFramePlacements(model, data)
    for j in support:
        jac = np.reshape(pin.getJointJacobian(model, data, j, pin.WORLD), (6, model.nv))
        if float(jac[3:, model.joints[j].idx_v] @ plane.normal) < 0.0:
            raise ModelError(
                f"robot {robot.name!r} is not a planar chain for frame {frame!r}: joint "
                f"{model.names[j]!r} turns against the first joint's axis"
            )
    basis = plane.basis
    points = [data.oMi[j].translation @ basis for j in support]
    points.append(data.oMf[fid].translation @ basis)
    segments = np.diff(np.array(points), axis=0)
    lengths = np.linalg.norm(segments, axis=1)
    if np.any(lengths <= 1e-9):
        raise ModelError(
            f"robot {robot.name!r} is not a planar revolute chain for frame {frame!r}: "
            f"segment lengths in its plane are {lengths.tolist()} m (a zero one)"
        )
    phi = np.arctan2(segments[:, 1], segments[:, 0])
    offset = np.diff(np.r_[0.0, phi])
    offset = np.arctan2(np.sin(offset), np.cos(offset))
    idx = [model.joints[j].idx_q for j in support]
    lo = np.array([model.lowerPositionLimit[i] for i in idx], dtype=np.float64)
    hi = np.array([model.upperPositionLimit[i] for i in idx], dtype=np.float64)
    lo = np.where(lo <= -1e10, -np.inf, lo)
    hi = np.where(hi >= 1e10, np.inf, hi)
    chain = PlanarChain(
        lengths=lengths,
        q_lower=lo,
        q_upper=hi,
        base=points[0],
        angle_offset=offset,
        name=name or str(robot.name),
        tip_frame=str(frame),
    )
    rng = np.random.default_rng(0)
    lo_s = np.maximum(chain.q_lower, -math.pi)
    hi_s = np.minimum(chain.q_upper, math.pi)
    worst = 0.0
    q = q0.copy()
    for theta in rng.uniform(lo_s, hi_s, (20, len(support))):
        q[idx] = theta
        pin.framesForwardKinematics(model, data, q)
        ref = data.oMf[fid].translation @ basis
        worst = max(worst, float(np.linalg.norm(chain.tip_position(theta) - ref)))
    if worst > _CHECK_TOL:
        raise ModelError(
            f"robot {robot.name!r} is not a planar revolute chain for frame {frame!r}: the "
            f"equivalent chain misses the frame by {worst:.3g} m (tolerance {_CHECK_TOL:g} m)"
        )
    return chain


def youbot_chain() -> PlanarChain:
    """Return the youBot arm (``load_model("youbot")``) as a planar chain."""
    return chain_from_robot(load_model("youbot"))
