"""What a loaded robot is: :class:`RobotModel`, its joint bounds and its kinematics.

A :class:`RobotModel` is an immutable bundle of the Pinocchio model, its visual
and collision geometry, the end-effector frame and the SI joint limits, passed
explicitly to everything that needs dynamics (data objects from
:meth:`RobotModel.create_data`; bounds from :meth:`RobotModel.bounds`).
:func:`frame_placement` gives any frame's placement; :func:`tip_pose` owns the
study's planar convention (spec ``trajopt.md``). Loading is
:func:`youbot_opt.robot.load.load_model`.

>>> pose = tip_pose(load_model("youbot"), [0.0, 0.0, 0.0])  # doctest: +SKIP
"""

from __future__ import annotations

import hashlib
import threading
import weakref
from collections.abc import Callable
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Literal, NamedTuple

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike

from youbot_opt._checks import check_bound_scale
from youbot_opt._typing import Array
from youbot_opt.exceptions import FrameNotFound, ParameterError
from youbot_opt.robot.packed import PackedGeometry, pack_geometry
from youbot_opt.robot.payload import Payload, add_payload

__all__ = [
    "RobotModel",
    "GeometryBuilder",
    "LazyGeometry",
    "JointBounds",
    "JointUnits",
    "REVOLUTE_UNITS",
    "PRISMATIC_UNITS",
    "BoundFamily",
    "BOUND_FAMILIES",
    "TipPose",
    "as_configuration",
    "as_robot_model",
    "tip_pose",
    "frame_placement",
]

BoundFamily = Literal["position", "velocity", "torque"]
BOUND_FAMILIES: tuple[BoundFamily, ...] = ("position", "velocity", "torque")
"""The joint-bound families :meth:`RobotModel.bounds` can scale (all of them by default)."""


@dataclass(frozen=True, slots=True, kw_only=True)
class JointBounds:
    """Box bounds on joint positions, velocities and torques, already scaled.

    Attributes
    ----------
    q_lower, q_upper : ndarray, shape (nv,)
        Position bounds in [rad].
    v_lower, v_upper : ndarray, shape (nv,)
        Velocity bounds in [rad/s].
    tau_lower, tau_upper : ndarray, shape (nv,)
        Torque bounds in [N m].
    """

    q_lower: Array
    q_upper: Array
    v_lower: Array
    v_upper: Array
    tau_lower: Array
    tau_upper: Array

    def violation(self, q: Array, v: Array, tau: Array) -> float:
        """Largest bound violation (>= 0) of knot-major arrays, in their units.

        Parameters
        ----------
        q, v, tau : ndarray, shape (n, nv) or (nv,)
            Positions [rad], velocities [rad/s] and torques [N m].

        Returns
        -------
        float
            The largest excess over a bound, 0 if every value is inside.
        """
        worst = 0.0
        for x, lo, hi in (
            (q, self.q_lower, self.q_upper),
            (v, self.v_lower, self.v_upper),
            (tau, self.tau_lower, self.tau_upper),
        ):
            x = np.atleast_2d(x)
            worst = max(
                worst, float(np.max(lo - x, initial=0.0)), float(np.max(x - hi, initial=0.0))
            )
        return worst


class JointUnits(NamedTuple):
    """The units of one joint coordinate's position, velocity and effort.

    Attributes
    ----------
    position, velocity, effort : str
        ``"rad"``, ``"rad/s"``, ``"N m"`` for a revolute joint; ``"m"``,
        ``"m/s"``, ``"N"`` for a prismatic one.
    prismatic : bool
        True for a prismatic (translating) joint.
    """

    position: str
    velocity: str
    effort: str
    prismatic: bool


REVOLUTE_UNITS = JointUnits("rad", "rad/s", "N m", False)
"""Units of a revolute (or continuous) joint coordinate."""
PRISMATIC_UNITS = JointUnits("m", "m/s", "N", True)
"""Units of a prismatic joint coordinate."""


_P, _R = PRISMATIC_UNITS, REVOLUTE_UNITS
_JOINT_UNITS: dict[str, list[JointUnits]] = {
    "JointModelPX": [_P],
    "JointModelPY": [_P],
    "JointModelPZ": [_P],
    "JointModelPrismaticUnaligned": [_P],
    "JointModelPlanar": [_P, _P, _R],
    "JointModelTranslation": [_P, _P, _P],
}  # Pinocchio's joint models with a translating coordinate; all others turn


