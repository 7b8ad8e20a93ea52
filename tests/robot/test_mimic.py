"""Mimic joints are locked at their relation's reference value with a warning, never free."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from youbot_opt.exceptions import YoubotOptWarning
from youbot_opt.robot.load import load_model
from youbot_opt.robot.mimic import mimic_joints

TWO_LINK = """<?xml version="1.0"?>
<robot name="mimic_pair">
  <link name="base"/>
  <link name="a"><inertial><origin xyz="0 0 0.1"/><mass value="1.0"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.005"/></inertial></link>
  <link name="b"><inertial><origin xyz="0 0 0.1"/><mass value="0.5"/>
    <inertia ixx="0.004" ixy="0" ixz="0" iyy="0.004" iyz="0" izz="0.002"/></inertial></link>
  <joint name="drive" type="revolute"><parent link="base"/><child link="a"/>
    <axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="5" velocity="2"/></joint>
  <joint name="follower" type="revolute"><parent link="a"/><child link="b"/>
    <origin xyz="0 0 0.2"/><axis xyz="0 1 0"/>
    <limit lower="-0.4" upper="0.9" effort="5" velocity="2"/>
    <mimic joint="drive" multiplier="2" offset="0.1"/></joint>
</robot>
"""


@pytest.fixture()
def pair(tmp_path: Path) -> Path:
    """A two-joint arm whose second joint mimics the first (q_b = 2 q_a + 0.1)."""
    path = tmp_path / "mimic_pair.urdf"
    path.write_text(TWO_LINK)
    return path


def test_mimic_relations_are_read(pair: Path) -> None:
    """The <mimic> relation is read with its multiplier and offset."""
    (mimic,) = mimic_joints(pair)
    assert (mimic.name, mimic.mimicked, mimic.multiplier, mimic.offset) == (
        "follower",
        "drive",
        2.0,
        0.1,
    )


def test_mimic_joint_locked_with_warning(pair: Path) -> None:
    """The follower is locked at 2 * 0 + 0.1 (neutral reference) and the warning names it."""
    with pytest.warns(YoubotOptWarning, match=r"follower = 2 \* drive \+ 0.1, locked at 0.1"):
        robot = load_model(pair)
    assert robot.joint_names == ("drive",)
    assert robot.locked_joints == (("follower", 0.1),)


def test_mimic_follows_locked_mimicked_value_and_clips(pair: Path) -> None:
    """With drive locked at 0.3 the follower is 2 * 0.3 + 0.1 = 0.7; at 0.9 it clips to 0.9."""
    with pytest.warns(YoubotOptWarning, match="locked at 0.7"):
        robot = load_model(pair, lock_joints={"drive": 0.3})
    assert dict(robot.locked_joints) == pytest.approx({"drive": 0.3, "follower": 0.7})
    with pytest.warns(YoubotOptWarning, match="locked at 0.9"):
        robot = load_model(pair, lock_joints={"drive": 0.9})  # 2 * 0.9 + 0.1 = 1.9 > 0.9
    assert dict(robot.locked_joints)["follower"] == pytest.approx(0.9)


def test_panda_finger_is_locked_and_dynamics_match() -> None:
    """panda's second finger is locked; M(q) of the rest equals the full model's with the
    finger at its locked value, finger row and column deleted (1e-12: same CRBA, rounding)."""
    with pytest.warns(YoubotOptWarning, match="panda_finger_joint2"):
        robot = load_model("panda")
    assert "panda_finger_joint2" not in robot.joint_names and robot.nq == 8
    full = pin.buildModelFromUrdf(str(robot.urdf_path))
    finger = full.joints[full.getJointId("panda_finger_joint2")].idx_q
    keep = [i for i in range(full.nq) if i != finger]
    rng = np.random.default_rng(4)
    data, full_data = robot.model.createData(), full.createData()
    for _ in range(3):
        q = rng.uniform(robot.q_lower, robot.q_upper)
        q_full = np.insert(q, finger, dict(robot.locked_joints)["panda_finger_joint2"])
        mass = pin.crba(robot.model, data, q)
        ref = pin.crba(full, full_data, q_full)[np.ix_(keep, keep)]
        np.testing.assert_allclose(np.triu(mass), np.triu(ref), rtol=0, atol=1e-12)
