"""IK-path result: joint path for replay, status handling, self re-check, summary."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from _migrate import migrate
from youbot_opt._files import json_digest
from youbot_opt.exceptions import ParameterError, ResultFileError, SolveFailed
from youbot_opt.ikpath.examples import example_problem
from youbot_opt.ikpath.io import load_result, save_result
from youbot_opt.ikpath.methods.al import ALOptions
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.result import build_result, checked
from youbot_opt.ikpath.solve import solve
from youbot_opt.nlp.status import SolveStatus
from youbot_opt.robot.planar import PlanarChain


@pytest.fixture(scope="module")
def result():
    return solve(example_problem("B"), method="al")


def test_joint_path_interpolates_and_closes_the_cycle(result):
    """The path passes through every configuration at s = j and ends at the first one."""
    path = result.joint_path(samples_per_segment=4)
    s_targets = result.problem.n_targets
    assert path.s.shape == (4 * s_targets + 1,) and path.q.shape == (4 * s_targets + 1, 3)
    np.testing.assert_array_equal(path.q[::4][:-1], result.configurations)
    np.testing.assert_array_equal(path.q[-1], result.configurations[0])
    mid = 0.5 * (result.configurations[0] + result.configurations[1])
    np.testing.assert_allclose(path.q[2], mid, atol=1e-15)
    with pytest.raises(ParameterError, match="samples_per_segment"):
        result.joint_path(0)


def test_result_is_read_only_and_verified(result):
    """Arrays are read-only; residuals are recomputed by Pinocchio; E alias and model exist."""
    with pytest.raises(ValueError):
        result.configurations[0, 0] = 1.0
    np.testing.assert_allclose(result.tip_positions(), result.problem.target_points, atol=1e-9)
    assert result.E == result.objective
    assert result.model.nq == 3 and result.visual_model.ngeoms >= 3
    assert "E = 15.60589" in result.summary()


def test_raise_for_status(result):
    """Success returns the result; a failure raises SolveFailed carrying the result."""
    assert result.raise_for_status() is result
    failed = solve(example_problem("A"), method="ipopt", options=None, x0=None)
    assert failed.status is SolveStatus.SOLVED  # zero start converges (to a poor minimum) for IPOPT
    from youbot_opt.ikpath.methods.al import ALOptions

    capped = solve(example_problem("A"), options=ALOptions(max_outer_iterations=1))
    assert capped.status is SolveStatus.MAX_ITERATIONS
    with pytest.raises(SolveFailed, match="max_iterations") as info:
        capped.raise_for_status()
    assert info.value.result is capped


def _claim(problem, x, *, status=SolveStatus.SOLVED, tol=1e-10):
    """A result claiming ``status`` for configurations ``x`` (as a solver would build it)."""
    n = problem.n_variables
    return build_result(
        problem,
        method="al",
        status=status,
        x=x,
        multipliers=np.zeros(2 * problem.n_targets),
        iterations=1,
        inner_iterations=0,
        wall_time=0.0,
        message="claimed",
        start=np.zeros(n),
        constraint_tol=tol,
    )


def test_replace_with_nan_configurations_is_not_a_success(result):
    """A success replaced with NaN configurations: check() says NON_FINITE, checked() sets it."""
    assert result.success
    nan = np.full_like(result.configurations, np.nan)
    replaced = dataclasses.replace(result, configurations=nan)
    assert replaced.status is SolveStatus.SOLVED  # construction does no work (rule 5)
    verdict = replaced.check()
    assert verdict.status is SolveStatus.NON_FINITE and not verdict.passed
    assert verdict.message == "non-finite values in configurations"
    bad = checked(replaced)
    assert bad.status is SolveStatus.NON_FINITE and not bad.success
    assert "re-check failed: non-finite values in configurations" in bad.message
    with pytest.raises(SolveFailed, match="non_finite"):
        bad.raise_for_status()
    inf_e = checked(dataclasses.replace(result, objective=math.inf))
    assert inf_e.status is SolveStatus.NON_FINITE and "objective" in inf_e.message


def test_replace_with_moved_configuration_or_stale_figures_fails_the_recheck(result):
    """A joint moved by 1e-3 rad misses its target and leaves E stale: CHECK_FAILED."""
    q = np.array(result.configurations)
    q[2, 1] += 1e-3
    moved = checked(dataclasses.replace(result, configurations=q))
    assert moved.status is SolveStatus.CONSTRAINT_VIOLATION
    assert "target 2 missed by" in moved.message and "reported E" in moved.message
    stale = checked(dataclasses.replace(result, objective=result.objective + 1e-6))
    assert stale.status is SolveStatus.CONSTRAINT_VIOLATION and "reported E" in stale.message
    same = checked(dataclasses.replace(result))  # nothing changed: still a success
    assert same.success and same.message == result.message
    assert result.check() == (SolveStatus.SOLVED, "")


def test_recheck_uses_the_solver_constraint_tolerance():
    """A residual of 1e-9 m passes with constraint_tol 1e-9 m, fails with 5e-10 m.

    Turning joint 1 of an exact solution by delta moves the tip on a circle of
    radius |p| about the base: residual 2 |p| sin(delta / 2) (closed form).
    """
    chain = PlanarChain(lengths=[1.0, 1.0])
    q = np.array([[0.3, 0.9], [1.2, -0.4]])
    targets = [chain.tip_position(qj) for qj in q]
    problem = CyclicIKProblem(robot=chain, targets=targets)
    radius = float(np.linalg.norm(targets[0]))
    delta = 2.0 * math.asin(1e-9 / (2.0 * radius))
    x = q.copy()
    x[0, 0] += delta
    ok = _claim(problem, x, tol=1e-9)  # allowed sqrt(2) * 1e-9 + 3e-12 m > 1e-9 m
    assert ok.success, ok.message
    assert ok.max_position_error() == pytest.approx(1e-9, rel=1e-5)  # rounding of 1e-16 m in 1e-9 m
    tight = _claim(problem, x, tol=5e-10)  # allowed 7.1e-10 m < 1e-9 m
    assert (
        tight.status is SolveStatus.CONSTRAINT_VIOLATION
        and "target 0 missed by 1e-09 m" in tight.message
    )


def test_claimed_success_outside_the_limits_fails_the_recheck():
    """Targets met exactly but a joint 0.2 rad past its limit: CHECK_FAILED, not success."""
    chain = PlanarChain(lengths=[1.0, 1.0], q_lower=-0.5, q_upper=0.5)
    q = np.array([[0.7, 0.1], [0.2, 0.3]])
    problem = CyclicIKProblem(robot=chain, targets=[chain.tip_position(qj) for qj in q])
    res = _claim(problem, q)
    assert res.status is SolveStatus.CONSTRAINT_VIOLATION
    assert "joint limits violated by 0.2 rad" in res.message
    free = CyclicIKProblem(robot=chain, targets=problem.target_points, use_limits=False)
    assert _claim(free, q).success  # the same configurations without the limits


def test_failures_are_kept_and_tolerance_is_validated():
    """Only claimed successes are re-checked; constraint_tol must be finite and > 0."""
    problem = example_problem("A")
    far = _claim(problem, np.zeros(problem.n_variables), status=SolveStatus.MAX_ITERATIONS)
    assert far.status is SolveStatus.MAX_ITERATIONS and far.message == "claimed"
    verdict = far.check()  # the targets are missed, but a failure keeps its own status
    assert verdict.status is SolveStatus.MAX_ITERATIONS and "missed by" in verdict.message
    for tol in (0.0, -1e-9, math.nan, math.inf):
        with pytest.raises(ParameterError, match="constraint_tol"):
            _claim(problem, np.zeros(problem.n_variables), tol=tol)


def test_constraint_tolerance_survives_the_file_and_old_files_get_the_default(result, tmp_path):
    """The tolerance is saved; a 0.1.0 file without it gets ALOptions' default by the migration."""
    custom = solve(example_problem("B"), options=ALOptions(constraint_tol=1e-9))
    assert custom.success and custom.constraint_tol == 1e-9
    assert load_result(save_result(custom, tmp_path / "c")).constraint_tol == 1e-9
    path = save_result(result, tmp_path / "old.json")
    doc = json.loads(path.read_text())
    del doc["result"]["constraint_tol"]
    doc["sha256"] = json_digest(doc["result"])
    path.write_text(json.dumps(doc))
    with pytest.raises(ResultFileError, match="incomplete or invalid.*constraint_tol"):
        load_result(path)  # the current schema records it
    doc["schema_version"] = 1  # as 0.1.0 wrote it
    path.write_text(json.dumps(doc))
    assert migrate(path).returncode == 0
    old = load_result(path)
    assert old.constraint_tol == ALOptions().constraint_tol and old.success


def test_loader_rechecks_a_claimed_success(tmp_path):
    """A file claiming SOLVED for a path that misses its targets loads as CONSTRAINT_VIOLATION."""
    capped = solve(example_problem("A"), options=ALOptions(max_outer_iterations=1))
    assert capped.status is SolveStatus.MAX_ITERATIONS and capped.max_position_error() > 1e-3
    path = save_result(capped, tmp_path / "claimed.json")
    doc = json.loads(path.read_text())
    doc["result"]["status"] = "solved"
    doc["sha256"] = json_digest(doc["result"])
    path.write_text(json.dumps(doc))
    loaded = load_result(path)
    assert loaded.status is SolveStatus.CONSTRAINT_VIOLATION
    assert "re-check failed: target" in loaded.message
