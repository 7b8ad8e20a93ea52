"""Tests of MJCF robots (youbot_opt.robot.mjcf): the same arm as MJCF and URDF, refusals."""

from __future__ import annotations

import warnings

import numpy as np
import pinocchio as pin
import pytest

from youbot_opt.exceptions import InvalidModelError, UnsafeURDFError, YoubotOptWarning
from youbot_opt.robot.load import load_model
from youbot_opt.robot.mjcf import load_mjcf_strict
from youbot_opt.robot.payload import Payload
from youbot_opt.robot.source import RobotSource

ARM = """<mujoco model="arm">
  {compiler}
  <worldbody>
    {open_base}
    <body name="link1" pos="0 0 0.1">
      <joint name="j1" type="hinge" axis="0 0 1" range="{r1}" damping="0.1"/>
      <inertial pos="0.15 0 0" mass="1.0" diaginertia="0.01 0.02 0.02"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02"/>
      <body name="link2" pos="0.3 0 0" euler="{euler}">
        <joint name="j2" type="hinge" axis="0 1 0" range="{r2}"/>
        <inertial pos="0.1 0 0" mass="0.5" diaginertia="0.005 0.01 0.01"/>
        <site name="tip" pos="0.2 0 0"/>
      </body>
    </body>
    {close_base}
  </worldbody>
  <actuator>
    <motor joint="j1" ctrlrange="-1 1" gear="20"/>
    <motor joint="j2" forcerange="-5 5"/>
  </actuator>
  {extra}
</mujoco>
"""

DEGREES = {"r1": "-90 90", "r2": "-45 135", "euler": "0 0 30"}
RADIANS = {
    "r1": f"{-np.pi / 2!r} {np.pi / 2!r}",
    "r2": f"{-np.pi / 4!r} {3 * np.pi / 4!r}",
    "euler": f"0 0 {np.pi / 6!r}",
}

URDF = f"""<?xml version="1.0"?>
<robot name="arm">
  <link name="base"/>
  <joint name="j1" type="revolute">
    <parent link="base"/><child link="link1"/><origin xyz="0 0 0.1"/><axis xyz="0 0 1"/>
    <limit lower="{-np.pi / 2!r}" upper="{np.pi / 2!r}" velocity="2" effort="20"/>
    <dynamics damping="0.1"/>
  </joint>
  <link name="link1">
    <inertial><origin xyz="0.15 0 0"/><mass value="1.0"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.02"/></inertial>
  </link>
  <joint name="j2" type="revolute">
    <parent link="link1"/><child link="link2"/>
    <origin xyz="0.3 0 0" rpy="0 0 {np.pi / 6!r}"/><axis xyz="0 1 0"/>
    <limit lower="{-np.pi / 4!r}" upper="{3 * np.pi / 4!r}" velocity="2" effort="5"/>
  </joint>
  <link name="link2">
    <inertial><origin xyz="0.1 0 0"/><mass value="0.5"/>
      <inertia ixx="0.005" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
  </link>
  <joint name="tip_joint" type="fixed">
    <parent link="link2"/><child link="tip"/><origin xyz="0.2 0 0"/>
  </joint>
  <link name="tip"/>
</robot>
"""

FREE_BASE = (
    '<body name="base" pos="0 0 0"><freejoint name="float"/>'
    '<inertial pos="0 0 0" mass="5" diaginertia="0.1 0.1 0.1"/>'
)


def _mjcf(tmp_path, name="arm.xml", *, angle="degree", extra="", free=False, **values):
    compiler = "" if angle is None else f'<compiler angle="{angle}"/>'
    text = ARM.format(
        compiler=compiler,
        open_base=FREE_BASE if free else "",
        close_base="</body>" if free else "",
        extra=extra,
        **{**(RADIANS if angle == "radian" else DEGREES), **values},
    )
    path = tmp_path / name
    path.write_text(text)
    return path


@pytest.fixture()
def urdf_arm(tmp_path):
    path = tmp_path / "arm.urdf"
    path.write_text(URDF)
    return load_model(path, tip_frame="tip")


def _assert_same_dynamics(a, b, rng, frame="tip"):
    """Same joints, limits, damping and M(q), g(q), tip pose at 10 seeded q (1e-10)."""
    assert list(a.model.names) == list(b.model.names)
    for field in ("lowerPositionLimit", "upperPositionLimit", "effortLimit", "damping"):
        np.testing.assert_allclose(getattr(a.model, field), getattr(b.model, field), atol=1e-12)
    for q in rng.uniform(a.q_lower, a.q_upper, size=(10, a.nq)):
        v = rng.normal(size=a.nv)
        da, db = a.create_data(), b.create_data()
        np.testing.assert_allclose(pin.crba(a.model, da, q), pin.crba(b.model, db, q), atol=1e-10)
        np.testing.assert_allclose(
            pin.rnea(a.model, da, q, v, 0 * v), pin.rnea(b.model, db, q, v, 0 * v), atol=1e-10
        )
        pin.framesForwardKinematics(a.model, da, q)
        pin.framesForwardKinematics(b.model, db, q)
        np.testing.assert_allclose(
            da.oMf[a.frame_id(frame)].homogeneous, db.oMf[b.frame_id(frame)].homogeneous, atol=1e-12
        )


