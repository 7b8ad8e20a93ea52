"""``youbot-opt robots``, the shared --robot options and the report --robot FILE bug."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from youbot_opt.cli import main
from youbot_opt.robot.catalogue import available_robots, example_robots

FIVE_DOF = Path(__file__).resolve().parents[2] / "urdf" / "youbot_arm_5dof.urdf"
FINGERS = ["--lock", "gripper_finger_joint_l=0", "--lock", "gripper_finger_joint_r=0"]


def test_robots_names_lists_every_name(capsys: pytest.CaptureFixture[str]) -> None:
    """--names prints every name load_model accepts, the whole zoo included."""
    assert main(["robots", "--names"]) == 0
    names = capsys.readouterr().out.split()
    assert names == list(available_robots()) and set(example_robots()) <= set(names)


def test_robots_table_gives_dof_types_and_status(capsys: pytest.CaptureFixture[str]) -> None:
    """A row per robot: nq/nv, joint types, and default / lenient / refused with the rule."""
    assert main(["robots", "ur5", "romeo_small", "ur_description/ur3"]) == 0
    rows = {line.split()[0]: line for line in capsys.readouterr().out.splitlines()}
    assert "6/6" in rows["ur5"] and "default" in rows["ur5"] and "revolute 6" in rows["ur5"]
    assert "lenient" in rows["romeo_small"] and "triangle inequality" in rows["romeo_small"]
    assert (
        "refused" in rows["ur_description/ur3"] and "<robot name=...>" in rows["ur_description/ur3"]
    )
    assert main(["robots", "no_such_robot"]) == 2


def _arm_files(folder: Path) -> dict[str, Path]:
    """Three edits of the committed youBot URDF: loads as it is, only leniently, refused."""
    text = (FIVE_DOF.parent / "youbot_arm_planar.urdf").read_text()
    edits = {
        "strict": text,
        # arm_link_1's izz breaks I1 + I2 >= I3: an inertia only --lenient accepts
        "lenient": text.replace('izz="0.0005931"', 'izz="0.007"', 1),
        "refused": text.replace('<mass value="0.821"/>', '<mass value="-1"/>', 1),
    }
    assert len(set(edits.values())) == 3
    paths = {}
    for kind, body in edits.items():
        paths[kind] = folder / f"{kind}.urdf"
        paths[kind].write_text(body)
    return paths


def test_robots_takes_urdf_paths_and_names_mixed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Own files get the names' verdict: default / lenient (rule, line) / refused (rule, line)."""
    files = _arm_files(tmp_path)
    args = ["robots", str(files["strict"]), "ur5", str(files["lenient"]), str(files["refused"])]
    assert main(args) == 0
    rows = {line.split()[0]: line for line in capsys.readouterr().out.splitlines()}
    assert "3/3" in rows[str(files["strict"])] and "default" in rows[str(files["strict"])]
    assert "default" in rows["ur5"]
    lenient = rows[str(files["lenient"])]
    assert "lenient" in lenient and "triangle inequality" in lenient
    assert "arm_link_1" in lenient and "line " in lenient
    refused = rows[str(files["refused"])]
    assert "refused, also with --lenient: mass >= 0" in refused and "line 55" in refused
    assert main([*args, "--json"]) == 0
    by_name = {row["name"]: row for row in json.loads(capsys.readouterr().out)}
    assert {len(row) for row in by_name.values()} == {9}  # one shape for names and paths
    assert by_name[str(files["refused"])]["path"] == str(files["refused"].resolve())
    assert [by_name[str(files[k])]["status"] for k in ("strict", "lenient", "refused")] == [
        "default",
        "lenient",
        "refused",
    ]
    assert main(["robots", "ur5", str(tmp_path / "gone.urdf")]) == 2
    assert "neither a robot name nor an existing file" in capsys.readouterr().err


def test_report_of_a_file_whose_robot_is_named_youbot(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A file whose robot is named "youbot" gets its neutral q, not the study arm's (was exit 2)."""
    path = tmp_path / "arm.urdf"
    path.write_text(FIVE_DOF.read_text().replace('name="youbot_arm_5dof"', 'name="youbot"'))
    assert main(["report", "--robot", str(path)]) == 0
    out = capsys.readouterr().out
    assert "robot: youbot  (nq=7, nv=7)" in out
    assert "q: [0 rad, 0 rad, 0 rad, 0 rad, 0 rad, 0 m, 0 m]" in out  # units per joint kind


def test_report_with_lock_tip_frame_and_package_dir(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--lock, --tip-frame and --package-dir reach load_model; bad --lock is exit 2."""
    args = ["report", "--robot", "youbot_arm_5dof", *FINGERS, "--tip-frame", "arm_link_5"]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "(nq=5, nv=5)" in out and "tip frame: arm_link_5" in out
    copy = tmp_path / "ur5.urdf"
    copy.write_bytes(example_robots()["ur5_robot"].read_bytes())
    from youbot_opt.robot.catalogue import example_robot_data_dir

    assert main(["report", "--robot", str(copy)]) == 2  # meshes not found
    assert (
        main(["report", "--robot", str(copy), "--package-dir", str(example_robot_data_dir())]) == 0
    )
    with pytest.raises(SystemExit) as info:
        main(["report", "--lock", "arm_joint_1"])
    assert info.value.code == 2


def test_ikpath_takes_the_robot_loading_options(tmp_path):
    """`ikpath --robot ur5 --lock J=V` plans without the locked joint, with no traceback."""
    import json
    import subprocess
    import sys

    out = subprocess.run(
        [sys.executable, "-m", "youbot_opt", "ikpath", "--robot", "ur5", "--method", "ipopt"]
        + ["--target", "0.3", "0.2", "0.4", "--target", "0.3", "-0.2", "0.4"]
        + ["--lock", "shoulder_pan_joint=0.1", "--out", str(tmp_path / "run")],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert out.returncode in (0, 1, 2), out.stderr
    assert "Traceback" not in out.stderr
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert "shoulder_pan_joint" not in summary["joints"]
    assert len(summary["joints"]) == 5
