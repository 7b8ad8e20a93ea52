"""Tests of youbot_opt.robot.load: loading by name, path and parameters; locked joints."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from youbot_opt.exceptions import FrameNotFound, ModelError, ParameterError, RobotNotFound
from youbot_opt.robot.load import load_model
from youbot_opt.robot.model import RobotModel, frame_placement
from youbot_opt.robot.params import YOUBOT_PLANAR


def test_load_from_parameters_with_damping_and_gravity() -> None:
    """ArmParameters build in memory; damping and gravity reach the Pinocchio model."""
    params = dataclasses.replace(YOUBOT_PLANAR, gravity=1.62, damping=0.1)
    robot = load_model(params)
    assert robot.urdf_path is None
    np.testing.assert_array_equal(robot.damping, [0.1, 0.1, 0.1])
    np.testing.assert_array_equal(robot.model.gravity.linear, [0.0, 0.0, -1.62])
    override = load_model("youbot", damping=0.3)
    np.testing.assert_array_equal(override.damping, [0.3, 0.3, 0.3])
    with pytest.raises(ParameterError, match="damping"):
        load_model("youbot", damping=-0.1)


@pytest.mark.parametrize("name", ["double_pendulum", "ur5", "panda"])
def test_example_robot_data_robots_load(name: str) -> None:
    """example-robot-data robots load with limits, their tip frame and resolvable meshes."""
    robot = load_model(name)
    assert robot.name == name
    assert robot.q_lower.shape == (robot.nq,) and robot.effort_limit.shape == (robot.nv,)
    assert np.all(robot.q_lower <= robot.q_upper)
    robot.frame_id(robot.tip_frame)
    assert robot.visual_model.ngeoms > 0
    meshes = [
        g.meshPath
        for g in robot.visual_model.geometryObjects
        if g.meshPath.endswith((".stl", ".dae", ".obj"))
    ]
    assert meshes, "expected mesh geometry"
    assert all(Path(m).is_file() for m in meshes)
    placement = frame_placement(robot, pin.neutral(robot.model))
    assert np.all(np.isfinite(placement.translation))


def test_missing_path(tmp_path: Path) -> None:
    """A path that does not exist raises RobotNotFound naming the path."""
    missing = tmp_path / "nothing.urdf"
    with pytest.raises(RobotNotFound, match="nothing.urdf") as info:
        load_model(missing)
    assert info.value.path == str(missing)


def test_malformed_urdf(tmp_path: Path) -> None:
    """Malformed XML raises ModelError naming the file."""
    bad = tmp_path / "bad.urdf"
    bad.write_text('<robot name="x"><link name="a"></robot>', encoding="utf-8")
    with pytest.raises(ModelError, match="bad.urdf") as info:
        load_model(bad)
    assert not isinstance(info.value, RobotNotFound)


def test_path_source_and_shared_frame_names(tmp_path: Path) -> None:
    """A URDF file loads by path; a frame name shared by a fixed joint and a link is usable."""
    urdf = tmp_path / "one.urdf"
    urdf.write_text(
        '<robot name="one"><link name="base"/>'
        '<link name="arm"><inertial><mass value="1"/>'
        '<inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>'
        '<link name="tip"/>'
        '<joint name="j" type="revolute"><parent link="base"/><child link="arm"/>'
        '<axis xyz="0 0 1"/><limit lower="-1" upper="1" velocity="2" effort="3"/></joint>'
        '<joint name="tip" type="fixed"><parent link="arm"/><child link="tip"/>'
        '<origin xyz="0.5 0 0"/></joint></robot>',
        encoding="utf-8",
    )
    robot = load_model(urdf)
    assert robot.name == "one" and robot.tip_frame == "tip"
    assert robot.model.frames[robot.frame_id("tip")].type == pin.FrameType.BODY
    placement = frame_placement(robot, [math.pi / 2])
    # Rotating the 0.5 m lever by pi/2 about z: (0, 0.5, 0), rounding ~1e-16.
    np.testing.assert_allclose(placement.translation, [0.0, 0.5, 0.0], atol=1e-12)
    with pytest.raises(FrameNotFound, match="base") as info:
        load_model(urdf, tip_frame="nope")
    assert "tip" in info.value.available


# --- the real 5-DOF youBot arm, locked joints and tip frame (issue 12) -----------------------

FINGERS = ("gripper_finger_joint_l", "gripper_finger_joint_r")
YOUBOT_5DOF_FILE = Path(__file__).resolve().parents[2] / "urdf" / "youbot_arm_5dof.urdf"


def _rpy(rpy: np.ndarray) -> np.ndarray:
    """URDF roll-pitch-yaw (fixed x, y, z axes): Rz(yaw) Ry(pitch) Rx(roll)."""
    (cr, cp, cy), (sr, sp, sy) = np.cos(rpy), np.sin(rpy)
    rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    return rz @ ry @ rx


def _urdf_fk(path: Path, link: str, q: dict[str, float]) -> np.ndarray:
    """Pose (4x4) of ``link`` in the root link, as the product of the file's transforms.

    Independent of Pinocchio: each joint is T(origin) * motion(axis, q) read with
    ElementTree (revolute: Rodrigues rotation, prismatic: translation along the axis).
    """
    import xml.etree.ElementTree as ET

    joints = {j.find("child").get("link"): j for j in ET.parse(path).getroot().iter("joint")}
    pose = np.eye(4)
    while link in joints:
        joint = joints[link]
        origin = joint.find("origin")
        xyz = np.array([float(x) for x in origin.get("xyz", "0 0 0").split()])
        rpy = np.array([float(x) for x in origin.get("rpy", "0 0 0").split()])
        placement = np.eye(4)
        placement[:3, :3], placement[:3, 3] = _rpy(rpy), xyz
        motion = np.eye(4)
        if joint.get("type") != "fixed":
            axis = np.array([float(x) for x in joint.find("axis").get("xyz").split()])
            value = q[joint.get("name")]
            if joint.get("type") == "prismatic":
                motion[:3, 3] = value * axis
            else:
                k = np.array(
                    [[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]]
                )
                motion[:3, :3] = np.eye(3) + np.sin(value) * k + (1 - np.cos(value)) * k @ k
        pose = placement @ motion @ pose
        link = joint.find("parent").get("link")
    return pose


@pytest.fixture(scope="module")
def youbot5() -> RobotModel:
    """The real youBot arm by name, fingers locked half open (5.75 mm each)."""
    return load_model("youbot_arm_5dof", lock_joints={f: 0.00575 for f in FINGERS})


def test_youbot_5dof_locked_fingers_by_name_and_path(youbot5: RobotModel) -> None:
    """By name and by path: 7 joints in the file, 5 once the two fingers are locked."""
    assert load_model(YOUBOT_5DOF_FILE).nq == 7
    assert (youbot5.nq, youbot5.nv) == (5, 5)
    assert youbot5.joint_names == tuple(f"arm_joint_{i}" for i in range(1, 6))
    assert youbot5.tip_frame == "gripper_palm_link"
    assert dict(youbot5.locked_joints) == {f: 0.00575 for f in FINGERS}
    np.testing.assert_array_equal(youbot5.effort_limit, [9.5, 9.5, 6.0, 2.0, 1.0])
    by_path = load_model(YOUBOT_5DOF_FILE, lock_joints={f: 0.00575 for f in FINGERS})
    assert by_path.nq == 5 and by_path.visual_model.ngeoms == youbot5.visual_model.ngeoms


@pytest.mark.parametrize("frame", ["gripper_palm_link", "gripper_finger_link_l"])
def test_youbot_5dof_poses_match_the_urdf_transforms(youbot5: RobotModel, frame: str) -> None:
    """Tip and finger poses at seeded in-limit q equal the product of the URDF's transforms."""
    rng = np.random.default_rng(12)
    for _ in range(5):
        q = rng.uniform(youbot5.q_lower, youbot5.q_upper)
        values = dict(zip(youbot5.joint_names, q, strict=True)) | dict(youbot5.locked_joints)
        expected = _urdf_fk(YOUBOT_5DOF_FILE, frame, values)
        got = frame_placement(youbot5, q, frame)
        # 1e-12 [m]: six products of O(1) rotations and < 1 m offsets; rounding ~1e-15.
        np.testing.assert_allclose(got.rotation, expected[:3, :3], rtol=0, atol=1e-12)
        np.testing.assert_allclose(got.translation, expected[:3, 3], rtol=0, atol=1e-12)