class TipPose(NamedTuple):
    """End-effector pose in the platform's (x, z) plane.

    Attributes
    ----------
    position : numpy.ndarray
        Tip position ``(x, z)`` in [m], shape (2,).
    rotation : numpy.ndarray
        2-D rotation, shape (2, 2): column 0 is the tip frame's x axis and
        column 1 its y axis, both expressed in platform ``(x, z)``.
    """

    position: Array
    rotation: Array


def _read_only(a: ArrayLike) -> Array:
    out = np.array(a, dtype=float)
    out.setflags(write=False)
    return out


GeometryBuilder = Callable[[], pin.GeometryModel]
"""A function (picklable: a frozen dataclass with ``__call__``) that builds a geometry model."""

_BUILD_LOCK = threading.RLock()


class LazyGeometry:
    """A dataclass field holding a ``pinocchio.GeometryModel``, or the function that builds it.

    Assigned a :data:`GeometryBuilder`, the field calls it on its first read and
    keeps what it returns: a robot's visual meshes (0.27 s for ur5's ``.dae``
    files) are read only by the runs that draw. Assigned a ``GeometryModel``, it
    holds it. The field is the class attribute; the value lives in the
    instance's ``__dict__`` (so the dataclass may not use ``slots``).

    Parameters
    ----------
    name : str
        The field's name.
    """

    def __init__(self, name: str) -> None:
        self._key = f"{name}_value"
        self._name = name

    def __get__(self, obj: object, objtype: type | None = None) -> pin.GeometryModel:
        if obj is None:
            return self  # the class's attribute: the field's default marker
        value = obj.__dict__[self._key]
        if isinstance(value, pin.GeometryModel):
            return value
        with _BUILD_LOCK:  # two threads reading it first build it once
            value = obj.__dict__[self._key]
            if not isinstance(value, pin.GeometryModel):
                value = value()
                if not isinstance(value, pin.GeometryModel):
                    raise ParameterError(
                        f"the builder of {self._name} returned {type(value).__name__}, "
                        "expected a pinocchio.GeometryModel",
                        name=self._name,
                    )
                obj.__dict__[self._key] = value
        return value

    def __set__(self, obj: object, value: pin.GeometryModel | GeometryBuilder) -> None:
        if value is self:  # not given: no geometry
            value = pin.GeometryModel()
        if not (isinstance(value, pin.GeometryModel) or callable(value)):
            raise ParameterError(
                f"{self._name} must be a pinocchio.GeometryModel or a function building one, "
                f"got {type(value).__name__}",
                name=self._name,
                value=value,
            )
        obj.__dict__[self._key] = value

    def held(self, obj: object) -> pin.GeometryModel | GeometryBuilder:
        """Return what ``obj`` holds: the model, or its builder if it was never read."""
        value: pin.GeometryModel | GeometryBuilder = obj.__dict__[self._key]
        return value

    def is_built(self, obj: object) -> bool:
        """Return whether ``obj``'s geometry exists (given, or built by a read)."""
        return isinstance(obj.__dict__[self._key], pin.GeometryModel)


_VISUAL_FIELD = LazyGeometry("visual_model")


