"""Tests of youbot_opt.robot.model: the loaded model, its limits, frames and tip-pose convention."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pinocchio as pin
import pytest

from youbot_opt.cli import main as cli_main
from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.load import load_model
from youbot_opt.robot.model import RobotModel, tip_pose
from youbot_opt.robot.params import STUDY_Q_START, YOUBOT_PLANAR

A, H = 0.184, 0.147
L1, L2, L3 = 0.155, 0.135, 0.2175
PI = math.pi
# Spec trajopt.md tip-pose table: q -> (position (x, z), 2-D rotation).
SPEC_TIP_TABLE = [
    ((0.0, 0.0, 0.0), (A, H + L1 + L2 + L3), [[0, -1], [1, 0]]),
    ((0.0, PI / 2, 0.0), (A - L2 - L3, H + L1), [[-1, 0], [0, -1]]),
    ((-PI / 2, PI / 2, -PI / 2), (A + L1 + L3, H + L2), [[1, 0], [0, 1]]),
    ((PI, -PI, PI), (A, H - L1 + L2 - L3), [[0, 1], [-1, 0]]),
]


@pytest.mark.parametrize(("q", "position", "rotation"), SPEC_TIP_TABLE)
def test_tip_pose_matches_spec_table(
    youbot: RobotModel, q: tuple[float, ...], position: tuple[float, float], rotation: list
) -> None:
    """tip_pose reproduces the four tip poses of the spec table."""
    pose = tip_pose(youbot, q)
    # 1e-12 [m]: sums of a few products of O(1) numbers, rounding is ~1e-16.
    np.testing.assert_allclose(pose.position, position, rtol=0, atol=1e-12)
    np.testing.assert_allclose(pose.rotation, rotation, rtol=0, atol=1e-12)


def test_youbot_model_contents(youbot: RobotModel) -> None:
    """The youBot model has 3 DoF, the table limits, no damping, g = 9.81 along -z."""
    assert (youbot.nq, youbot.nv) == (3, 3)
    assert youbot.joint_names == ("arm_joint_1", "arm_joint_2", "arm_joint_3")
    assert youbot.tip_frame == "gripper_tip"
    np.testing.assert_allclose(youbot.q_lower, YOUBOT_PLANAR.q_lower, rtol=0, atol=1e-12)
    np.testing.assert_allclose(youbot.q_upper, YOUBOT_PLANAR.q_upper, rtol=0, atol=1e-12)
    np.testing.assert_allclose(youbot.effort_limit, YOUBOT_PLANAR.effort_limit, atol=1e-12)
    np.testing.assert_allclose(
        youbot.velocity_limit, YOUBOT_PLANAR.velocity_limit, rtol=0, atol=1e-12
    )
    np.testing.assert_array_equal(youbot.damping, np.zeros(3))
    np.testing.assert_array_equal(youbot.model.gravity.linear, [0.0, 0.0, -9.81])
    assert youbot.urdf_path is not None and youbot.urdf_path.is_file()
    assert youbot.visual_model.ngeoms >= 3 and youbot.collision_model.ngeoms >= 3
    with pytest.raises(ValueError, match="read-only"):
        youbot.q_lower[0] = 0.0


@pytest.mark.parametrize(
    ("q", "match"),
    [([0.0, 0.0], r"shape \(3,\)"), ([0.0, float("nan"), 0.0], "finite"), ("abc", "q must")],
)
def test_bad_configuration(youbot: RobotModel, q: object, match: str) -> None:
    """A q of the wrong shape or with NaN raises ParameterError naming q."""
    with pytest.raises(ParameterError, match=match) as info:
        tip_pose(youbot, q)  # type: ignore[arg-type]
    assert info.value.name == "q"


def test_cli_report(capsys: pytest.CaptureFixture[str]) -> None:
    """`youbot-opt report` prints the tip position at the study's start configuration."""
    assert cli_main(["report"]) == 0
    out = capsys.readouterr().out
    line = next(x for x in out.splitlines() if x.startswith("tip position"))
    printed = np.array([float(t) for t in line.split("[")[1].split("]")[0].split()])
    phi = np.cumsum(STUDY_Q_START)
    lengths = np.array([L1, L2, L3])
    expected = [A - lengths @ np.sin(phi), H + lengths @ np.cos(phi)]
    # The report prints 6 decimals: 5e-7 [m] is its rounding.
    np.testing.assert_allclose(printed, expected, rtol=0, atol=5e-7)
    assert "-65.00" in out and "9.500 N m" in out
    assert cli_main(["report", "--q", "1", "2"]) == 2


def test_joint_units_are_per_joint_kind(youbot: RobotModel) -> None:
    """joint_units: rad, rad/s, N m per revolute coordinate; m, m/s, N for panda's finger."""
    from youbot_opt.robot.load import load_model
    from youbot_opt.robot.model import PRISMATIC_UNITS, REVOLUTE_UNITS

    assert youbot.joint_units() == (REVOLUTE_UNITS,) * 3
    panda = load_model("panda")
    units = panda.joint_units()
    assert len(units) == panda.nv == 8
    assert units[:7] == (REVOLUTE_UNITS,) * 7 and units[7] == PRISMATIC_UNITS
    assert panda.joint_names[7] == "panda_finger_joint1"
    assert PRISMATIC_UNITS == ("m", "m/s", "N", True)