def test_locked_mass_matrix_is_the_block_of_the_full_one(youbot5: RobotModel) -> None:
    """Locking keeps the arm rows and columns of M(q) of the full model (fingers held)."""
    full = load_model("youbot_arm_5dof")
    q = np.array([1.0, 0.7, -1.2, 0.4, 2.0])
    q_full = np.concatenate([q, [0.00575, 0.00575]])
    m_full = pin.crba(full.model, full.create_data(), q_full)
    m_red = pin.crba(youbot5.model, youbot5.create_data(), q)
    # CRBA sums in a different order in the two models: 1e-12 relative to ~0.5 kg m^2.
    np.testing.assert_allclose(np.triu(m_red), np.triu(m_full[:5, :5]), rtol=0, atol=1e-12)


def test_lock_joints_and_tip_frame_are_checked() -> None:
    """Unknown joints, positions outside the limits and unknown tip frames are refused."""
    with pytest.raises(ParameterError, match="not a movable joint.*arm_joint_1"):
        load_model("youbot_arm_5dof", lock_joints={"finger": 0.0})
    with pytest.raises(ParameterError, match=r"outside its limits \[0.0, 0.0115\]"):
        load_model("youbot_arm_5dof", lock_joints={FINGERS[0]: 0.02})
    with pytest.raises(ParameterError, match="finite number"):
        load_model("youbot_arm_5dof", lock_joints={FINGERS[0]: math.nan})
    with pytest.raises(FrameNotFound):
        load_model("youbot_arm_5dof", tip_frame="no_such_frame")
    robot = load_model("youbot_arm_5dof", tip_frame="arm_link_3")
    assert robot.tip_frame == "arm_link_3"
