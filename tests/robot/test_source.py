"""RobotSource (youbot_opt.robot.source): a robot named so that it loads again after a move."""

from __future__ import annotations

import hashlib
import os
import shutil
import warnings
from pathlib import Path

import pinocchio as pin
import pytest

from youbot_opt.exceptions import (
    InvalidModelError,
    ModelError,
    ParameterError,
    RobotNotFound,
    YoubotOptWarning,
)
from youbot_opt.robot.catalogue import youbot_urdf_path
from youbot_opt.robot.load import load_model
from youbot_opt.robot.model import RobotModel
from youbot_opt.robot.source import RobotSource, urdf_digest

CORPUS = Path(__file__).resolve().parent / "urdf_corpus"


def _copy_youbot(folder: Path, name: str = "arm.urdf") -> Path:
    """The committed youBot URDF (no meshes) copied to ``folder/name``."""
    folder.mkdir(parents=True, exist_ok=True)
    return Path(shutil.copy(youbot_urdf_path(), folder / name))


def _lenient_youbot(folder: Path) -> Path:
    """The youBot URDF with arm_link_1's izz breaking I1 + I2 >= I3: strict refuses it."""
    folder.mkdir(parents=True, exist_ok=True)
    text = youbot_urdf_path().read_text()
    edited = text.replace('izz="0.0005931"', 'izz="0.007"', 1)
    assert edited != text
    path = folder / "lenient.urdf"
    path.write_text(edited)
    return path


def _load_lenient(path: Path, **kwargs: object) -> RobotModel:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", YoubotOptWarning)
        return load_model(path, strict=False, **kwargs)  # type: ignore[arg-type]


def test_urdf_digest_is_the_sha256_of_the_file_bytes(tmp_path: Path) -> None:
    """urdf_digest equals hashlib.sha256 of the bytes; an unreadable file names path and robot."""
    path = _copy_youbot(tmp_path)
    assert urdf_digest(path, "arm") == hashlib.sha256(path.read_bytes()).hexdigest()
    with pytest.raises(ParameterError, match=r"cannot read the URDF .*gone\.urdf of robot 'arm'"):
        urdf_digest(tmp_path / "gone.urdf", "arm")


def test_a_known_robot_is_recorded_by_name_without_digest(tmp_path: Path) -> None:
    """load_model("youbot") -> source "youbot", no SHA-256, no relative path even with a folder."""
    robot = load_model("youbot")
    assert robot.strict is True  # the default policy, recorded on the model
    source = RobotSource.of(robot)
    assert (source.source, source.urdf_sha256) == ("youbot", None)
    data = source.to_json(folder=tmp_path)
    assert data["relative_source"] is None and data["urdf_sha256"] is None
    assert source.candidates(tmp_path) == ()
    assert source.locate(tmp_path) == "youbot"


def test_a_file_is_recorded_by_absolute_path_digest_and_path_relative_to_the_folder(
    tmp_path: Path,
) -> None:
    """A URDF in proj/robots seen from proj/runs/r1: the relative path is ../../robots/arm.urdf."""
    urdf = _copy_youbot(tmp_path / "proj" / "robots")
    run = tmp_path / "proj" / "runs" / "r1"
    run.mkdir(parents=True)
    source = RobotSource.of(load_model(urdf))
    assert source.source == str(urdf.resolve())
    assert source.urdf_sha256 == hashlib.sha256(urdf.read_bytes()).hexdigest()
    data = source.to_json(folder=run)
    assert data["relative_source"] == os.path.join("..", "..", "robots", "arm.urdf")
    assert data["relative_package_dirs"] == [os.path.join("..", "..", "robots")]
    assert data["source"] == source.source  # the absolute path is kept besides


def test_json_round_trip_keeps_every_field(tmp_path: Path) -> None:
    """from_json(to_json(folder)) holds the relative paths written; writing it again: the same."""
    robot = _load_lenient(_lenient_youbot(tmp_path / "a"), lock_joints={"arm_joint_3": 0.2})
    data = RobotSource.of(robot).to_json(folder=tmp_path / "a")
    back = RobotSource.from_json(data)
    assert back.to_json() == data
    assert back.strict is False and back.lock_joints == (("arm_joint_3", 0.2),)
    assert back.relative_source == "lenient.urdf" and back.relative_package_dirs == (".",)


