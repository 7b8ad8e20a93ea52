"""Robot models: load a URDF (the youBot arm, an example-robot-data robot, a file).

:func:`load_model` returns a :class:`RobotModel`, an immutable bundle of the
Pinocchio model, its visual and collision geometry, the end-effector frame and
the SI joint limits, passed explicitly to everything that needs dynamics (data
objects from :meth:`RobotModel.create_data`; bounds from :meth:`RobotModel.bounds`).
:func:`tip_pose` owns the study's planar convention (spec ``trajopt.md``).

>>> robot = load_model("youbot")  # doctest: +SKIP
>>> ur5 = load_model("ur5", lock_joints={"wrist_3_joint": 0.0})  # doctest: +SKIP
"""

from __future__ import annotations

import functools
import importlib.metadata
import logging
import math
import os
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal, NamedTuple

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike

from youbot_opt._checks import check_bound_scale
from youbot_opt._typing import Array
from youbot_opt.exceptions import FrameNotFound, ModelError, ParameterError, RobotNotFound
from youbot_opt.robot.params import YOUBOT_PLANAR, ArmParameters
from youbot_opt.robot.strict.limits import SizeLimits
from youbot_opt.robot.urdf import TIP_FRAME, urdf_string

__all__ = [
    "RobotModel",
    "SizeLimits",
    "JointBounds",
    "BoundFamily",
    "BOUND_FAMILIES",
    "check_bound_scale",
    "TipPose",
    "as_robot_model",
    "available_robots",
    "example_robots",
    "load_model",
    "tip_pose",
    "frame_placement",
    "youbot_urdf_path",
    "example_robot_data_dir",
]

_log = logging.getLogger(__name__)

YOUBOT = "youbot"
_YOUBOT_FILE = "youbot_arm_planar.urdf"
YOUBOT_ARM_5DOF = "youbot_arm_5dof"
_YOUBOT_5DOF_FILE = "youbot_arm_5dof.urdf"
_YOUBOT_5DOF_TIP = "gripper_palm_link"

# Short names kept from before the whole zoo loaded by name, and their tip frames:
# name -> (URDF path relative to example-robot-data's ``robots`` folder, default tip frame).
# Every other robot of example-robot-data is found in its folder (example_robots()).
_EXAMPLE_ROBOTS: dict[str, tuple[str, str]] = {
    "double_pendulum": ("double_pendulum_description/urdf/double_pendulum.urdf", "link2"),
    "ur3": ("ur_description/urdf/ur3_robot.urdf", "tool0"),
    "ur5": ("ur_description/urdf/ur5_robot.urdf", "tool0"),
    "ur10": ("ur_description/urdf/ur10_robot.urdf", "tool0"),
    "panda": ("panda_description/urdf/panda.urdf", "panda_hand_tcp"),
    "so101": ("so_arm_description/urdf/so101.urdf", "gripper_frame_link"),
    "z1": ("z1_description/urdf/z1.urdf", "gripperStator"),
    "xarm7": ("xarm_description/urdf/xarm7.urdf", "link_eef"),
}


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


@dataclass(frozen=True, slots=True, kw_only=True)
class RobotModel:
    """A loaded robot: Pinocchio model, geometry, tip frame and SI limits.

    Attributes
    ----------
    name : str
        Robot name (``"youbot"``, an example-robot-data name, or the URDF's).
    model : pinocchio.Model
        Kinematic and inertial model; treat as read-only.
    visual_model : pinocchio.GeometryModel
        Geometry to draw.
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
    """

    name: str
    model: pin.Model
    visual_model: pin.GeometryModel
    collision_model: pin.GeometryModel
    urdf_path: Path | None
    package_dirs: tuple[Path, ...]
    tip_frame: str
    locked_joints: tuple[tuple[str, float], ...] = ()
    strict: bool = True

    def __post_init__(self) -> None:
        self.frame_id(self.tip_frame)  # raises FrameNotFound listing the frames

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


def youbot_urdf_path() -> Path:
    """Return the committed youBot URDF (source checkout, else the packaged copy).

    Returns
    -------
    pathlib.Path
        ``<repo>/urdf/youbot_arm_planar.urdf`` if it exists, else
        ``youbot_opt/_urdf/youbot_arm_planar.urdf``.
    """
    return _committed_urdf(_YOUBOT_FILE)


