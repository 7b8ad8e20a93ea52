"""Tests of youbot_opt.robot.urdf: params -> URDF -> Pinocchio round trip and the committed file."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.params import YOUBOT_PLANAR
from youbot_opt.robot.urdf import (
    JOINT_NAMES,
    LINK_NAMES,
    TIP_FRAME,
    build_urdf,
    default_urdf_path,
    main,
    urdf_string,
    write_urdf,
)

REGENERATE = "python -m youbot_opt.robot.urdf"
TOL = 1e-12  # [SI] decimal round trip is exact; 1e-16 rotations from rpy=pi are well below


def _pin_model(tmp_path: Path, **kwargs: float) -> pin.Model:
    path = write_urdf(YOUBOT_PLANAR, tmp_path / "arm.urdf", **kwargs)
    model, _, _ = pin.buildModelsFromUrdf(str(path))
    return model


def test_committed_file_is_up_to_date() -> None:
    """The committed urdf/youbot_arm_planar.urdf is byte-identical to a regenerated one."""
    committed = default_urdf_path()
    assert committed.is_file(), f"{committed} is missing; run `{REGENERATE}`"
    assert committed.read_bytes() == urdf_string(YOUBOT_PLANAR).encode("utf-8"), (
        f"{committed} is stale; regenerate it with `{REGENERATE}`"
    )


def test_output_is_deterministic(tmp_path: Path) -> None:
    """Two builds give the same text, and the entry point writes exactly that text."""
    assert urdf_string() == urdf_string()
    out = tmp_path / "x.urdf"
    assert main(["--output", str(out)]) == 0
    assert out.read_text(encoding="utf-8") == urdf_string()


def test_round_trip_inertials(tmp_path: Path) -> None:
    """Pinocchio reads back every link's mass, COM and inertia about the joint axis."""
    model = _pin_model(tmp_path)
    for k, link in enumerate(YOUBOT_PLANAR.links):
        jid = model.getJointId(JOINT_NAMES[k])
        inertia = model.inertias[jid]
        np.testing.assert_allclose(inertia.mass, link.mass, rtol=0, atol=TOL)
        np.testing.assert_allclose(inertia.lever, [0.0, 0.0, link.com_distance], atol=TOL)
        # Joint axis is local y: I_yy is the table's inertia about the joint-axis direction.
        np.testing.assert_allclose(inertia.inertia[1, 1], link.inertia, rtol=0, atol=TOL)
        np.testing.assert_allclose(inertia.inertia, link.inertia_tensor, rtol=0, atol=TOL)


def test_round_trip_geometry_and_limits(tmp_path: Path) -> None:
    """Joint placements give the mounting and link lengths; limits are the SI table values."""
    model = _pin_model(tmp_path)
    p = YOUBOT_PLANAR
    placements = [model.jointPlacements[model.getJointId(n)] for n in JOINT_NAMES]
    np.testing.assert_allclose(
        placements[0].translation, [p.mounting.a, 0.0, p.mounting.h], rtol=0, atol=TOL
    )
    for k in (1, 2):
        np.testing.assert_allclose(
            placements[k].translation, [0.0, 0.0, p.links[k - 1].length], rtol=0, atol=TOL
        )
    tip = model.frames[model.getFrameId(TIP_FRAME, pin.FrameType.BODY)].placement
    np.testing.assert_allclose(tip.translation, [0.0, 0.0, p.links[2].length], atol=TOL)
    np.testing.assert_allclose(model.lowerPositionLimit, p.q_lower, rtol=0, atol=TOL)
    np.testing.assert_allclose(model.upperPositionLimit, p.q_upper, rtol=0, atol=TOL)
    np.testing.assert_allclose(model.velocityLimit, p.velocity_limit, rtol=0, atol=TOL)
    np.testing.assert_allclose(model.effortLimit, p.effort_limit, rtol=0, atol=TOL)
    np.testing.assert_array_equal(model.damping, [0.0, 0.0, 0.0])
    assert [model.joints[model.getJointId(n)].shortname() for n in JOINT_NAMES] == [
        "JointModelRY"
    ] * 3


def test_joint_axes_are_platform_minus_y(tmp_path: Path) -> None:
    """Every joint turns about platform -y, so positive angles swing the arm towards -x."""
    model = _pin_model(tmp_path)
    data = model.createData()
    q = np.array([0.3, -0.7, 1.1])
    pin.forwardKinematics(model, data, q)
    for n in JOINT_NAMES:
        axis = data.oMi[model.getJointId(n)].rotation @ np.array([0.0, 1.0, 0.0])
        np.testing.assert_allclose(axis, [0.0, -1.0, 0.0], atol=TOL)


def test_damping_is_written(tmp_path: Path) -> None:
    """A damping override (or the params' damping) reaches Pinocchio's model.damping."""
    np.testing.assert_array_equal(_pin_model(tmp_path, damping=0.1).damping, [0.1] * 3)
    damped = dataclasses.replace(YOUBOT_PLANAR, damping=0.25)
    assert 'damping="0.25"' in urdf_string(damped)
    with pytest.raises(ParameterError, match="damping"):
        build_urdf(YOUBOT_PLANAR, damping=-1.0)


def test_structure() -> None:
    """The URDF has the platform root, three arm links, the gripper tip and drawable cylinders."""
    robot = build_urdf().robot
    assert [link.name for link in robot.links] == ["platform", *LINK_NAMES, TIP_FRAME]
    assert [j.type for j in robot.joints] == ["revolute"] * 3 + ["fixed"]
    for link, params in zip(robot.links[1:4], YOUBOT_PLANAR.links, strict=True):
        (visual,) = link.visuals
        assert visual.geometry.cylinder.length == params.length
        assert len(link.collisions) == 1
    with pytest.raises(ParameterError, match="ArmParameters"):
        build_urdf("youbot")  # type: ignore[arg-type]