def test_load_after_the_tree_moved_finds_the_urdf_by_its_relative_path(tmp_path: Path) -> None:
    """proj/ moved to moved/: the robot loads from moved/robots/arm.urdf (same nq and joints)."""
    urdf = _copy_youbot(tmp_path / "proj" / "robots")
    run = tmp_path / "proj" / "runs" / "r1"
    run.mkdir(parents=True)
    robot = load_model(urdf)
    data = RobotSource.of(robot).to_json(folder=run)
    shutil.move(tmp_path / "proj", tmp_path / "moved")
    source = RobotSource.from_json(data)
    new_run = tmp_path / "moved" / "runs" / "r1"
    back = source.load(folder=new_run)
    assert back.urdf_path == (tmp_path / "moved" / "robots" / "arm.urdf").resolve()
    assert (back.nq, back.joint_names) == (robot.nq, robot.joint_names)
    tried = source.candidates(new_run)
    assert tried == (urdf.resolve(), (tmp_path / "moved" / "robots" / "arm.urdf").resolve())


def test_the_recorded_absolute_path_is_tried_first(tmp_path: Path) -> None:
    """With the folder copied (not moved) both candidates match: the recorded path is taken."""
    urdf = _copy_youbot(tmp_path / "a")
    data = RobotSource.of(load_model(urdf)).to_json(folder=tmp_path / "a")
    shutil.copytree(tmp_path / "a", tmp_path / "b")
    assert RobotSource.from_json(data).load(folder=tmp_path / "b").urdf_path == urdf.resolve()


def test_a_changed_file_at_the_recorded_path_gives_way_to_a_matching_relative_one(
    tmp_path: Path,
) -> None:
    """The first existing candidate whose content matches is taken, not the first existing one."""
    urdf = _copy_youbot(tmp_path / "a")
    data = RobotSource.of(load_model(urdf)).to_json(folder=tmp_path / "a")
    shutil.copytree(tmp_path / "a", tmp_path / "b")
    with urdf.open("a") as handle:
        handle.write("<!-- edited -->\n")
    back = RobotSource.from_json(data).load(folder=tmp_path / "b")
    assert back.urdf_path == (tmp_path / "b" / "arm.urdf").resolve()


def test_a_urdf_found_nowhere_names_every_path_tried(tmp_path: Path) -> None:
    """Deleted after the move: RobotNotFound names the recorded and the relative path."""
    urdf = _copy_youbot(tmp_path / "a")
    data = RobotSource.of(load_model(urdf)).to_json(folder=tmp_path / "a")
    shutil.move(tmp_path / "a", tmp_path / "b")
    (tmp_path / "b" / "arm.urdf").unlink()
    with pytest.raises(RobotNotFound) as info:
        RobotSource.from_json(data).load(folder=tmp_path / "b")
    message = str(info.value)
    assert (
        str(urdf.resolve()) in message and str((tmp_path / "b" / "arm.urdf").resolve()) in message
    )
    assert "'arm.urdf'" in message  # the recorded relative path


def test_an_edited_urdf_names_the_file_and_both_digests(tmp_path: Path) -> None:
    """A comment appended after the move: ModelError with the path and both SHA-256 prefixes."""
    urdf = _copy_youbot(tmp_path / "a")
    source = RobotSource.of(load_model(urdf))
    data = source.to_json(folder=tmp_path / "a")
    shutil.move(tmp_path / "a", tmp_path / "b")
    moved = tmp_path / "b" / "arm.urdf"
    with moved.open("a") as handle:
        handle.write("<!-- edited -->\n")
    new = hashlib.sha256(moved.read_bytes()).hexdigest()
    with pytest.raises(ModelError, match="has changed") as info:
        RobotSource.from_json(data).load(folder=tmp_path / "b")
    message = str(info.value)
    assert str(moved.resolve()) in message
    assert new[:12] in message and str(source.urdf_sha256)[:12] in message