def _committed_urdf(filename: str) -> Path:
    """Return ``urdf/<filename>`` of the source checkout, else the packaged copy."""
    repo = Path(__file__).resolve().parents[3] / "urdf" / filename
    if repo.is_file():
        return repo
    return Path(__file__).resolve().parents[1] / "_urdf" / filename


def example_robot_data_dir() -> Path:
    """Return example-robot-data's ``share`` folder (holds ``example-robot-data/robots``).

    Returns
    -------
    pathlib.Path
        The folder that ``package://example-robot-data/...`` references resolve against.

    Raises
    ------
    ModelError
        If example-robot-data is not installed (``pip install example-robot-data``).
    """
    try:
        dist = importlib.metadata.distribution("example-robot-data")
    except importlib.metadata.PackageNotFoundError as exc:
        raise ModelError(
            "example-robot-data is not installed; run `pip install example-robot-data`"
        ) from exc
    for f in dist.files or ():
        parts = f.parts
        for k in range(len(parts) - 1):
            if parts[k] == "example-robot-data" and parts[k + 1] == "robots":
                return Path(str(dist.locate_file(Path(*parts[:k]))))
    raise ModelError("example-robot-data is installed but ships no robots/ folder")


def _robots_folder() -> Path:
    return example_robot_data_dir() / "example-robot-data" / "robots"


@functools.cache
def _example_robots_cached(robots: Path) -> tuple[tuple[str, str], ...]:
    files = sorted(p.relative_to(robots).as_posix() for p in robots.rglob("*.urdf"))
    stems: dict[str, list[str]] = {}
    for rel in files:
        stems.setdefault(Path(rel).stem, []).append(rel)
    names = []
    for rel in files:
        stem = Path(rel).stem
        alias = _EXAMPLE_ROBOTS.get(stem)
        unique = len(stems[stem]) == 1 and (alias is None or alias[0] == rel)
        names.append((stem if unique else f"{Path(rel).parts[0]}/{stem}", rel))
    return tuple(names)


def example_robots() -> dict[str, Path]:
    """Return every robot of the installed example-robot-data: name -> URDF file.

    Found from the installed data (each ``*.urdf`` under its ``robots``
    folder), not from a list kept here. A robot is named by its file name
    without ``.urdf`` (``panda``, ``ur5_robot``, ``talos_left_arm``); a name
    shared by several files, or taken by a short name below, is qualified by
    its package folder (``anymal_b_simple_description/anymal``,
    ``ur_description/ur3``). The short names ``ur3``, ``ur5`` and ``ur10``
    (``ur*_robot``) are accepted by :func:`load_model` besides these.

    Returns
    -------
    dict of str to pathlib.Path
        One entry per URDF file, sorted by path.

    Raises
    ------
    ModelError
        If example-robot-data is not installed.
    """
    robots = _robots_folder()
    return {name: robots / rel for name, rel in _example_robots_cached(robots)}


def available_robots() -> tuple[str, ...]:
    """Return the robot names :func:`load_model` accepts.

    Returns
    -------
    tuple of str
        ``"youbot"``, ``"youbot_arm_5dof"``, the short example-robot-data names
        (``ur5``, ``panda``, ...), then every other robot of the installed
        example-robot-data (:func:`example_robots`; none when it is not installed).
    """
    try:
        zoo = tuple(example_robots())
    except ModelError:
        zoo = ()
    return tuple(dict.fromkeys((YOUBOT, YOUBOT_ARM_5DOF, *_EXAMPLE_ROBOTS, *zoo)))


def _example_source(name: str) -> tuple[Path, str | None] | None:
    """Return (URDF file, default tip frame) of an example-robot-data name, else None."""
    if name in _EXAMPLE_ROBOTS:
        rel, tip = _EXAMPLE_ROBOTS[name]
        return _robots_folder() / rel, tip
    try:
        zoo = example_robots()
    except ModelError:
        return None
    return (zoo[name], None) if name in zoo else None


def _example_package_dirs(path: Path) -> tuple[Path, ...]:
    """Package folders of example-robot-data if ``path`` lies in it, else ()."""
    try:
        share = example_robot_data_dir()
    except ModelError:
        return ()
    robots = share / "example-robot-data" / "robots"
    real = path.resolve()
    if real.is_relative_to(robots.resolve()):
        return (robots, share)
    return ()


