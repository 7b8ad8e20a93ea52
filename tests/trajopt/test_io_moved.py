"""Trajectory result files of a robot loaded from a URDF still load after the folder moved."""

from __future__ import annotations

import hashlib
import json
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest

from _migrate import REFUSAL, migrate
from youbot_opt.exceptions import (
    InvalidModelError,
    ParameterError,
    ResultFileError,
    YoubotOptWarning,
)
from youbot_opt.nlp.ipopt import IpoptOptions
from youbot_opt.reproduction.study1 import study1_problem
from youbot_opt.robot.catalogue import youbot_urdf_path
from youbot_opt.robot.load import load_model
from youbot_opt.robot.source import RobotSource, urdf_digest
from youbot_opt.trajopt.io import load_result, save_result
from youbot_opt.trajopt.problem import BoundaryState, TrajOptProblem
from youbot_opt.trajopt.result import TrajOptResult
from youbot_opt.trajopt.solver import solve
from youbot_opt.trajopt.sweep_store import robot_identity

_CHEAP = IpoptOptions(max_iter=3)  # a few iterations: the file, not the optimum, is under test


def _saved_in_moved_folder(tmp_path: Path) -> tuple[TrajOptResult, Path, Path, Path]:
    """youBot URDF copied into A, a result saved in A, A moved to B.

    Returns (result, result file in B, URDF path in A as recorded, URDF in B).
    """
    folder = tmp_path / "A"
    folder.mkdir()
    urdf = Path(shutil.copy(youbot_urdf_path(), folder / "arm.urdf"))
    robot = load_model(urdf, damping=0.1)
    result = solve(study1_problem(6, robot=robot), options=_CHEAP, seed=1)
    save_result(result, folder / "result.npz")
    shutil.move(folder, tmp_path / "B")
    return result, tmp_path / "B" / "result.npz", urdf.resolve(), tmp_path / "B" / "arm.urdf"


def _assert_same_numbers(a: TrajOptResult, b: TrajOptResult) -> None:
    """Robot size and joints, status, scalars and every saved array equal exactly."""
    ra, rb = a.problem.robot, b.problem.robot
    assert (ra.nq, ra.joint_names, ra.locked_joints) == (rb.nq, rb.joint_names, rb.locked_joints)
    np.testing.assert_array_equal(ra.damping, rb.damping)
    assert a.status is b.status and a.iterations == b.iterations
    for name in ("duration", "dt", "work", "objective", "max_violation"):
        assert getattr(a, name) == getattr(b, name), name
    for group in ("variables", "multipliers"):
        ga, gb = getattr(a, group), getattr(b, group)
        assert ga.keys() == gb.keys()
        for key in ga:
            np.testing.assert_array_equal(ga[key], gb[key], err_msg=key)
    np.testing.assert_array_equal(a.trajectory.q, b.trajectory.q)
    np.testing.assert_array_equal(a.trajectory.tau, b.trajectory.tau)