def test_an_older_record_loads_as_before(tmp_path: Path) -> None:
    """No digest and no relative path (files written before): the recorded path, unchecked."""
    urdf = _copy_youbot(tmp_path / "a")
    old = {"source": str(urdf), "package_dirs": [str(tmp_path / "a")], "lock_joints": []}
    source = RobotSource.from_json(old)
    assert source.urdf_sha256 is None and source.candidates(tmp_path) == ()
    with urdf.open("a") as handle:
        handle.write("<!-- edited: not checked in the older form -->\n")
    assert source.load(folder=tmp_path / "elsewhere").urdf_path == urdf.resolve()
    shutil.move(tmp_path / "a", tmp_path / "b")
    with pytest.raises(RobotNotFound):  # as before: the recorded path only
        source.load(folder=tmp_path / "b")


def test_package_dirs_moved_with_the_folder_are_found_relative_to_it(tmp_path: Path) -> None:
    """A mesh under an extra package folder: after the move it resolves from the relative path."""
    proj = tmp_path / "proj"
    meshes = proj / "pkgs" / "corpus_pkg" / "meshes"
    meshes.mkdir(parents=True)
    shutil.copy(CORPUS / "pkg" / "corpus_pkg" / "meshes" / "box.stl", meshes / "box.stl")
    urdf = Path(shutil.copy(CORPUS / "valid" / "minimal.urdf", proj / "robot.urdf"))
    robot = load_model(urdf, package_dirs=[proj / "pkgs"])
    data = RobotSource.of(robot).to_json(folder=proj)
    assert "pkgs" in data["relative_package_dirs"]
    shutil.move(proj, tmp_path / "moved")
    back = RobotSource.from_json(data).load(folder=tmp_path / "moved")
    assert (tmp_path / "moved" / "pkgs").resolve() in [Path(p) for p in back.package_dirs]
    assert len(back.visual_model.geometryObjects) == len(robot.visual_model.geometryObjects) == 1


def test_strictness_and_locked_joints_are_recorded_and_restored(tmp_path: Path) -> None:
    """A lenient load with a locked joint reloads lenient and locked (strict would refuse it)."""
    path = _lenient_youbot(tmp_path / "a")
    with pytest.raises(InvalidModelError):
        load_model(path)
    robot = _load_lenient(path, lock_joints={"arm_joint_3": 0.2})
    assert robot.strict is False and robot.nq == 2
    source = RobotSource.of(robot)
    assert source.strict is False and source.lock_joints == (("arm_joint_3", 0.2),)
    assert RobotSource.of(robot, strict=True).strict is True  # an explicit policy wins
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", YoubotOptWarning)
        back = source.load()
    assert (back.strict, back.locked_joints, back.joint_names) == (
        False,
        (("arm_joint_3", 0.2),),
        ("arm_joint_1", "arm_joint_2"),
    )


def test_a_robot_built_in_memory_has_no_source() -> None:
    """RobotModel.from_pin_model: no file, no known name -> ParameterError; strict defaults True."""
    model = pin.Model(load_model("youbot").model)
    model.name = "in_memory"  # a name load_model does not know
    robot = RobotModel.from_pin_model(model)
    assert robot.strict is True
    with pytest.raises(ParameterError, match="'in_memory' has no URDF file"):
        RobotSource.of(robot)


@pytest.mark.parametrize(
    ("fields", "match"),
    [
        ({"source": ""}, "source must be"),
        ({"source": "x.urdf", "urdf_sha256": "abc"}, "urdf_sha256 must be 64"),
        ({"source": "x.urdf", "relative_source": "x.urdf"}, "needs the urdf_sha256"),
        (
            {"source": "x.urdf", "package_dirs": ("/a", "/b"), "relative_package_dirs": (".",)},
            r"one path per package dir \(2\) or none, got 1",
        ),
    ],
)
def test_invalid_fields_are_refused(fields: dict[str, object], match: str) -> None:
    """Each inconsistent field raises ParameterError naming it."""
    with pytest.raises(ParameterError, match=match):
        RobotSource(**fields)  # type: ignore[arg-type]