@dataclass(frozen=True, kw_only=True)
class RobotModel:
    """A loaded robot: Pinocchio model, geometry, tip frame and SI limits.

    Attributes
    ----------
    name : str
        Robot name (``"youbot"``, an example-robot-data name, or the URDF's).
    model : pinocchio.Model
        Kinematic and inertial model; treat as read-only.
    visual_model : pinocchio.GeometryModel
        Geometry to draw. It may be given as a :data:`GeometryBuilder`, called on
        the first read (:class:`LazyGeometry`): :func:`~youbot_opt.robot.load.load_model`
        does so, and a run that draws nothing never reads the meshes. Not
        compared by ``==`` (what a robot draws does not change what it is).
    collision_model : pinocchio.GeometryModel
        Geometry for collision checks.
    urdf_path : pathlib.Path or None
        File the model came from; None when built in memory from parameters.
    package_dirs : tuple of pathlib.Path
        Folders used to resolve ``package://`` mesh references.
    tip_frame : str
        Name of the end-effector frame.
    locked_joints : tuple of (str, float)
        Joints of the file locked at a position in [rad] or [m] (removed from
        the model by Pinocchio's reduced model); empty when none.
    strict : bool
        The inertia policy the file was loaded under (``load_model(strict=)``;
        False: ``--lenient``), so that it can be loaded again the same way;
        True for models built in memory.
    catalogue_name : str or None
        The name it was loaded by from the robots known by name
        (:func:`~youbot_opt.robot.catalogue.available_robots`), so that it can
        be loaded again by that name; None for a file loaded by path (whatever
        its ``<robot name>``) and for a model built in memory.
    payload : Payload or None
        The payload :attr:`model` carries (:meth:`with_payload`), its frame
        resolved; None when it carries none.

    Notes
    -----
    A robot pickles without its visual geometry (meshes to draw: 176 MB of
    ur5's 186 MB pickle), which is what a sweep sends to its workers with
    every task and receives back with every result. The process that pickled
    it puts it back on unpickling (results come back whole); any other process
    gets a robot with an empty :attr:`visual_model` (workers never draw; to draw
    elsewhere, load the robot again). A visual geometry never read travels as
    its builder instead (a few kB), and is built where it is first read. The
    collision geometry travels (a clearance needs it) packed, its meshes as
    arrays (:mod:`youbot_opt.robot.packed`: ur5's 9.9 MB as 0.14 MB), and the
    process that packed it gets its own model back.
    """

    name: str
    model: pin.Model
    visual_model: pin.GeometryModel = field(default=_VISUAL_FIELD, compare=False)  # noqa: RUF009
    collision_model: pin.GeometryModel
    urdf_path: Path | None
    package_dirs: tuple[Path, ...]
    tip_frame: str
    locked_joints: tuple[tuple[str, float], ...] = ()
    strict: bool = True
    catalogue_name: str | None = None
    payload: Payload | None = None

    def __post_init__(self) -> None:
        self.frame_id(self.tip_frame)  # raises FrameNotFound listing the frames

    def __reduce__(self) -> tuple[object, ...]:
        """Pickle without the visual geometry; this process restores it (see Notes).

        A visual geometry never read travels as its builder (a few kB: the
        receiver builds it if it draws).
        """
        state = self._state()
        if self.collision_model.ngeoms:
            state["collision_model"] = self._packed_collision()
        if not _VISUAL_FIELD.is_built(self):
            return (_unpickle_robot, (state, ""))
        state["visual_model"] = pin.GeometryModel()
        return (_unpickle_robot, (state, _hold_visual(self.visual_model)))

    def _packed_collision(self) -> PackedGeometry:
        """Return the collision geometry packed (:func:`pack_geometry`), packed once."""
        packed = self.__dict__.get("_packed_collision_value")
        if packed is None:
            packed = self.__dict__["_packed_collision_value"] = pack_geometry(self.collision_model)
        assert isinstance(packed, PackedGeometry)
        return packed

    def _state(self) -> dict[str, object]:
        """Return the fields by name, the visual geometry as held (unbuilt if never read)."""
        state = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "visual_model"}
        state["visual_model"] = _VISUAL_FIELD.held(self)
        return state

    def replace(self, **changes: object) -> RobotModel:
        """Return a copy with ``changes``, as :func:`dataclasses.replace`, the geometry unread.

        :func:`dataclasses.replace` reads every field, which builds a deferred
        visual geometry (:class:`LazyGeometry`); this keeps it as it is held.

        Parameters
        ----------
        **changes
            Fields and their new values (``model=``, ``collision_model=``, ...).

        Returns
        -------
        RobotModel
            The copy (checked as any new robot: the tip frame must exist).

        Raises
        ------
        ParameterError
            If a name is not a field of :class:`RobotModel`.
        """
        unknown = sorted(set(changes) - {f.name for f in fields(self)})
        if unknown:
            raise ParameterError(
                f"RobotModel has no field {unknown[0]!r}; its fields: "
                f"{', '.join(f.name for f in fields(self))}",
                name=unknown[0],
            )
        return RobotModel(**{**self._state(), **changes})  # type: ignore[arg-type]

    def with_payload(self, payload: Payload) -> RobotModel:
        """Return this robot carrying ``payload`` (:func:`~youbot_opt.robot.payload.add_payload`).

        Parameters
        ----------
        payload : Payload
            The payload; its ``frame`` None means :attr:`tip_frame`.

        Returns
        -------
        RobotModel
            A copy whose model has the payload's inertia added to the carrying
            frame's joint, and whose :attr:`payload` names the frame.

        Raises
        ------
        ParameterError
            If ``payload`` is not a :class:`Payload`, or this robot already
            carries one (attach one payload, the sum of what it carries, to the
            robot as loaded).
        FrameNotFound
            If the payload's frame is not a frame of the model.
        """
        if not isinstance(payload, Payload):
            raise ParameterError(
                f"payload must be a Payload, got {type(payload).__name__}", name="payload"
            )
        if self.payload is not None:
            raise ParameterError(
                f"robot {self.name!r} already carries a payload ({self.payload}); attach one "
                "payload to the robot as loaded",
                name="payload",
            )
        frame = self.tip_frame if payload.frame is None else payload.frame
        model = add_payload(self.model, self.frame_id(frame), payload)
        return self.replace(model=model, payload=replace(payload, frame=frame))

    @property
    def nq(self) -> int:
        """Size of the configuration vector."""
        return int(self.model.nq)

    @property
    def nv(self) -> int:
        """Size of the velocity vector."""
        return int(self.model.nv)

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Names of the moving joints, in configuration order (the universe excluded)."""
        return tuple(self.model.names[1:])

    @property
    def q_lower(self) -> Array:
        """Lower position limits in [rad] (or [m]), shape (nq,), read-only."""
        return _read_only(self.model.lowerPositionLimit)

    @property
    def q_upper(self) -> Array:
        """Upper position limits in [rad] (or [m]), shape (nq,), read-only."""
        return _read_only(self.model.upperPositionLimit)

    @property
    def velocity_limit(self) -> Array:
        """Symmetric speed limits in [rad/s] (or [m/s]), shape (nv,), read-only."""
        return _read_only(self.model.velocityLimit)

    @property
    def effort_limit(self) -> Array:
        """Symmetric effort limits in [N m] (or [N]), shape (nv,), read-only."""
        return _read_only(self.model.effortLimit)

    @property
    def damping(self) -> Array:
        """Viscous joint damping in [N m s/rad], shape (nv,), read-only."""
        return _read_only(self.model.damping)

    def joint_units(self) -> tuple[JointUnits, ...]:
        """Return the units of each velocity coordinate, shape (nv,): m, m/s, N if prismatic.

        Every printer and plotter of joint values reads its units here. A
        joint is prismatic when Pinocchio models it as one (``JointModelP*``);
        every other moving joint (revolute, continuous) is in rad, rad/s, N m.
        """
        units: list[JointUnits] = []
        for joint in self.model.joints[1:]:
            units += _JOINT_UNITS.get(joint.shortname(), [REVOLUTE_UNITS] * joint.nv)
        return tuple(units)

    def frame_id(self, name: str) -> int:
        """Return the index of frame ``name``.

        Parameters
        ----------
        name : str
            Frame name (a link, joint or operational frame).

        Returns
        -------
        int
            Index into ``model.frames``; when several frames share the name
            (a fixed joint and its child link), the link's.

        Raises
        ------
        FrameNotFound
            If the model has no such frame; the message lists the frames.
        """
        frames = self.model.frames
        matches = [i for i in range(len(frames)) if frames[i].name == name]
        if not isinstance(name, str) or not matches:
            raise FrameNotFound(str(name), tuple(f.name for f in frames))
        # A fixed joint and its child link may share a name: prefer the link (BODY) frame.
        bodies = [i for i in matches if frames[i].type == pin.FrameType.BODY]
        return int((bodies or matches)[0])

    def create_data(self) -> pin.Data:
        """Return a fresh ``pinocchio.Data`` for this model."""
        return self.model.createData()

    def bounds(
        self, scale: float = 1.0, *, families: tuple[BoundFamily, ...] = BOUND_FAMILIES
    ) -> JointBounds:
        """Return the joint bounds, the families in ``families`` multiplied by ``scale``.

        The one place where bounds are scaled (the study scaled all three
        families to 100, 95, 90 and 85 % of the data sheet). Position bounds
        are scaled about zero (``scale * q_lower``, ``scale * q_upper``);
        speed and torque bounds are symmetric.

        Parameters
        ----------
        scale : float
            Factor > 0 (1.0 = data sheet).
        families : tuple of {"position", "velocity", "torque"}
            The families scaled; the others keep their data-sheet values.

        Returns
        -------
        JointBounds
            Position [rad], velocity [rad/s] and torque [N m] bounds.

        Raises
        ------
        ParameterError
            If ``scale`` is not finite and > 0, or a family is unknown.
        """
        s = check_bound_scale(scale)
        bad = [f for f in families if f not in BOUND_FAMILIES]
        if bad:
            raise ParameterError(
                f"bound families must be among {BOUND_FAMILIES}, got {bad}", name="families"
            )

        def factor(family: BoundFamily) -> float:
            return s if family in families else 1.0

        vmax = factor("velocity") * np.asarray(self.model.velocityLimit, dtype=float)
        tmax = factor("torque") * np.asarray(self.model.effortLimit, dtype=float)
        return JointBounds(
            q_lower=factor("position") * np.asarray(self.model.lowerPositionLimit, dtype=float),
            q_upper=factor("position") * np.asarray(self.model.upperPositionLimit, dtype=float),
            v_lower=-vmax,
            v_upper=vmax,
            tau_lower=-tmax,
            tau_upper=tmax,
        )

    @classmethod
    def from_pin_model(cls, model: pin.Model, tip_frame: str | None = None) -> RobotModel:
        """Wrap a bare ``pinocchio.Model`` (no geometry, no file) as a :class:`RobotModel`.

        Its limits, damping and name are the model's own.

        Parameters
        ----------
        model : pinocchio.Model
            The kinematic and inertial model (not copied).
        tip_frame : str, optional
            End-effector frame; the model's last frame by default.

        Returns
        -------
        RobotModel
            The robot, with empty visual and collision geometry.

        Raises
        ------
        ParameterError
            If ``model`` is not a ``pinocchio.Model``.
        FrameNotFound
            If ``tip_frame`` is not a frame of the model.
        """
        if not isinstance(model, pin.Model):
            raise ParameterError(
                f"model must be a pinocchio.Model, got {type(model).__name__}", name="model"
            )
        tip = model.frames[len(model.frames) - 1].name if tip_frame is None else tip_frame
        return cls(
            name=str(model.name),
            model=model,
            visual_model=pin.GeometryModel(),
            collision_model=pin.GeometryModel(),
            urdf_path=None,
            package_dirs=(),
            tip_frame=tip,
        )


# Visual geometry of the robots pickled by this process, by a digest of what it
# draws: unpickling here puts it back (weak references: a robot dropped frees it).
_VISUALS: dict[str, weakref.ref[pin.GeometryModel]] = {}
_VISUALS_LOCK = threading.Lock()


def _visual_digest(visual: pin.GeometryModel) -> str:
    """Return a digest of what ``visual`` draws: names, frames, placements, meshes, colours."""
    h = hashlib.sha256()
    for go in visual.geometryObjects:
        h.update(
            "\0".join(
                [
                    go.name,
                    str(go.parentJoint),
                    str(go.parentFrame),
                    go.meshPath,
                    type(go.geometry).__name__,
                ]
            ).encode()
        )
        h.update(np.asarray(go.placement.homogeneous, dtype=float).tobytes())
        h.update(np.asarray(go.meshScale, dtype=float).tobytes())
        h.update(np.asarray(go.meshColor, dtype=float).tobytes())
    return f"{visual.ngeoms}:{h.hexdigest()}"


# The empty visual models of robots unpickled without their meshes -> the key of those
# meshes, which pickling such a robot again passes on (a worker's result goes home whole).
_AWAY: weakref.WeakKeyDictionary[pin.GeometryModel, str] = weakref.WeakKeyDictionary()


def _hold_visual(visual: pin.GeometryModel) -> str:
    """Remember ``visual`` for this process's unpickling; return its key ("" when none)."""
    if visual.ngeoms == 0:
        with _VISUALS_LOCK:
            return _AWAY.get(visual, "")
    key = _visual_digest(visual)  # content, not process: forked workers hold the same
    with _VISUALS_LOCK:
        for dead in [k for k, ref in _VISUALS.items() if ref() is None]:
            del _VISUALS[dead]
        _VISUALS[key] = weakref.ref(visual)
    return key


