"""Real planar arms as IK-path chains: the youBot arm (spec ``trajopt.md``, "The arm").

:func:`chain_from_robot` turns a loaded :class:`~youbot_opt.robot.model.RobotModel`
whose joints all turn about the platform's y axis into a
:class:`~youbot_opt.ikpath.chain.PlanarChain` whose coordinates are the robot's
own joint angles and whose targets are tool-tip positions ``(x, z)`` in the
platform frame; :func:`youbot_chain` is the youBot arm. The mapping between the
two angle conventions is in :func:`chain_from_robot`.

>>> chain = youbot_chain()  # base (0.184, 0.147) m, angle_offset (pi/2, 0, 0)  # doctest: +SKIP
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from youbot_opt.exceptions import ModelError
from youbot_opt.ikpath.chain import PlanarChain

if TYPE_CHECKING:
    from youbot_opt.robot.model import RobotModel

__all__ = ["chain_from_robot", "youbot_chain"]

_CHECK_TOL = 1e-10  # [m] largest accepted tip mismatch between chain and robot


def chain_from_robot(robot: RobotModel, *, name: str | None = None) -> PlanarChain:
    """Build the planar chain equivalent to a robot that moves in its platform's x-z plane.

    The youBot arm moves in the x-z plane of its platform; its joint angles are
    measured from the vertical, positive towards platform -x, and joint 1 sits
    at ``(a, h) = (0.184, 0.147)`` m. In the IK-path convention (x right, angles
    counter-clockwise from the x axis, plane coordinates ``(x, y) := (x, z)`` of
    the platform) the same arm is a chain with ``base = (a, h)``,
    ``angle_offset = (pi/2, 0, 0)`` (the study angle ``theta_1 = q_1 + pi/2``:
    q = 0 points up, along +z = the planar +y axis, and a positive angle turns
    towards -x, counter-clockwise in the (x, z) plane; ``theta_2 = q_2``,
    ``theta_3 = q_3``), and the link lengths and joint limits of the robot
    model. These numbers are read from the joint origins and the tip at
    ``q = 0``; the chain is then verified against
    :func:`youbot_opt.robot.model.tip_pose` at 20 seeded configurations.

    Parameters
    ----------
    robot : youbot_opt.robot.model.RobotModel
        A loaded robot (``load_model("youbot")``): revolute joints about the
        platform y axis, tip frame ``robot.tip_frame``.
    name : str, optional
        Chain name (default: the robot's).

    Returns
    -------
    PlanarChain
        Coordinates ``q`` equal the robot's joint angles; positions are the
        platform's (x, z) in [m]; limits are the robot's.

    Raises
    ------
    ModelError
        If the robot is not a planar revolute chain in the x-z plane (the
        chain's tip differs from ``tip_pose`` by more than 1e-10 m somewhere).
    """
    from youbot_opt.robot.model import tip_pose  # the owner of the youBot plane convention

    model: pin.Model = robot.model
    nq = int(model.nq)
    if nq < 1 or model.nv != nq or model.njoints != nq + 1:
        raise ModelError(
            f"robot {robot.name!r} is not a chain of 1-DoF joints (nq={nq}, nv={model.nv}, "
            f"joints={model.njoints - 1})"
        )
    data = model.createData()
    q0 = np.zeros(nq)
    pin.forwardKinematics(model, data, q0)
    points = [data.oMi[j].translation[[0, 2]].copy() for j in range(1, nq + 1)]
    points.append(np.asarray(tip_pose(robot, q0).position, dtype=np.float64))
    segments = np.diff(np.array(points), axis=0)
    lengths = np.linalg.norm(segments, axis=1)
    if np.any(lengths <= 1e-9):
        raise ModelError(
            f"robot {robot.name!r} is not a planar revolute chain in its platform's x-z plane: "
            f"segment lengths in that plane are {lengths.tolist()} m (a zero one)"
        )
    phi = np.arctan2(segments[:, 1], segments[:, 0])
    offset = np.diff(np.r_[0.0, phi])
    offset = np.arctan2(np.sin(offset), np.cos(offset))
    chain = PlanarChain(
        lengths=lengths,
        q_lower=np.asarray(robot.q_lower, dtype=np.float64),
        q_upper=np.asarray(robot.q_upper, dtype=np.float64),
        base=points[0],
        angle_offset=offset,
        name=name or str(robot.name),
        tip_frame=str(robot.tip_frame),
    )
    rng = np.random.default_rng(0)
    lo = np.maximum(chain.q_lower, -math.pi)
    hi = np.minimum(chain.q_upper, math.pi)
    worst = 0.0
    for q in rng.uniform(lo, hi, (20, nq)):
        ref = np.asarray(tip_pose(robot, q).position, dtype=np.float64)
        worst = max(worst, float(np.linalg.norm(chain.tip_position(q) - ref)))
    if worst > _CHECK_TOL:
        raise ModelError(
            f"robot {robot.name!r} is not a planar revolute chain in its platform's x-z plane: "
            f"the equivalent chain misses tip_pose by {worst:.3g} m (tolerance {_CHECK_TOL:g} m)"
        )
    return chain


def youbot_chain() -> PlanarChain:
    """Return the youBot arm (``load_model("youbot")``) as a planar chain."""
    from youbot_opt.robot.load import load_model

    return chain_from_robot(load_model("youbot"))