def _rewrite_metadata(path: Path, change) -> None:  # type: ignore[no-untyped-def]
    with np.load(path, allow_pickle=False) as npz:
        arrays = {k: np.array(npz[k]) for k in npz.files}
    meta = json.loads(arrays["metadata"].tobytes().decode())
    change(meta)
    arrays["metadata"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
    np.savez(path, **arrays)


def _metadata(path: Path) -> dict:  # type: ignore[type-arg]
    with np.load(path, allow_pickle=False) as npz:
        return json.loads(npz["metadata"].tobytes().decode())


def test_a_result_moved_with_its_urdf_reloads_without_robot(tmp_path: Path) -> None:
    """A moved to B: load_result(path) loads the robot from B/arm.urdf, with the same numbers."""
    result, path, recorded, moved = _saved_in_moved_folder(tmp_path)
    meta = _metadata(path)
    assert meta["problem"]["urdf_path"] == str(recorded)  # the older keys are still written
    assert meta["problem"]["robot"] == result.problem.robot.name
    assert meta["robot_source"]["relative_source"] == "arm.urdf"
    loaded = load_result(path)
    assert loaded.problem.robot.urdf_path == moved.resolve()
    _assert_same_numbers(result, loaded)  # the saved damping (0.1) is restored too


def test_an_edited_urdf_is_refused_naming_it_and_both_digests(tmp_path: Path) -> None:
    """A comment appended to the moved URDF: ResultFileError with its path and both SHA-256."""
    result, path, _, moved = _saved_in_moved_folder(tmp_path)
    with moved.open("a") as handle:
        handle.write("<!-- edited -->\n")
    new = hashlib.sha256(moved.read_bytes()).hexdigest()
    recorded = _metadata(path)["robot_source"]["urdf_sha256"]
    with pytest.raises(ResultFileError, match="has changed") as info:
        load_result(path)
    message = str(info.value)
    assert str(moved.resolve()) in message and "pass robot=" in message
    assert new[:12] in message and recorded[:12] in message
    # robot= overrides the file's robot: the edited file loads when passed on purpose
    _assert_same_numbers(result, load_result(path, robot=load_model(moved, damping=0.1)))


def test_a_deleted_urdf_names_every_path_tried(tmp_path: Path) -> None:
    """The URDF gone from A and B: the message lists both paths and says to pass robot=."""
    result, path, recorded, moved = _saved_in_moved_folder(tmp_path)
    moved.unlink()
    with pytest.raises(ResultFileError, match="not found") as info:
        load_result(path)
    message = str(info.value)
    assert str(recorded) in message and str(moved.resolve()) in message
    assert "pass robot=" in message


def _as_0_1_0(meta: dict) -> None:
    """Metadata as 0.1.0 wrote it before robot sources: schema 1, beta in the problem."""
    meta.pop("robot_source")
    meta["problem"]["beta"] = meta["beta"]
    meta["schema_version"] = 1


def test_a_file_of_0_1_0_without_robot_source_is_migrated_then_loads_as_then(
    tmp_path: Path,
) -> None:
    """Without "robot_source" (0.1.0): refused; migrated, reloaded from problem.urdf_path in place.

    After a move it is refused (the URDF path was all 0.1.0 recorded).
    """
    folder = tmp_path / "A"
    folder.mkdir()
    urdf = Path(shutil.copy(youbot_urdf_path(), folder / "arm.urdf"))
    result = solve(study1_problem(6, robot=load_model(urdf, damping=0.1)), options=_CHEAP)
    path = save_result(result, folder / "old.npz")
    _rewrite_metadata(path, _as_0_1_0)
    assert "robot_source" not in _metadata(path)
    with pytest.raises(ResultFileError, match=REFUSAL):
        load_result(path)
    done = migrate(path)
    assert done.returncode == 0, done.stderr
    assert _metadata(path)["robot_source"]["source"] == str(urdf)
    _assert_same_numbers(result, load_result(path))
    (folder / "old.npz.0.1.0.bak").unlink()
    shutil.move(folder, tmp_path / "B")
    with pytest.raises(ResultFileError, match=r"cannot reload robot .*pass robot="):
        load_result(tmp_path / "B" / "old.npz")


def test_a_lenient_robot_with_a_locked_joint_round_trips(tmp_path: Path) -> None:
    """strict=False and lock_joints are saved: the moved file reloads as loaded (strict refuses)."""
    folder = tmp_path / "A"
    folder.mkdir()
    text = youbot_urdf_path().read_text()
    urdf = folder / "lenient.urdf"  # arm_link_1's izz breaks I1 + I2 >= I3
    urdf.write_text(text.replace('izz="0.0005931"', 'izz="0.007"', 1))
    with pytest.raises(InvalidModelError):
        load_model(urdf)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", YoubotOptWarning)
        robot = load_model(urdf, strict=False, lock_joints={"arm_joint_3": 0.2})
        problem = TrajOptProblem(
            robot=robot,
            start=BoundaryState(q=np.array([-0.5, -0.5])),
            goal=BoundaryState(q=np.array([0.5, 0.5])),
            n_knots=6,
        )
        result = solve(problem, options=_CHEAP, seed=2)
        save_result(result, folder / "result.npz")
        shutil.move(folder, tmp_path / "B")
        loaded = load_result(tmp_path / "B" / "result.npz")
    back = loaded.problem.robot
    assert back.strict is False and back.locked_joints == (("arm_joint_3", 0.2),)
    assert back.urdf_path == (tmp_path / "B" / "lenient.urdf").resolve()
    _assert_same_numbers(result, loaded)


def test_sweep_stores_and_result_files_hash_the_urdf_alike(tmp_path: Path) -> None:
    """robot_identity (sweep manifests) = RobotSource digest = urdf_digest = sha256 of the bytes."""
    urdf = Path(shutil.copy(youbot_urdf_path(), tmp_path / "arm.urdf"))
    robot = load_model(urdf)
    want = hashlib.sha256(urdf.read_bytes()).hexdigest()
    assert robot_identity(robot) == RobotSource.of(robot).urdf_sha256 == want
    assert urdf_digest(urdf, robot.name) == want
    urdf.unlink()
    with pytest.raises(ParameterError, match=r"cannot read the URDF .*arm\.urdf of robot"):
        robot_identity(robot)  # the sweep store's message, unchanged