def _unpickle_robot(state: dict[str, object], visual_key: str) -> RobotModel:
    """Rebuild a pickled :class:`RobotModel`, its visual geometry if this process holds it."""
    packed = state["collision_model"]
    if isinstance(packed, PackedGeometry):
        state = {**state, "collision_model": packed.unpack()}
    if visual_key:
        with _VISUALS_LOCK:
            ref = _VISUALS.get(visual_key)
        visual = None if ref is None else ref()
        if visual is not None:
            state = {**state, "visual_model": visual}
        else:
            with _VISUALS_LOCK:
                _AWAY[state["visual_model"]] = visual_key  # type: ignore[index]
    return RobotModel(**state)  # type: ignore[arg-type]


def as_robot_model(robot: RobotModel | pin.Model) -> RobotModel:
    """Return ``robot`` as a :class:`RobotModel` (a bare ``pinocchio.Model`` is wrapped).

    Parameters
    ----------
    robot : RobotModel or pinocchio.Model
        The robot.

    Returns
    -------
    RobotModel
        ``robot`` itself, or :meth:`RobotModel.from_pin_model` of it.

    Raises
    ------
    ParameterError
        If ``robot`` is neither.
    """
    if isinstance(robot, RobotModel):
        return robot
    if isinstance(robot, pin.Model):
        return RobotModel.from_pin_model(robot)
    raise ParameterError(
        f"robot must be a RobotModel (load_model(...)) or a pinocchio.Model, "
        f"got {type(robot).__name__}",
        name="robot",
        value=type(robot).__name__,
    )