def _build_pinocchio_models(
    path: Path,
    package_dirs: tuple[Path, ...],
    *,
    strict: bool = True,
    locked: frozenset[str] = frozenset(),
    size_limits: SizeLimits | None = None,
) -> tuple[pin.Model, pin.GeometryModel, pin.GeometryModel]:
    """Build (model, visual, collision) from a URDF file; the single Pinocchio entry point."""
    if not path.is_file():
        raise RobotNotFound(
            f"URDF file {str(path)!r} does not exist", path=str(path), available=available_robots()
        )
    from youbot_opt.robot.strict.loader import load_urdf_strict

    # The strict loader refuses malformed XML, DOCTYPE/entities, resources outside
    # ``package_dirs`` and physically invalid models, each with a URDFError (a ModelError).
    loaded = load_urdf_strict(
        path, package_dirs, strict=strict, locked=locked, size_limits=size_limits
    )
    model, visual, collision = loaded.model, loaded.visual_model, loaded.collision_model
    return model, visual, collision


def _check_damping(damping: float | None) -> float | None:
    """Return ``damping`` as a float (None passes), else raise ParameterError."""
    if damping is None:
        return None
    if isinstance(damping, bool) or not isinstance(damping, int | float):
        raise ParameterError(
            f"damping must be a number in [N m s/rad], got {damping!r}",
            name="damping",
            value=damping,
        )
    if not math.isfinite(damping) or damping < 0:
        raise ParameterError(
            f"damping must be finite and >= 0 in [N m s/rad], got {damping!r}",
            name="damping",
            value=damping,
        )
    return float(damping)


def _check_lock(
    model: pin.Model, lock_joints: Mapping[str, float]
) -> tuple[tuple[str, float], ...]:
    """Validate ``lock_joints`` against the model: known 1-dof joints, finite in-limit values."""
    if not isinstance(lock_joints, Mapping):
        raise ParameterError(
            f"lock_joints must be a mapping {{joint name: position}}, got {lock_joints!r}",
            name="lock_joints",
            value=lock_joints,
        )
    movable = tuple(model.names[1:])
    checked = []
    for name, value in lock_joints.items():
        if name not in movable:
            raise ParameterError(
                f"lock_joints: {name!r} is not a movable joint of the robot; "
                f"its joints are {list(movable)}",
                name="lock_joints",
                value=name,
            )
        joint = model.joints[model.getJointId(name)]
        if (
            isinstance(value, bool)
            or not isinstance(value, int | float)
            or not math.isfinite(value)
        ):
            raise ParameterError(
                f"lock_joints: the position of {name!r} must be a finite number "
                f"in [rad] or [m], got {value!r}",
                name="lock_joints",
                value=value,
            )
        if joint.nv != 1:
            raise ParameterError(
                f"lock_joints: joint {name!r} ({joint.shortname()}) has {joint.nv} velocity "
                "coordinates; only 1-dof joints (revolute, prismatic, continuous) can be locked",
                name="lock_joints",
                value=name,
            )
        if joint.nq == 1:
            lo, hi = model.lowerPositionLimit[joint.idx_q], model.upperPositionLimit[joint.idx_q]
            if not lo <= value <= hi:
                raise ParameterError(
                    f"lock_joints: {name!r} = {value} is outside its limits [{lo}, {hi}]",
                    name="lock_joints",
                    value=value,
                )
        checked.append((str(name), float(value)))
    return tuple(checked)


def _lock(
    model: pin.Model,
    visual: pin.GeometryModel,
    collision: pin.GeometryModel,
    locked: tuple[tuple[str, float], ...],
) -> tuple[pin.Model, pin.GeometryModel, pin.GeometryModel]:
    """Build Pinocchio's reduced model with the ``locked`` joints held at their positions."""
    if not locked:
        return model, visual, collision
    q_ref = pin.neutral(model)
    ids = []
    for name, value in locked:
        jid = model.getJointId(name)
        joint = model.joints[jid]
        if joint.nq == 1:
            q_ref[joint.idx_q] = value
        else:  # continuous: (cos, sin) of the angle
            q_ref[joint.idx_q : joint.idx_q + 2] = (math.cos(value), math.sin(value))
        ids.append(jid)
    reduced, (vis, col) = pin.buildReducedModel(model, [visual, collision], ids, q_ref)
    reduced.name = model.name
    return reduced, vis, col