def test_cli_report_prints_a_prismatic_joint_in_metres(capsys: pytest.CaptureFixture[str]) -> None:
    """`youbot-opt report --robot panda`: the finger's limits in m, m/s, N and mm, not degrees."""
    assert cli_main(["report", "--robot", "panda"]) == 0
    out = capsys.readouterr().out
    rows = [x for x in out.splitlines() if x.split()[:1] and "] " in x]
    finger = next(x for x in rows if x.split()[0] == "panda_finger_joint1")
    assert "] m " in finger and " m/s " in finger and " N " in finger and " mm" in finger
    assert "deg" not in finger and "rad" not in finger
    joint1 = next(x for x in rows if x.split()[0] == "panda_joint1")
    assert "rad" in joint1 and "N m" in joint1 and "deg" in joint1
    assert " N s/m]" in out and "N m s/rad, " in out  # damping per joint kind


def _visual_count(robot):  # a spawned worker's task (module level: picklable)
    return robot.visual_model.ngeoms, robot


def _collision_as_loaded(robot):  # a spawned worker's task: the unpacked collision geometry
    return robot.collision_model == load_model(robot.name).collision_model


def test_a_pickled_robot_leaves_its_meshes_home():
    """A robot pickles without its visual geometry; the process that pickled it puts it back.

    ur5's visual meshes are most of its pickle (176 of 186 MB before), coal's
    pickle of its collision meshes the rest (9.9 MB): the visual meshes stay
    home, the collision ones travel packed, the pickle under 1 MB. Unpickled here, the robot
    is equal to the original and holds the same visual model; in a spawned
    process it has none (ngeoms 0) but the same kinematics and collision
    geometry; sent back, it is whole again (what a sweep's results do).
    """
    import multiprocessing
    import pickle

    robot = load_model("ur5")
    assert robot.visual_model.ngeoms > 0
    data = pickle.dumps(robot)
    assert len(data) < 1_000_000  # the collision meshes packed (9.9 MB as coal pickles them)
    here = pickle.loads(data)
    assert here == robot and here.visual_model is robot.visual_model
    with multiprocessing.get_context("spawn").Pool(1) as pool:
        count, back = pool.apply(_visual_count, (robot,))
        rebuilt = pool.apply(_collision_as_loaded, (robot,))
    assert count == 0  # the worker drew nothing and got no meshes
    assert rebuilt  # its collision geometry rebuilt from the arrays equals the file's
    assert back == robot and back.visual_model is robot.visual_model
    lean = dataclasses.replace(robot, visual_model=pin.GeometryModel())
    assert pickle.loads(pickle.dumps(lean)).visual_model.ngeoms == 0  # nothing to restore


def _geometry_rows(geometry: pin.GeometryModel) -> list[tuple[object, ...]]:
    """What a geometry model draws: name, joint, frame, mesh, scale and placement per object."""
    return [
        (
            go.name,
            int(go.parentJoint),
            int(go.parentFrame),
            go.meshPath,
            tuple(np.round(go.meshScale, 12)),
            tuple(np.round(go.placement.homogeneous.ravel(), 12)),
        )
        for go in geometry.geometryObjects
    ]


@pytest.mark.parametrize(
    ("name", "lock"),
    [("ur5", None), ("panda", {"panda_finger_joint1": 0.01, "panda_finger_joint2": 0.01})],
)
def test_a_deferred_visual_geometry_is_read_when_first_read_and_equals_the_eager_one(
    name, lock
) -> None:
    """load_model(defer_visual=True) reads the meshes at the first read, as the eager load does.

    The deferred geometry of a reduced model (panda's fingers locked) is the
    eager reduced model's, object by object; copies made meanwhile (a payload,
    other coordinates) keep it unread.
    """
    from youbot_opt.dynamics.coordinates import angle_robot
    from youbot_opt.robot.payload import Payload

    eager = load_model(name, lock_joints=lock)
    lazy = load_model(name, lock_joints=lock, defer_visual=True)
    field = RobotModel.visual_model
    assert not field.is_built(lazy)
    carried = lazy.with_payload(Payload(mass=0.5))
    turned = angle_robot(lazy)
    assert lazy == eager and not field.is_built(carried) and not field.is_built(turned)
    assert not field.is_built(lazy)
    assert _geometry_rows(lazy.visual_model) == _geometry_rows(eager.visual_model)
    assert field.is_built(lazy) and lazy.visual_model is lazy.visual_model  # built once
    assert _geometry_rows(carried.visual_model) == _geometry_rows(eager.visual_model)
    assert eager.visual_model.ngeoms > 0


def test_a_deferred_visual_geometry_travels_as_its_builder():
    """Pickled before it is read, a robot carries the builder (not meshes) and draws anywhere.

    The pickle is under the collision geometry plus 1 MB; in a spawned process
    the geometry is built on its read (the eager robot's there: 0, the meshes
    stay home).
    """
    import multiprocessing
    import pickle

    eager = load_model("ur5")
    lazy = load_model("ur5", defer_visual=True)
    data = pickle.dumps(lazy)
    assert len(data) < len(pickle.dumps(lazy.collision_model)) + 1_000_000
    assert not RobotModel.visual_model.is_built(pickle.loads(data))
    with multiprocessing.get_context("spawn").Pool(1) as pool:
        count, _ = pool.apply(_visual_count, (lazy,))
    assert count == eager.visual_model.ngeoms > 0


def test_a_geometry_builder_must_build_a_geometry_model():
    """A visual_model neither a GeometryModel nor callable, or building another type: refused."""
    youbot = load_model("youbot")
    with pytest.raises(ParameterError, match="visual_model must be a pinocchio.GeometryModel"):
        dataclasses.replace(youbot, visual_model=3)
    odd = dataclasses.replace(youbot, visual_model=lambda: "mesh")
    with pytest.raises(ParameterError, match="builder of visual_model returned str"):
        odd.visual_model  # noqa: B018 - the read builds