def _file_named_youbot(folder: Path) -> Path:
    """The youBot URDF as a file whose ``<robot name>`` is "youbot" but arm_link_1 is heavier.

    A catalogue name, another robot: loaded by path it must never be recorded
    (and reloaded) as the catalogue's youBot.
    """
    folder.mkdir(parents=True, exist_ok=True)
    text = youbot_urdf_path().read_text()
    edited = text.replace('name="youbot_arm_planar"', 'name="youbot"', 1)
    edited = edited.replace('<mass value="1.318"/>', '<mass value="2.5"/>', 1)
    assert edited.count('name="youbot"') == 1 and '<mass value="2.5"/>' in edited
    path = folder / "mine.urdf"
    path.write_text(edited)
    return path


def _masses(robot: RobotModel) -> list[float]:
    return [float(inertia.mass) for inertia in robot.model.inertias[1:]]


def test_a_file_named_like_a_catalogue_robot_is_recorded_by_path_and_digest(
    tmp_path: Path,
) -> None:
    """<robot name="youbot"> loaded by path: recorded by path and SHA-256, never by the name."""
    urdf = _file_named_youbot(tmp_path)
    robot = load_model(urdf)
    assert robot.name == "youbot" and robot.catalogue_name is None
    source = RobotSource.of(robot)
    assert source.source == str(urdf.resolve())
    assert source.urdf_sha256 == hashlib.sha256(urdf.read_bytes()).hexdigest()
    assert _masses(source.load())[0] == 2.5 != _masses(load_model("youbot"))[0]
    assert load_model("youbot").catalogue_name == "youbot"


def test_a_trajectory_result_of_such_a_file_reloads_that_file_or_refuses(tmp_path: Path) -> None:
    """save_result/load_result: the file itself comes back; edited or gone, a clear refusal."""
    from youbot_opt.exceptions import ResultFileError
    from youbot_opt.nlp.ipopt import IpoptOptions
    from youbot_opt.reproduction.study1 import study1_problem
    from youbot_opt.trajopt.io import load_result, save_result
    from youbot_opt.trajopt.solver import solve

    urdf = _file_named_youbot(tmp_path / "robots")
    robot = load_model(urdf)
    result = solve(study1_problem(6, robot=robot), options=IpoptOptions(max_iter=3), seed=1)
    (tmp_path / "run").mkdir()
    save_result(result, tmp_path / "run" / "result.npz")
    back = load_result(tmp_path / "run" / "result.npz").problem.robot
    assert back.urdf_path == urdf.resolve() and _masses(back) == _masses(robot)
    urdf.write_text(urdf.read_text().replace('<mass value="2.5"/>', '<mass value="2.6"/>'))
    with pytest.raises(ResultFileError, match=r"cannot reload robot 'youbot'.*has changed"):
        load_result(tmp_path / "run" / "result.npz")
    urdf.unlink()
    with pytest.raises(ResultFileError, match=r"cannot reload robot 'youbot'.*not found"):
        load_result(tmp_path / "run" / "result.npz")


def test_a_spatial_ik_result_of_such_a_file_reloads_that_file(tmp_path: Path) -> None:
    """save_result/load_result with RobotSource.of: the file, not the catalogue."""
    from _ik_results import exact_result
    from youbot_opt.exceptions import ResultFileError
    from youbot_opt.ikpath.io import load_result, save_result

    urdf = _file_named_youbot(tmp_path / "robots")
    robot = load_model(urdf)
    result = exact_result(robot)
    path = tmp_path / "run" / "result.json"
    path.parent.mkdir()
    save_result(result, path, RobotSource.of(robot))
    back = load_result(path).problem.model
    assert [float(i.mass) for i in back.inertias[1:]] == _masses(robot)
    urdf.unlink()
    with pytest.raises(ResultFileError, match="not found"):
        load_result(path)


def test_a_recorded_path_that_is_no_robot_file_is_named_not_read(tmp_path: Path) -> None:
    """A result may name any path (../../etc/shadow): only robot files are hashed (#29)."""
    secret = tmp_path / "shadow"
    secret.write_text("root:secret\n")
    data = {"source": str(secret), "urdf_sha256": "0" * 64, "relative_source": None}
    source = RobotSource.from_json(data)
    with pytest.raises(ModelError, match="is not a robot file") as info:
        source.locate()
    digest = hashlib.sha256(secret.read_bytes()).hexdigest()
    assert digest[:12] not in str(info.value) and str(secret) in str(info.value)
