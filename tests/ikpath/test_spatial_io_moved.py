"""Spatial IK-path result files of a robot loaded from a URDF still load after the folder moved."""

from __future__ import annotations

import hashlib
import json
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest

from _ik_results import exact_result
from youbot_opt._files import json_digest
from youbot_opt.exceptions import InvalidModelError, ResultFileError, YoubotOptWarning
from youbot_opt.ikpath import RobotSource as IkpathRobotSource
from youbot_opt.ikpath.io import RobotSource as SpatialIoRobotSource
from youbot_opt.ikpath.io import load_result, save_result
from youbot_opt.ikpath.result import IKPathResult
from youbot_opt.nlp.status import SolveStatus
from youbot_opt.robot import RobotSource as RobotLayerSource
from youbot_opt.robot.catalogue import youbot_urdf_path
from youbot_opt.robot.load import load_model
from youbot_opt.robot.model import RobotModel
from youbot_opt.robot.source import RobotSource


def _exact_result(robot: RobotModel) -> IKPathResult:
    """An exactly met two-target result on ``robot`` (checked to be a success)."""
    result = exact_result(robot)
    assert result.success
    return result


def _saved_in_moved_folder(tmp_path: Path, name: str = "arm.urdf", **load: object):
    """URDF ``name`` in A, a result saved in A with its RobotSource, A moved to B.

    Returns (result, result file in B, URDF path recorded in A, URDF in B).
    """
    folder = tmp_path / "A"
    urdf = folder / name
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", YoubotOptWarning)  # the lenient loader's
        robot = load_model(urdf, **load)  # type: ignore[arg-type]
    result = _exact_result(robot)
    save_result(result, folder / "result.json", RobotSource.of(robot))
    shutil.move(folder, tmp_path / "B")
    return result, tmp_path / "B" / "result.json", urdf.resolve(), tmp_path / "B" / name


@pytest.fixture()
def arm_in_a(tmp_path: Path) -> Path:
    """tmp_path/A/arm.urdf: the committed youBot URDF (no meshes)."""
    (tmp_path / "A").mkdir()
    return Path(shutil.copy(youbot_urdf_path(), tmp_path / "A" / "arm.urdf"))


def _assert_same(a: IKPathResult, b: IKPathResult) -> None:
    """Joints, configurations, start, E and the per-target errors equal exactly."""
    assert a.problem.model.nq == b.problem.model.nq
    assert list(a.problem.model.names) == list(b.problem.model.names)
    assert a.problem.joint_names == b.problem.joint_names
    np.testing.assert_array_equal(a.configurations, b.configurations)
    np.testing.assert_array_equal(a.start, b.start)
    assert a.objective == b.objective and b.status is SolveStatus.SOLVED
    np.testing.assert_array_equal(a.position_errors, b.position_errors)


def test_robot_source_is_one_class_under_three_names() -> None:
    """youbot_opt.robot, youbot_opt.ikpath and ikpath.io give the same RobotSource."""
    assert RobotLayerSource is IkpathRobotSource is SpatialIoRobotSource is RobotSource


def test_a_result_moved_with_its_urdf_reloads_without_robot(tmp_path: Path, arm_in_a) -> None:
    """A moved to B: load_result(path) loads B/arm.urdf and gives the same numbers."""
    result, path, recorded, moved = _saved_in_moved_folder(tmp_path)
    doc = json.loads(path.read_text())["result"]["robot"]
    assert doc["source"] == str(recorded) and doc["relative_source"] == "arm.urdf"
    _assert_same(result, load_result(path))


def test_an_edited_urdf_is_refused_naming_it_and_both_digests(tmp_path: Path, arm_in_a) -> None:
    """A comment appended (same kinematics): refused by content, path and both SHA-256 named."""
    result, path, _, moved = _saved_in_moved_folder(tmp_path)
    with moved.open("a") as handle:
        handle.write("<!-- edited -->\n")
    new = hashlib.sha256(moved.read_bytes()).hexdigest()
    recorded = json.loads(path.read_text())["result"]["robot"]["urdf_sha256"]
    with pytest.raises(ResultFileError, match="has changed") as info:
        load_result(path)
    message = str(info.value)
    assert str(moved.resolve()) in message and "pass robot=" in message
    assert new[:12] in message and recorded[:12] in message
    _assert_same(result, load_result(path, robot=load_model(moved)))  # robot= overrides


def test_a_deleted_urdf_names_every_path_tried(tmp_path: Path, arm_in_a) -> None:
    """The URDF gone: the message lists the recorded and the relative path, and says robot=."""
    _, path, recorded, moved = _saved_in_moved_folder(tmp_path)
    moved.unlink()
    with pytest.raises(ResultFileError, match="not found") as info:
        load_result(path)
    message = str(info.value)
    assert str(recorded) in message and str(moved.resolve()) in message
    assert "pass robot=" in message


def test_a_file_written_before_digests_loads_as_then(tmp_path: Path, arm_in_a) -> None:
    """An older robot source (no digest, no relative path): loads in place, refused once moved."""
    robot = load_model(arm_in_a)
    result = _exact_result(robot)
    path = save_result(result, tmp_path / "A" / "old.json", RobotSource.of(robot))
    doc = json.loads(path.read_text())
    for key in ("urdf_sha256", "relative_source", "relative_package_dirs"):
        del doc["result"]["robot"][key]
    doc["sha256"] = json_digest(doc["result"])
    path.write_text(json.dumps(doc))
    _assert_same(result, load_result(path))
    shutil.move(tmp_path / "A", tmp_path / "B")
    with pytest.raises(ResultFileError, match=r"cannot load the robot.*pass robot="):
        load_result(tmp_path / "B" / "old.json")


def test_a_lenient_robot_with_a_locked_joint_round_trips(tmp_path: Path) -> None:
    """strict=False and the locked joint are recorded: the moved file reloads (strict refuses)."""
    (tmp_path / "A").mkdir()
    text = youbot_urdf_path().read_text()
    urdf = tmp_path / "A" / "lenient.urdf"  # arm_link_1's izz breaks I1 + I2 >= I3
    urdf.write_text(text.replace('izz="0.0005931"', 'izz="0.007"', 1))
    with pytest.raises(InvalidModelError):
        load_model(urdf)
    result, path, _, _ = _saved_in_moved_folder(
        tmp_path, "lenient.urdf", strict=False, lock_joints={"arm_joint_3": 0.2}
    )
    robot = json.loads(path.read_text())["result"]["robot"]
    assert robot["strict"] is False and robot["lock_joints"] == [["arm_joint_3", 0.2]]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", YoubotOptWarning)
        loaded = load_result(path)
    assert loaded.problem.model.nq == 2
    _assert_same(result, loaded)
