"""Tests of youbot_opt.robot.catalogue: the robots known by name, found from installed data."""

from __future__ import annotations

import importlib.metadata

import numpy as np
import pinocchio as pin
import pytest

from youbot_opt.exceptions import ModelError, RobotNotFound
from youbot_opt.robot.catalogue import available_robots, example_robot_data_dir
from youbot_opt.robot.load import load_model


def test_example_robot_data_dir_locates_urdfs() -> None:
    """example_robot_data_dir() is the share folder holding example-robot-data/robots, and the
    URDFs there build the same models load_model gives (the dynamics tests rely on both)."""
    robots = example_robot_data_dir() / "example-robot-data" / "robots"
    assert robots.is_dir()
    for name, rel in [
        ("double_pendulum", "double_pendulum_description/urdf/double_pendulum.urdf"),
        ("ur5", "ur_description/urdf/ur5_robot.urdf"),
        ("panda", "panda_description/urdf/panda.urdf"),
    ]:
        path = robots / rel
        assert path.is_file(), path
        direct = pin.buildModelFromUrdf(str(path))
        robot = load_model(name)
        loaded = robot.model
        if robot.locked_joints:  # mimic joints (panda's second finger) are locked
            q_ref = pin.neutral(direct)
            ids = [direct.getJointId(joint) for joint, _ in robot.locked_joints]
            for jid, (_, value) in zip(ids, robot.locked_joints, strict=True):
                q_ref[direct.joints[jid].idx_q] = value
            direct = pin.buildReducedModel(direct, ids, q_ref)
        assert (direct.nq, direct.nv) == (loaded.nq, loaded.nv)
        assert list(direct.names) == list(loaded.names)
        # Same file parsed twice: masses identical to the last bit.
        np.testing.assert_array_equal(
            [i.mass for i in direct.inertias], [i.mass for i in loaded.inertias]
        )


def test_example_robot_data_missing(monkeypatch: pytest.MonkeyPatch) -> None:
    """Without example-robot-data, the locator raises ModelError with the pip command."""

    def missing(name: str) -> None:
        raise importlib.metadata.PackageNotFoundError(name)

    monkeypatch.setattr(importlib.metadata, "distribution", missing)
    with pytest.raises(ModelError, match="pip install example-robot-data"):
        example_robot_data_dir()


def test_unknown_robot_lists_names() -> None:
    """An unknown robot name raises RobotNotFound whose message lists the available names."""
    with pytest.raises(RobotNotFound, match="ur5") as info:
        load_model("no_such_robot")
    assert info.value.available == available_robots()
    assert "youbot" in str(info.value) and "panda" in str(info.value)
