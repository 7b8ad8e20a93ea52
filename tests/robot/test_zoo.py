"""The whole example-robot-data zoo by name, its package folders, and the loader policy on it."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

from youbot_opt.cli.robots import RobotSurvey, survey
from youbot_opt.exceptions import InvalidModelError, ResourceNotFoundError, YoubotOptWarning
from youbot_opt.robot.catalogue import available_robots, example_robot_data_dir, example_robots
from youbot_opt.robot.load import load_model

ROBOTS = example_robot_data_dir() / "example-robot-data" / "robots"


def test_every_installed_urdf_has_one_name() -> None:
    """One name per URDF file of the installed data (counted here with os.walk)."""
    files = {
        Path(root, f).resolve()
        for root, _, names in os.walk(ROBOTS)
        for f in names
        if f.endswith(".urdf")
    }
    zoo = example_robots()
    assert len(zoo) == len(files) and {p.resolve() for p in zoo.values()} == files
    assert set(zoo) <= set(available_robots())
    assert {"youbot", "youbot_arm_5dof", "ur5", "panda", "talos_left_arm"} <= set(
        available_robots()
    )


def test_a_path_inside_example_robot_data_finds_its_package_folders() -> None:
    """A file of example-robot-data given by path resolves its package:// meshes."""
    robot = load_model(example_robots()["ur5_robot"])
    assert robot.visual_model.ngeoms > 0
    assert all(Path(g.meshPath).is_file() for g in robot.visual_model.geometryObjects)


def test_package_dirs_resolve_a_copied_file(tmp_path: Path) -> None:
    """A copy outside the data needs package_dirs; with them its meshes resolve."""
    copy = tmp_path / "ur5.urdf"
    shutil.copyfile(example_robots()["ur5_robot"], copy)
    with pytest.raises(ResourceNotFoundError, match="package://example-robot-data"):
        load_model(copy)
    robot = load_model(copy, package_dirs=[example_robot_data_dir()])
    assert robot.nq == 6 and robot.visual_model.ngeoms > 0


@pytest.fixture(scope="session")
def zoo_survey() -> dict[str, RobotSurvey]:
    """Every robot of the zoo loaded by default, then leniently (~45 s on 2 cores)."""
    return {name: survey(name) for name in example_robots()}


@pytest.mark.slow
def test_every_robot_loads_or_is_refused_with_a_rule(zoo_survey: dict[str, RobotSurvey]) -> None:
    """Each robot loads by default, or with --lenient, or is refused naming a rule."""
    for name, row in zoo_survey.items():
        assert row.status in ("default", "lenient", "refused"), name
        if row.status == "default":
            assert row.nq is not None and not row.reason
        else:
            assert "[rule: " in row.message, (name, row.message)
        if row.status == "lenient":
            assert "strict=False" in row.message and "--lenient" in row.message
            assert row.warnings >= 1  # the lenient load warned about the inertia
    # Bodies welded to the world (tiago's antennas, go1's base) only warn; moving links
    # with implausible inertias (romeo_small's shoulder) need --lenient.
    assert zoo_survey["tiago"].status == "default" and zoo_survey["tiago"].warnings == 2
    assert zoo_survey["go1"].status == "default" and zoo_survey["go1"].warnings == 1
    assert zoo_survey["romeo_small"].status == "lenient"
    assert "link 'RShoulderYawLink'" in zoo_survey["romeo_small"].message


def test_lenient_opt_in_says_what_a_massless_foot_adds() -> None:
    """bolt's massless feet with inertia are refused; strict=False loads them with a
    warning naming the body (the lower leg's joint) that Pinocchio merges them into."""
    with pytest.raises(InvalidModelError, match="link 'FL_FOOT'.*strict=False.*--lenient"):
        load_model("bolt")
    with pytest.warns(YoubotOptWarning) as record:
        robot = load_model("bolt", strict=False)
    feet = [str(w.message) for w in record if "<inertia> of link" in str(w.message)]
    assert len(feet) == 2 and all("[rule: mass = 0 implies inertia = 0]" in m for m in feet)
    assert "merges it into the body of moving joint 'FL_KFE'" in feet[0]
    assert "adds 0 kg and rotational inertia" in feet[0] and robot.nq == 6