def as_configuration(robot: RobotModel, q: ArrayLike) -> Array:
    """Return ``q`` as a finite float array of the robot's configuration size.

    Parameters
    ----------
    robot : RobotModel
        The robot.
    q : array_like
        Configuration, shape (nq,), in [rad] (or [m]).

    Returns
    -------
    numpy.ndarray
        ``q`` as floats, shape (nq,).

    Raises
    ------
    ParameterError
        If ``q`` is not numeric, has another shape or is not finite.
    """
    try:
        arr = np.asarray(q, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ParameterError(
            f"q must be an array of {robot.nq} numbers in [rad], got {q!r}", name="q", value=q
        ) from exc
    if arr.shape != (robot.nq,):
        raise ParameterError(
            f"q must have shape ({robot.nq},) for robot {robot.name!r}, got shape {arr.shape}",
            name="q",
            value=q,
        )
    if not np.all(np.isfinite(arr)):
        raise ParameterError(f"q must be finite, got {arr}", name="q", value=q)
    return arr


def frame_placement(robot: RobotModel, q: ArrayLike, frame: str | None = None) -> pin.SE3:
    """Return the placement of a frame in the root (world/platform) frame.

    Parameters
    ----------
    robot : RobotModel
        The robot.
    q : array_like
        Configuration, shape (nq,), in [rad] (or [m]).
    frame : str, optional
        Frame name; defaults to ``robot.tip_frame``.

    Returns
    -------
    pinocchio.SE3
        ``oMf``: rotation and translation [m] of the frame in the root frame.

    Raises
    ------
    ParameterError
        Bad shape or non-finite ``q``.
    FrameNotFound
        Unknown frame.
    """
    fid = robot.frame_id(robot.tip_frame if frame is None else frame)
    qa = as_configuration(robot, q)
    data = robot.create_data()
    pin.framesForwardKinematics(robot.model, data, qa)
    return pin.SE3(data.oMf[fid])


def tip_pose(robot: RobotModel, q: ArrayLike) -> TipPose:
    """Return the tip pose in the platform's (x, z) plane (the study's convention).

    The arm of the study moves in the platform's x-z plane; the tip frame has
    its x axis along the last link and its z axis along platform -y. The 2-D
    rotation is the tip frame's (x, y) axes projected on platform (x, z).
    For a robot that does not move in that plane the projection is not a
    rotation; use :func:`frame_placement` instead.

    Parameters
    ----------
    robot : RobotModel
        The robot (normally the youBot arm).
    q : array_like
        Joint angles in [rad], shape (nq,).

    Returns
    -------
    TipPose
        Position (2,) in [m] and rotation (2, 2).

    Raises
    ------
    ParameterError
        Bad shape or non-finite ``q``.
    """
    placement = frame_placement(robot, q)
    rows = [0, 2]  # platform x and z
    position = _read_only(placement.translation[rows])
    rotation = _read_only(placement.rotation[np.ix_(rows, [0, 1])])
    return TipPose(position=position, rotation=rotation)
