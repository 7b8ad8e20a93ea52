"""``youbot-opt report``: print a model report (joints, masses, limits, M(q), N(q), tip pose).

Usage::

    youbot-opt report [--robot NAME|PATH] [--package-dir DIR] [--lenient]
                      [--lock NAME=VALUE] [--tip-frame F] [--q Q1 Q2 ...]

The default robot is the study's youBot arm and the default configuration its
start configuration ``(-pi/6, -pi/6, -pi/3)`` [rad]; every other robot (a file
too, whatever its robot's name) defaults to its neutral configuration.
"""

from __future__ import annotations

import argparse
import math

import numpy as np
import pinocchio as pin

from youbot_opt.cli.flags import is_study_youbot, load_robot
from youbot_opt.robot.catalogue import youbot_urdf_path
from youbot_opt.robot.model import (
    JointUnits,
    RobotModel,
    as_configuration,
    frame_placement,
    tip_pose,
)
from youbot_opt.robot.params import STUDY_Q_START

__all__ = ["format_report", "run"]

_PLANAR_TIP = "gripper_tip"


def _fmt(x: np.ndarray, digits: int = 6) -> str:

    return np.array2string(np.asarray(x), precision=digits, suppress_small=True, max_line_width=100)


def _limit_row(name: str, lo: float, hi: float, vel: float, eff: float, unit: JointUnits) -> str:
    si = (
        f"[{lo:8.4f}, {hi:8.4f}] {unit.position:<3}  {vel:7.4f} {unit.velocity:<5}  "
        f"{eff:7.3f} {unit.effort:<3}"
    )
    if unit.prismatic:  # a length has no data-sheet degrees
        return f"  {name:<24} {si}   | prismatic: [{lo * 1e3:7.1f}, {hi * 1e3:7.1f}] mm"
    deg = f"[{math.degrees(lo):9.2f}, {math.degrees(hi):9.2f}] deg  {math.degrees(vel):7.2f} deg/s"
    return f"  {name:<24} {si}   | {deg}"


def _per_joint(values: np.ndarray, units: list[str]) -> str:
    """``value unit`` pairs when the units differ, else the array and its one unit."""
    if len(set(units)) == 1:
        return f"{_fmt(values)} {units[0]}"
    small = np.abs(values) < 1e-12  # round-off zeros, as _fmt's suppress_small prints them
    shown = np.where(small, 0.0, values)
    return "[" + ", ".join(f"{x:.6g} {u}" for x, u in zip(shown, units, strict=True)) + "]"


def format_report(robot: RobotModel, q: np.ndarray) -> str:
    """Return the report text of ``robot`` at configuration ``q``.

    Parameters
    ----------
    robot : RobotModel
        The robot.
    q : numpy.ndarray
        Configuration in [rad], shape (nq,).

    Returns
    -------
    str
        Multi-line report (SI units, with data-sheet degrees beside the limits).
    """
    qa = as_configuration(robot, q)
    model = robot.model
    data = robot.create_data()
    lines = [
        f"robot: {robot.name}  (nq={robot.nq}, nv={robot.nv})",
        f"urdf: {robot.urdf_path if robot.urdf_path is not None else '(built in memory)'}",
        f"tip frame: {robot.tip_frame}",
        f"gravity: {_fmt(model.gravity.linear)} m/s^2",
        "joints (type, body mass [kg]):",
    ]
    for jid in range(1, model.njoints):
        mass = model.inertias[jid].mass
        lines.append(f"  {model.names[jid]:<24} {model.joints[jid].shortname():<28} {mass:.6g}")
    lines.append("limits (SI per joint kind | data-sheet units; revolute joints read in degrees):")
    units = robot.joint_units()
    lo, hi, vel, eff = robot.q_lower, robot.q_upper, robot.velocity_limit, robot.effort_limit
    for jid in range(1, model.njoints):
        j = model.joints[jid]
        if j.nq != 1 or j.nv != 1:
            lines.append(f"  {model.names[jid]:<24} (multi-dof joint, see the URDF)")
            continue
        iq, iv = j.idx_q, j.idx_v
        lines.append(_limit_row(model.names[jid], lo[iq], hi[iq], vel[iv], eff[iv], units[iv]))
    damping_units = [f"{u.effort} s/{u.position}" for u in units]
    lines.append(f"damping: {_per_joint(robot.damping, damping_units)}")
    if robot.payload is not None:
        p = robot.payload
        lines.append(
            f"payload: {p.mass:g} kg at {list(p.com)} m in frame {p.frame!r} (included in the "
            "body masses, M(q) and N(q) below)"
        )
    mass_matrix = pin.crba(model, data, qa)
    mass_matrix = np.triu(mass_matrix) + np.triu(mass_matrix, 1).T
    lines += [
        f"q: {_per_joint(qa, [u.position for u in units]) if qa.size == len(units) else _fmt(qa)}",
        "M(q) [kg m^2; kg m and kg in the rows and columns of prismatic joints]:"
        if any(u.prismatic for u in units)
        else "M(q) [kg m^2]:",
        _fmt(mass_matrix),
        "gravity torque N(q): "
        + _per_joint(pin.computeGeneralizedGravity(model, data, qa), [u.effort for u in units]),
    ]
    planar = robot.tip_frame == _PLANAR_TIP and robot.urdf_path in (None, youbot_urdf_path())
    if planar and not robot.locked_joints:  # the study's arm: its (x, z) plane convention
        pose = tip_pose(robot, qa)
        lines += [
            f"tip position (x, z) in platform: {_fmt(pose.position)} m",
            "tip rotation (2-D, platform x-z plane):",
            _fmt(pose.rotation),
        ]
    else:
        placement = frame_placement(robot, qa)
        lines += [
            f"tip position in root frame: {_fmt(placement.translation)} m",
            "tip rotation:",
            _fmt(placement.rotation),
        ]
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Run ``youbot-opt report``; returns the exit code."""
    robot = load_robot(args)
    if args.q is not None:
        q = np.asarray(args.q, dtype=float)
    elif is_study_youbot(args):  # the built-in planar arm only, never a file named "youbot"
        q = np.asarray(STUDY_Q_START)
    else:
        q = pin.neutral(robot.model)
    print(format_report(robot, q))
    if len(robot.collision_model.geometryObjects) > 1:  # a pair needs two geometries
        from youbot_opt.collision.pairs import pairs_report, self_collision_pairs

        pairs = self_collision_pairs(
            robot,
            srdf=True if args.srdf is None else args.srdf,
            disable=[tuple(pair) for pair in args.disable_pair or ()],
        )
        print("\n".join(pairs_report(pairs)))
    return 0
