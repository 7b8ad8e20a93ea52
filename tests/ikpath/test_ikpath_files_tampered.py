"""IK result files that lie, written with the package's own writer as an attacker would (#29).

A success claim is re-checked on load at the smaller of the file's tolerance and the
caller's (the library's 1e-6 by default), against the model's joint limits: the
file can tighten a check, never loosen it.
"""

from __future__ import annotations

import numpy as np
import pytest

from youbot_opt.exceptions import ParameterError, ResultFileError
from youbot_opt.ikpath.examples import example_problem
from youbot_opt.ikpath.io import load_result, save_result
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.result import build_result
from youbot_opt.ikpath.targets import Target
from youbot_opt.nlp.status import SolveStatus
from youbot_opt.robot.load import load_model
from youbot_opt.robot.source import RobotSource


@pytest.fixture(scope="module")
def ur5():
    return load_model("ur5")


def _claimed(problem, q, **kw):
    return build_result(
        problem, method="al", status=SolveStatus.SOLVED, x=np.asarray(q).ravel(),
        multipliers=np.zeros(problem.n_constraints), iterations=1, wall_time=0.0,
        message="converged", start=np.asarray(q).ravel(), **kw,
    )  # fmt: skip


def test_targets_with_tolerance_1e9_and_moved_configurations_are_refused(ur5, tmp_path):
    base = CyclicIKProblem(robot=ur5.model, frame=ur5.tip_frame,
                           targets=(Target(position=(0, 0, 0)),) * 2)  # fmt: skip
    q = np.array([[0.1, -0.5, 0.4, 0.0, 0.3, 0.0], [0.5, -0.8, 0.9, 0.2, -0.3, 0.1]])
    exact = base.with_targets(
        tuple(Target(position=base.placement(row).translation, position_tol=1e9) for row in q)
    )
    forged = _claimed(exact, q + 0.5)  # 0.5 rad off: the tip is decimetres from each target
    assert forged.success and forged.position_errors.min() > 0.1  # the file's 1e9 passes it
    path = save_result(forged, tmp_path / "forged.json", RobotSource.of(ur5))
    with pytest.raises(ResultFileError, match=r"claims 'solved' but targets \[0, 1\] are missed"):
        load_result(path)
    assert load_result(path, position_tol=1.0).success  # a caller may choose to be lenient
    honest = save_result(_claimed(exact, q), tmp_path / "honest.json", RobotSource.of(ur5))
    assert load_result(honest).success


def test_limits_wider_than_the_models_are_refused(ur5, tmp_path):
    """A joint at 7.25 rad on a robot whose limit is 2 pi, under limits the file widened."""
    upper = np.array(ur5.model.upperPositionLimit[:6], dtype=float)
    assert upper[0] == pytest.approx(2 * np.pi)
    wide = upper.copy()
    wide[0] = 10.0
    base = CyclicIKProblem(robot=ur5.model, frame=ur5.tip_frame, q_upper=wide,
                           targets=(Target(position=(0, 0, 0)),) * 2)  # fmt: skip
    q = np.array([[7.25, -0.5, 0.4, 0.0, 0.3, 0.0], [0.5, -0.8, 0.9, 0.2, -0.3, 0.1]])
    exact = base.with_targets(tuple(Target(position=base.placement(r).translation) for r in q))
    forged = _claimed(exact, q)
    assert forged.success and forged.limit_violation == 0.0  # within the file's limits
    path = save_result(forged, tmp_path / "wide.json", RobotSource.of(ur5))
    with pytest.raises(ResultFileError, match=r"joint limits are wider than the model's"):
        load_result(path)


def test_a_planar_file_cannot_loosen_its_constraint_tolerance(tmp_path):
    """A planar result claiming success with constraint_tol 1e9 and moved configurations
    is downgraded on load: it is re-checked at the caller's 1e-6 m."""
    exact = example_problem("A")
    q = np.zeros((exact.n_targets, exact.n_joints)) + 0.3
    forged = _claimed(exact, q, constraint_tol=1e9)
    assert forged.success
    path = save_result(forged, tmp_path / "planar.json")
    back = load_result(path)
    assert not back.success and "not the file's 1e+09" in back.message


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf"), True])
def test_the_callers_tolerances_are_checked(tmp_path, bad):
    problem = example_problem("A")
    forged = _claimed(problem, np.zeros((problem.n_targets, problem.n_joints)))
    path = save_result(forged, tmp_path / "p.json")
    with pytest.raises(ParameterError, match="position_tol must be a positive finite"):
        load_result(path, position_tol=bad)