def load_model(
    source: str | os.PathLike[str] | ArmParameters = YOUBOT,
    *,
    tip_frame: str | None = None,
    package_dirs: Sequence[str | os.PathLike[str]] | None = None,
    damping: float | None = None,
    strict: bool = True,
    lock_joints: Mapping[str, float] | None = None,
    size_limits: SizeLimits | None = None,
) -> RobotModel:
    """Load a robot model.

    Parameters
    ----------
    source : str, os.PathLike or ArmParameters
        ``"youbot"`` (default): the committed ``urdf/youbot_arm_planar.urdf``
        (generated by :mod:`youbot_opt.robot.urdf`; in a non-editable install
        the copy packaged as ``youbot_opt/_urdf/``); ``"youbot_arm_5dof"``: the
        real 5-DOF arm with its gripper (``urdf/youbot_arm_5dof.urdf``); a name
        from :func:`available_robots`: every URDF of the installed
        example-robot-data, found in its ``robots`` folder
        (:func:`example_robots`), loaded with a fixed base; a path to a URDF
        file (its package folders are found when it lies in
        example-robot-data); or :class:`~youbot_opt.robot.params.ArmParameters`
        to build the youBot URDF from (e.g. with other damping or scaled limits).
    tip_frame : str, optional
        End-effector frame; defaults to ``"gripper_tip"`` for the youBot,
        ``"gripper_palm_link"`` for ``"youbot_arm_5dof"``, the table's frame
        for the short example-robot-data names and the last frame of the
        model otherwise.
    package_dirs : sequence of path-like, optional
        Extra folders for ``package://`` mesh references (the example-robot-data
        folders are added for its robots and for files inside it; a file's own
        folder is added for files).
    damping : float, optional
        Viscous damping of every joint in [N m s/rad], overriding the URDF's
        ``<dynamics damping>`` (for ``ArmParameters`` it is written into the
        generated URDF).
    strict : bool
        True (default) refuses a physically implausible inertia on a moving
        link; False loads it with a :class:`~youbot_opt.exceptions.YoubotOptWarning`.
        Implausible inertias on links welded to the world always load with a
        warning (:func:`youbot_opt.robot.strict.loader.inertia_policy`).
    lock_joints : mapping of str to float, optional
        Joints to lock, with their positions in [rad] or [m] (a continuous
        joint's angle in [rad]); built with Pinocchio's reduced model
        (``buildReducedModel``) on the model and both geometry models. Links
        behind locked joints count as welded for the inertia policy.
    size_limits : SizeLimits, optional
        Size limits of the URDF file, each a count (an integer >= 1): joints
        (``max_joints``, default 1000), degrees of freedom (``max_dof``, 100),
        longest joint chain (``max_tree_depth``, 500), XML nesting
        (``max_xml_depth``, 100 levels) and XML elements (``max_xml_elements``,
        200,000). A limit left None takes its environment variable
        (``YOUBOT_OPT_MAX_JOINTS``, ``YOUBOT_OPT_MAX_DOF``,
        ``YOUBOT_OPT_MAX_TREE_DEPTH``, ``YOUBOT_OPT_MAX_XML_DEPTH``,
        ``YOUBOT_OPT_MAX_XML_ELEMENTS``) when set, else the default
        (:class:`~youbot_opt.robot.strict.limits.SizeLimits`). Example:
        ``load_model("big.urdf", size_limits=SizeLimits(max_joints=5000))``.

    Returns
    -------
    RobotModel
        The loaded robot.

    Raises
    ------
    RobotNotFound
        Unknown name (the message lists :func:`available_robots`) or missing file.
    ModelError
        The file is not a loadable URDF (an implausible inertia on a moving
        link under ``strict``: the message says how to load it anyway).
    FrameNotFound
        ``tip_frame`` is not a frame of the (reduced) model.
    ParameterError
        ``damping`` is negative or not finite; ``lock_joints`` names an unknown
        or multi-dof joint, or a position that is not finite or outside the
        limits; ``size_limits`` is not a :class:`SizeLimits`, or a limit in it
        (or its environment variable) is not an integer >= 1.
    UnsafeURDFError
        The file exceeds a size limit (the message names the count, the limit
        and how to raise it).
    """
    if size_limits is not None and not isinstance(size_limits, SizeLimits):
        raise ParameterError(
            "size_limits must be a SizeLimits (e.g. SizeLimits(max_joints=5000)) or None, "
            f"got {type(size_limits).__name__} {size_limits!r}",
            name="size_limits",
            value=size_limits,
        )
    sizes = (size_limits or SizeLimits()).resolved()  # a bad environment variable fails here
    extra = tuple(Path(p) for p in (package_dirs or ()))
    damping = _check_damping(damping)
    gravity: float | None = None
    locked_names = frozenset(str(k) for k in (lock_joints or {}))
    tip: str | None
    if isinstance(source, ArmParameters):
        gravity = source.gravity
        text = urdf_string(source, damping=damping)
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / _YOUBOT_FILE
            path.write_text(text, encoding="utf-8")
            built = _build_pinocchio_models(
                path, extra, strict=strict, locked=locked_names, size_limits=sizes
            )
        name, urdf_path, dirs, tip = source.name, None, extra, TIP_FRAME
    elif isinstance(source, str) and source in (YOUBOT, YOUBOT_ARM_5DOF):
        five = source == YOUBOT_ARM_5DOF
        gravity = None if five else YOUBOT_PLANAR.gravity
        urdf_path = _committed_urdf(_YOUBOT_5DOF_FILE if five else _YOUBOT_FILE)
        dirs = (urdf_path.parent, *extra)
        built = _build_pinocchio_models(
            urdf_path, dirs, strict=strict, locked=locked_names, size_limits=sizes
        )
        name, tip = source, (_YOUBOT_5DOF_TIP if five else TIP_FRAME)
    elif isinstance(source, str) and (found := _example_source(source)) is not None:
        urdf_path, tip = found
        dirs = (*_example_package_dirs(urdf_path), *extra)
        built = _build_pinocchio_models(
            urdf_path, dirs, strict=strict, locked=locked_names, size_limits=sizes
        )
        name = source
    elif isinstance(source, str | os.PathLike):
        urdf_path = Path(source)
        try:
            is_file = urdf_path.is_file()
        except OSError:  # e.g. a name longer than the file system allows
            is_file = False
        if not is_file:
            raise RobotNotFound(
                f"{str(source)!r} is neither a robot name (`youbot-opt robots` lists them: "
                f"{', '.join(available_robots()[:10])}, ...) nor an existing URDF file",
                available=available_robots(),
                path=str(source),
            )
        urdf_path = urdf_path.resolve()
        dirs = (urdf_path.parent, *_example_package_dirs(urdf_path), *extra)
        built = _build_pinocchio_models(
            urdf_path, dirs, strict=strict, locked=locked_names, size_limits=sizes
        )
        name, tip = built[0].name or urdf_path.stem, None
    else:
        raise ParameterError(
            "source must be a robot name, a URDF path or ArmParameters, "
            f"got {type(source).__name__}",
            name="source",
            value=source,
        )
    model, visual, collision = built
    locked = _check_lock(model, lock_joints) if lock_joints is not None else ()
    from youbot_opt.robot.mimic import mimic_locks  # never independent: locked, with a warning

    locked = (
        *locked,
        *mimic_locks(model, urdf_path, dict(locked), str(name), size_limits=sizes),
    )
    model, visual, collision = _lock(model, visual, collision, locked)
    if damping is not None:
        model.damping = np.full(model.nv, damping)
    if gravity is not None:
        model.gravity.linear = np.array([0.0, 0.0, -gravity])
    if tip is None:
        tip = model.frames[len(model.frames) - 1].name
    _log.debug("loaded %s from %s (nq=%d, locked %s)", name, urdf_path, model.nq, locked)
    return RobotModel(
        name=name,
        model=model,
        visual_model=visual,
        collision_model=collision,
        urdf_path=urdf_path,
        package_dirs=dirs,
        tip_frame=tip if tip_frame is None else tip_frame,
        locked_joints=locked,
        strict=bool(strict),
    )


def as_configuration(robot: RobotModel, q: ArrayLike) -> Array:
    """Return ``q`` as a finite float array of shape (nq,), else raise ParameterError."""
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
