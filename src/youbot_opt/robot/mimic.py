"""Mimic joints of a URDF file: never loaded as independent, actuated joints.

A URDF ``<mimic joint="j" multiplier="m" offset="o"/>`` couples a joint to
``q = m q_j + o``. Pinocchio builds such a file either as independent joints
(``mimic=False``, its default) or as ``JointModelMimic`` (``mimic=True``), which
the CasADi dynamics backends cannot transcribe. :func:`mimic_locks` therefore
gives the positions at which :func:`youbot_opt.robot.load.load_model` locks
them: the relation evaluated at the reference configuration (the neutral
configuration, or the user's ``lock_joints`` value of the mimicked joint),
with a :class:`~youbot_opt.exceptions.YoubotOptWarning` naming the joints.
See docs/design.md, "Mimic joints".
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import NamedTuple

import pinocchio as pin

from youbot_opt.exceptions import YoubotOptWarning
from youbot_opt.robot.urdf_check.size import SizeLimits
from youbot_opt.robot.urdf_check.xml import parse_xml_strict, root_of

__all__ = ["MimicJoint", "mimic_joints", "mimic_locks"]


class MimicJoint(NamedTuple):
    """One ``<mimic>`` relation ``q[name] = multiplier * q[mimicked] + offset`` ([rad] or [m])."""

    name: str
    mimicked: str
    multiplier: float
    offset: float


def mimic_joints(
    urdf_path: Path, *, size_limits: SizeLimits | None = None
) -> tuple[MimicJoint, ...]:
    """Read the ``<mimic>`` relations of a URDF file (already checked by the strict loader).

    Parameters
    ----------
    urdf_path : pathlib.Path
        The URDF file.
    size_limits : SizeLimits, optional
        Its XML nesting and element limits (as it was loaded with).

    Returns
    -------
    tuple of MimicJoint
        One per non-fixed joint with a ``<mimic>`` element, in file order.
    """
    data = urdf_path.read_bytes()
    if b"<mimic" not in data:
        return ()
    sizes = (size_limits if size_limits is not None else SizeLimits()).resolved()
    tree = parse_xml_strict(
        data, str(urdf_path), max_depth=sizes.max_xml_depth, max_elements=sizes.max_xml_elements
    )
    robot = root_of(tree, str(urdf_path))
    out = []
    for joint in robot.iter("joint"):
        mimic = joint.find("mimic")
        if mimic is None or joint.get("type") == "fixed":
            continue
        out.append(
            MimicJoint(
                name=str(joint.get("name")),
                mimicked=str(mimic.get("joint")),
                multiplier=float(mimic.get("multiplier", "1")),
                offset=float(mimic.get("offset", "0")),
            )
        )
    return tuple(out)


def mimic_locks(
    model: pin.Model,
    urdf_path: Path | None,
    locked: Mapping[str, float],
    robot_name: str,
    *,
    size_limits: SizeLimits | None = None,
) -> tuple[tuple[str, float], ...]:
    """Positions at which to lock the mimic joints of ``model`` not already in ``locked``.

    Parameters
    ----------
    model : pin.Model
        The model built with mimic joints as ordinary joints.
    urdf_path : pathlib.Path or None
        Its file (None: nothing to read, no mimic joints).
    locked : mapping of str to float
        Joints the user locks, with their positions in [rad] or [m].
    robot_name : str
        For the warning.
    size_limits : SizeLimits, optional
        The XML limits the file was loaded with (its defaults otherwise).

    Returns
    -------
    tuple of (str, float)
        ``(joint, position)`` pairs: ``multiplier * q_ref[mimicked] + offset``
        clipped to the joint's limits, where ``q_ref`` is 0 (the neutral
        configuration) unless the mimicked joint is in ``locked``.

    Warns
    -----
    YoubotOptWarning
        Naming every joint locked here, its relation and its position.
    """
    if urdf_path is None:
        return ()
    out = []
    notes = []
    for mimic in mimic_joints(urdf_path, size_limits=size_limits):
        if mimic.name in locked or not model.existJointName(mimic.name):
            continue
        joint = model.joints[model.getJointId(mimic.name)]
        value = mimic.multiplier * float(locked.get(mimic.mimicked, 0.0)) + mimic.offset
        if joint.nq == 1:
            lo = float(model.lowerPositionLimit[joint.idx_q])
            hi = float(model.upperPositionLimit[joint.idx_q])
            value = min(max(value, lo), hi) if math.isfinite(lo) and math.isfinite(hi) else value
        out.append((mimic.name, value))
        notes.append(
            f"{mimic.name} = {mimic.multiplier:g} * {mimic.mimicked} + {mimic.offset:g}, "
            f"locked at {value:g}"
        )
    if notes:
        warnings.warn(
            f"robot {robot_name!r} ({urdf_path}): {len(notes)} mimic joint(s) locked at the "
            f"reference configuration, because the dynamics backends do not model joint "
            f"coupling: {'; '.join(notes)}. Pass lock_joints={{...}} to choose the positions "
            "(a mimicked joint's locked value sets its mimic joints).",
            YoubotOptWarning,
            stacklevel=3,
        )
    return tuple(out)
