"""Loading a robot: :func:`load_model` from a name, a URDF file or arm parameters.

The file goes through the hostile-URDF policy (:mod:`youbot_opt.robot.urdf_check`),
then joints are locked (asked for, or mimic joints) with Pinocchio's reduced
model, and damping and gravity overrides are applied. Package folders for
``package://`` references are the file's own, example-robot-data's and the
caller's.

>>> robot = load_model("youbot")  # doctest: +SKIP
>>> ur5 = load_model("ur5", lock_joints={"wrist_3_joint": 0.0})  # doctest: +SKIP
"""

from __future__ import annotations

import dataclasses
import functools
import logging
import math
import os
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pinocchio as pin

from youbot_opt._files import file_kind
from youbot_opt.exceptions import ParameterError, RobotNotFound
from youbot_opt.robot.catalogue import (
    YOUBOT,
    YOUBOT_ARM_5DOF,
    available_robots,
    example_package_dirs,
    find_robot,
)
from youbot_opt.robot.mimic import mimic_locks
from youbot_opt.robot.mjcf import is_mjcf, load_mjcf_strict
from youbot_opt.robot.model import RobotModel
from youbot_opt.robot.params import YOUBOT_PLANAR, ArmParameters
from youbot_opt.robot.payload import Payload
from youbot_opt.robot.urdf import TIP_FRAME, urdf_string
from youbot_opt.robot.urdf_check.loader import (
    LoadedURDF,
    VisualBuilder,
    load_urdf_strict,
    locked_reference,
)
from youbot_opt.robot.urdf_check.size import SizeLimits

__all__ = ["MAX_JOINT_DAMPING", "load_model"]

MAX_JOINT_DAMPING = 1e6
"""Largest viscous joint damping [N m s/rad, or N s/m] a model may carry (override or URDF).

50 times the largest in example-robot-data (pr2's 2e4 N s/m); the youBot study
uses 0.1. Larger values describe no arm and only overflow the stiffness
analysis that chooses the transcription (1e308 ended in numpy's LinAlgError).
"""

_log = logging.getLogger(__name__)

#: File name of a youBot URDF built from ArmParameters (in a temporary folder).
_BUILT_FILE = "youbot_arm_planar.urdf"


def _build_pinocchio_models(
    path: Path,
    package_dirs: tuple[Path, ...],
    *,
    strict: bool = True,
    locked: frozenset[str] = frozenset(),
    size_limits: SizeLimits | None = None,
    defer_visual: bool = False,
) -> tuple[pin.Model, pin.GeometryModel | VisualBuilder, pin.GeometryModel]:
    """Build (model, visual, collision) from a URDF file; the single Pinocchio entry point.

    Under ``defer_visual`` the visual geometry is its :class:`VisualBuilder`.
    """
    if not path.is_file():
        raise RobotNotFound(
            f"URDF file {str(path)!r} does not exist", path=str(path), available=available_robots()
        )
    # The strict loader refuses malformed XML, DOCTYPE/entities, resources outside
    # ``package_dirs`` and physically invalid models, each with a URDFError (a ModelError).
    loaded = load_urdf_strict(
        path,
        package_dirs,
        strict=strict,
        locked=locked,
        size_limits=size_limits,
        defer_visual=defer_visual,
    )
    visual = LoadedURDF.visual_model.held(loaded)  # deferred: its builder, not read here
    return loaded.model, visual, loaded.collision_model


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
    if not math.isfinite(damping) or damping < 0 or damping > MAX_JOINT_DAMPING:
        raise ParameterError(
            f"damping must be in [0, MAX_JOINT_DAMPING = {MAX_JOINT_DAMPING:g}] N m s/rad, "
            f"got {damping!r}",
            name="damping",
            value=damping,
        )
    return float(damping)


