"""Spatial IK-path result files (issue 14): round trip, FK re-check on load, edited files."""

from __future__ import annotations

import json

import numpy as np
import pytest

from youbot_opt._files import json_digest
from youbot_opt.exceptions import ResultFileError
from youbot_opt.ikpath.io import RobotSource, load_result, save_result
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.result import OuterIterate, build_result
from youbot_opt.ikpath.targets import Target
from youbot_opt.nlp.status import SolveStatus
from youbot_opt.robot.load import load_model


def _exact_panda_result():
    """Panda with a position, a pose and an approach target, met exactly by construction.

    The targets are the frame placements of three random in-limit configurations,
    so those configurations solve them (errors at rounding level, ~1e-16).
    """
    robot = load_model("panda")
    base = CyclicIKProblem(
        robot=robot.model,
        frame=robot.tip_frame,
        targets=(Target(position=(0, 0, 0)), Target(position=(0, 0, 0))),
    )
    q = np.random.default_rng(3).uniform(base.q_lower, base.q_upper, (3, base.n_joints))
    p = [base.placement(theta) for theta in q]
    problem = base.with_targets(
        (
            Target(position=p[0].translation),
            Target(position=p[1].translation, rotation=p[1].rotation),
            Target(position=p[2].translation, approach=p[2].rotation[:, 2]),
        )
    )
    history = (OuterIterate(0, q + 0.01, 1.5, 1e-3, 2e-3, 1e3, 7),)
    result = build_result(
        problem,
        method="al",
        status=SolveStatus.SOLVED,
        x=q.ravel(),
        multipliers=np.arange(problem.n_constraints, dtype=float),
        iterations=4,
        wall_time=0.25,
        message="converged",
        start=(q + 0.1).ravel(),
        history=history,
    )
    assert result.success
    return robot, result


def _rewrite(path, edit, *, redigest):
    doc = json.loads(path.read_text())
    edit(doc["result"])
    if redigest:
        doc["sha256"] = json_digest(doc["result"])
    path.write_text(json.dumps(doc))


def test_round_trip_reloads_the_robot_and_rechecks_by_forward_kinematics(tmp_path):
    robot, result = _exact_panda_result()
    path = save_result(result, tmp_path / "result", RobotSource.of(robot))
    assert path.name == "result.json"
    back = load_result(path)  # the robot comes from the file's source ("panda")
    assert back.status is SolveStatus.SOLVED and back.success
    assert (back.method, back.message, back.iterations) == ("al", "converged", 4)
    np.testing.assert_array_equal(back.configurations, result.configurations)
    np.testing.assert_array_equal(back.start, result.start)
    np.testing.assert_array_equal(back.multipliers, result.multipliers)
    assert back.objective == result.objective  # same float formula on the same numbers
    # errors recomputed by framesForwardKinematics: exact targets, rounding only
    assert np.max(back.position_errors) < 1e-12 and np.max(back.orientation_errors) < 1e-12
    assert [t.kind for t in back.problem.targets] == [t.kind for t in result.problem.targets]
    for a, b in zip(back.problem.targets, result.problem.targets, strict=True):
        np.testing.assert_array_equal(a.position, b.position)
    assert back.problem.joint_names == result.problem.joint_names
    np.testing.assert_array_equal(back.problem.q_upper, result.problem.q_upper)
    assert len(back.history) == 1 and back.history[0].inner_iterations == 7
    np.testing.assert_array_equal(back.history[0].x, result.history[0].x)


@pytest.mark.parametrize(
    ("redigest", "match"),
    [(False, "checksum mismatch"), (True, "disagree with pin.framesForwardKinematics")],
)
def test_a_moved_target_is_detected(tmp_path, redigest, match):
    robot, result = _exact_panda_result()
    path = save_result(result, tmp_path / "result.json", RobotSource.of(robot))

    def move(body):
        body["targets"][1]["position"][2] += 1e-6  # 1 um: far above the 1e-9 re-check

    _rewrite(path, move, redigest=redigest)
    with pytest.raises(ResultFileError, match=match):
        load_result(path, robot=robot)


def test_another_robot_or_a_false_success_is_refused(tmp_path):
    robot, result = _exact_panda_result()
    path = save_result(result, tmp_path / "result.json")  # no robot source
    with pytest.raises(ResultFileError, match="names no robot source"):
        load_result(path)
    with pytest.raises(ResultFileError, match="robot differs"):
        load_result(path, robot=load_model("ur5"))
    # A failed result (a configuration 0.2 rad off its target) edited to claim success.
    off = result.configurations.copy()
    off[0, 0] += 0.2
    failed = build_result(
        result.problem,
        method="ipopt",
        status=SolveStatus.MAX_ITERATIONS,
        x=off.ravel(),
        multipliers=result.multipliers,
        iterations=3000,
        wall_time=1.0,
        message="max iter",
        start=off.ravel(),
    )
    assert not failed.success
    path = save_result(failed, tmp_path / "failed.json")
    assert load_result(path, robot=robot.model).status is SolveStatus.MAX_ITERATIONS
    _rewrite(path, lambda body: body.update(status="solved"), redigest=True)
    with pytest.raises(ResultFileError, match=r"claims 'solved' but targets \[0\]"):
        load_result(path, robot=robot)