@pytest.mark.parametrize("angle", ["degree", "radian"])
def test_mjcf_arm_is_the_urdf_arm(tmp_path, urdf_arm, rng, angle):
    """The arm in degrees and in radians loads as the same robot as its URDF (limits, M, g, tip)."""
    robot = load_model(_mjcf(tmp_path, angle=angle))
    assert robot.tip_frame == "tip" and robot.urdf_path == (tmp_path / "arm.xml").resolve()
    _assert_same_dynamics(robot, urdf_arm, rng)


def test_actuator_ranges_are_the_effort_limits(tmp_path):
    """A motor's ctrlrange times its gear, or a forcerange, is the joint's effort limit [N m]."""
    loaded = load_mjcf_strict(_mjcf(tmp_path))
    np.testing.assert_array_equal(loaded.model.effortLimit, [20.0, 5.0])
    assert loaded.angle_unit == "degree" and loaded.welded_free_joint is None


def test_a_free_joint_is_welded(tmp_path, urdf_arm, rng):
    """A free joint on the root body is welded: the fixed-base robot of the URDF."""
    path = _mjcf(tmp_path, free=True)
    assert load_mjcf_strict(path).welded_free_joint == "float"
    _assert_same_dynamics(load_model(path), urdf_arm, rng)


def test_the_default_angle_unit_is_reported(tmp_path):
    """Without <compiler angle> the angles are read in degrees, with a warning saying so."""
    with pytest.warns(YoubotOptWarning, match="degrees.*no <compiler angle>"):
        loaded = load_mjcf_strict(_mjcf(tmp_path, angle=None))
    assert loaded.angle_unit == "degree"
    np.testing.assert_allclose(loaded.model.upperPositionLimit, [np.pi / 2, 3 * np.pi / 4])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert load_mjcf_strict(_mjcf(tmp_path, "r.xml", angle="radian")).angle_unit == "radian"


@pytest.mark.parametrize(
    ("extra", "values", "error", "match"),
    [
        (
            '<tendon><fixed name="t"><joint joint="j1" coef="1"/></fixed></tendon>',
            {},
            InvalidModelError,
            r"arm.xml:\d+: <tendon>: <tendon> is not supported",
        ),
        ('<include file="other.xml"/>', {}, UnsafeURDFError, "<include> is not supported"),
        ('<asset><mesh name="m" file="m.stl"/></asset>', {}, UnsafeURDFError, "mesh file="),
        ("", {"r1": '-90 90" armature="0.1'}, InvalidModelError, "armature"),
        ('<compiler angle="grad"/>', {}, InvalidModelError, "angle='grad'"),
    ],
)
def test_unsupported_mjcf_is_refused_by_name(tmp_path, extra, values, error, match):
    """Elements and attributes the optimisers cannot honour are refused by name and line."""
    with pytest.raises(error, match=match):
        load_model(_mjcf(tmp_path, extra=extra, **values))


def test_ball_joints_and_doctype_are_refused(tmp_path):
    """A ball joint and a DOCTYPE are refused with the URDF loader's error classes."""
    path = _mjcf(tmp_path)
    path.write_text(path.read_text().replace('type="hinge" axis="0 1 0"', 'type="ball"'))
    with pytest.raises(InvalidModelError, match="ball joint"):
        load_model(path)
    path.write_text('<!DOCTYPE m [<!ENTITY x "y">]>\n' + _mjcf(tmp_path, "b.xml").read_text())
    with pytest.raises(UnsafeURDFError):
        load_model(path)


def test_mjcf_robot_reloads_from_its_source_with_a_payload(tmp_path):
    """A loaded MJCF robot is recorded by path and digest and reloads, payload included."""
    robot = load_model(_mjcf(tmp_path), payload=Payload(mass=0.2))
    again = RobotSource.from_json(RobotSource.of(robot).to_json(folder=tmp_path)).load()
    assert again.payload == robot.payload
    np.testing.assert_array_equal(again.model.effortLimit, robot.model.effortLimit)


def test_implausible_inertias_follow_the_urdf_policy(tmp_path, rng, urdf_arm):
    """An implausible inertia of a moving body is refused (strict) or loaded with a warning."""
    path = _mjcf(tmp_path)
    path.write_text(path.read_text().replace("0.005 0.01 0.01", "0.005 0.01 0.03"))
    with pytest.raises(InvalidModelError, match=r"arm.xml:\d+: .*I1 \+ I2 >= I3.*--lenient"):
        load_model(path)
    with pytest.warns(YoubotOptWarning, match="strict=False"):
        load_model(path, strict=False)
    # on a body that cannot move (the welded base) it is only a warning
    free = _mjcf(tmp_path, "free.xml", free=True)
    free.write_text(free.read_text().replace("0.1 0.1 0.1", "0.1 0.1 0.3"))
    with pytest.warns(YoubotOptWarning, match="I1 \\+ I2 >= I3"):
        _assert_same_dynamics(load_model(free), urdf_arm, rng)


def test_malformed_numbers_are_refused_by_name(tmp_path):
    """A number that is not one is an InvalidModelError naming the attribute and line."""
    path = _mjcf(tmp_path)
    path.write_text(path.read_text().replace('gear="20"', 'gear="twenty"'))
    with pytest.raises(InvalidModelError, match=r"arm.xml:\d+: <motor>: gear='twenty'"):
        load_model(path)