def _check_model_damping(model: pin.Model, name: str) -> None:
    """Refuse a model whose file gives a joint more than :data:`MAX_JOINT_DAMPING`."""
    over = [
        (model.names[j], float(model.damping[model.joints[j].idx_v]))
        for j in range(1, model.njoints)
        if model.joints[j].nv == 1 and model.damping[model.joints[j].idx_v] > MAX_JOINT_DAMPING
    ]
    if over:
        joints = ", ".join(f"{joint} ({b:.3g})" for joint, b in over)
        raise ParameterError(
            f"{name}: joint damping over MAX_JOINT_DAMPING = {MAX_JOINT_DAMPING:g} N m s/rad: "
            f"{joints}; pass damping= to override it",
            name="damping",
        )


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
    visual: pin.GeometryModel | VisualBuilder,
    collision: pin.GeometryModel,
    locked: tuple[tuple[str, float], ...],
) -> tuple[pin.Model, pin.GeometryModel | VisualBuilder, pin.GeometryModel]:
    """Build Pinocchio's reduced model with the ``locked`` joints held at their positions.

    A visual geometry not built yet (a :class:`VisualBuilder`) is reduced when built.
    """
    if not locked:
        return model, visual, collision
    ids, q_ref = locked_reference(model, locked)
    if isinstance(visual, VisualBuilder):
        reduced, (col,) = pin.buildReducedModel(model, [collision], ids, q_ref)
        vis: pin.GeometryModel | VisualBuilder = dataclasses.replace(visual, locked=locked)
    else:
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
    payload: Payload | None = None,
    defer_visual: bool = False,
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
        warning (:func:`youbot_opt.robot.urdf_check.loader.inertia_policy`).
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
        (:class:`~youbot_opt.robot.urdf_check.size.SizeLimits`). Example:
        ``load_model("big.urdf", size_limits=SizeLimits(max_joints=5000))``.
    payload : Payload, optional
        A payload the robot carries (:meth:`RobotModel.with_payload`), in its
        frame (the tip frame when the payload names none).
    defer_visual : bool
        False (default): the visual geometry (meshes to draw) is read here.
        True: read on the first read of :attr:`RobotModel.visual_model` (a URDF's;
        an MJCF file's is read here): a run that draws nothing, or draws in
        another process, does not read them (ur5's: 0.27 s). Every mesh
        reference is checked here either way; the files must still be there
        when the geometry is read.

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
        ``tip_frame`` (or the payload's frame) is not a frame of the (reduced) model.
    ParameterError
        ``damping`` is negative, not finite or over :data:`MAX_JOINT_DAMPING`
        (also a joint's ``<dynamics damping>`` when not overridden);
        ``lock_joints`` names an unknown or multi-dof joint, or a position that
        is not finite or outside the limits; ``size_limits`` is not a
        :class:`SizeLimits`, or a limit in it (or its environment variable) is
        not an integer >= 1.
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
    build = functools.partial(
        _build_pinocchio_models,
        strict=strict,
        locked=locked_names,
        size_limits=sizes,
        defer_visual=defer_visual,
    )
    catalogue_name: str | None = None  # set only when loaded by name from the catalogue
    mimic_source: Path | None = None  # the URDF whose <mimic> joints are locked
    if isinstance(source, ArmParameters):
        gravity = source.gravity
        text = urdf_string(source, damping=damping)
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / _BUILT_FILE
            path.write_text(text, encoding="utf-8")
            built = build(path, extra)
        name, urdf_path, dirs, tip = source.name, None, extra, TIP_FRAME
    elif isinstance(source, str) and (found := find_robot(source)) is not None:
        urdf_path, tip = found
        if source in (YOUBOT, YOUBOT_ARM_5DOF):
            gravity = YOUBOT_PLANAR.gravity if source == YOUBOT else None
            dirs = (urdf_path.parent, *extra)
        else:
            dirs = (*example_package_dirs(urdf_path), *extra)
        built = build(urdf_path, dirs)
        name = catalogue_name = source
        mimic_source = urdf_path
    elif isinstance(source, str | os.PathLike):
        urdf_path = Path(source)
        try:
            is_file = urdf_path.is_file()
        except OSError:  # e.g. a name longer than the file system allows
            is_file = False
        if not is_file:
            try:  # a FIFO or device: say what it is (it is never opened)
                what = f" ({str(source)!r} is {file_kind(urdf_path.stat().st_mode)})"
            except OSError:
                what = ""
            raise RobotNotFound(
                f"{str(source)!r} is neither a robot name (`youbot-opt robots` lists them: "
                f"{', '.join(available_robots()[:10])}, ...) nor an existing URDF file{what}",
                available=available_robots(),
                path=str(source),
            )
        urdf_path = urdf_path.resolve()
        dirs = (urdf_path.parent, *example_package_dirs(urdf_path), *extra)
        if is_mjcf(urdf_path):
            mjcf = load_mjcf_strict(urdf_path, strict=strict, size_limits=sizes)
            built = (mjcf.model, mjcf.visual_model, mjcf.collision_model)
            mimic_source = None  # MJCF has no <mimic>; equality couplings are refused
        else:
            built = build(urdf_path, dirs)
            mimic_source = urdf_path
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
    # mimic joints are never independent: locked, with a warning
    locked = (
        *locked,
        *mimic_locks(model, mimic_source, dict(locked), str(name), size_limits=sizes),
    )
    model, visual, collision = _lock(model, visual, collision, locked)
    if damping is not None:
        model.damping = np.full(model.nv, damping)
    _check_model_damping(model, str(urdf_path))
    if gravity is not None:
        model.gravity.linear = np.array([0.0, 0.0, -gravity])
    if tip is None:
        tip = model.frames[len(model.frames) - 1].name
    _log.debug("loaded %s from %s (nq=%d, locked %s)", name, urdf_path, model.nq, locked)
    robot = RobotModel(
        name=name,
        model=model,
        visual_model=visual,
        collision_model=collision,
        urdf_path=urdf_path,
        package_dirs=dirs,
        tip_frame=tip if tip_frame is None else tip_frame,
        locked_joints=locked,
        strict=bool(strict),
        catalogue_name=catalogue_name,
    )
    return robot if payload is None else robot.with_payload(payload)
