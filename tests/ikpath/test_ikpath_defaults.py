"""The best IK path by default (issue 27 item 5, issue 25 item 4): automatic starts, certainty.

Default settings (no start count) solve from start 0, the targets' reachability
witnesses and the cheapest coherent chains of per-target IK solutions
(:class:`~youbot_opt.ikpath.starts.BranchStarts`); these tests check what they find,
that the result says how sure it is, and that the AL's final phase emits no overflow.
"""

from __future__ import annotations

import json
import re
import types
import warnings

import numpy as np
import pinocchio as pin
import pytest

from youbot_opt.cli import main
from youbot_opt.ikpath.methods.sqp import _sqp_step
from youbot_opt.ikpath.multistart import free_joints, minimum_distance, run_multistart
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.solve import solve
from youbot_opt.ikpath.starts import (
    BRANCH_KIND,
    BranchStarts,
    make_starts_3d,
    start_budget,
)
from youbot_opt.ikpath.targets import Target
from youbot_opt.robot.load import load_model
from youbot_opt.robot.planar import PlanarChain

PLANAR_ARGS = ["--lengths", "3", "2", "2", "--lower", "-1", "-2", "-2", "--upper", "1", "2", "2"]
PLANAR_ARGS += ["--target", "4", "1", "--target", "3", "-2"]
PLANAR_BEST = 0.5677879142  # rad^2: 20 feasible starts find it; the zero start finds 11.06


def _planar_example() -> CyclicIKProblem:
    chain = PlanarChain(lengths=[3, 2, 2]).with_limits([-1, -2, -2], [1, 2, 2])
    return CyclicIKProblem(robot=chain, targets=[(4, 1), (3, -2)])


def _ur5_problem(n: int, seed: int = 2026) -> CyclicIKProblem:
    """benchmarks/bench_wait.py's UR5 targets: tool0 at in-limit configurations (6 digits)."""
    robot = load_model("ur5")
    model, data = robot.model, robot.model.createData()
    frame = model.getFrameId(robot.tip_frame)
    rng = np.random.default_rng(seed)
    lo = np.maximum(model.lowerPositionLimit, -np.pi)
    hi = np.minimum(model.upperPositionLimit, np.pi)
    targets = []
    for _ in range(n):
        pin.framesForwardKinematics(model, data, rng.uniform(lo, hi))
        point = np.round(data.oMf[frame].translation, 6)
        targets.append(Target(position=point))
    return CyclicIKProblem(robot=robot, targets=targets)


def test_planar_default_finds_what_its_witnesses_and_twenty_starts_find():
    """The documented planar example: default E = 0.568, not the zero start's 11.06."""
    problem = _planar_example()
    ms = run_multistart(problem, workers=1)
    assert ms.start_kind == BRANCH_KIND and ms.n_starts == start_budget(problem) == 16
    assert ms.best.success and ms.best.objective == pytest.approx(PLANAR_BEST, abs=1e-9)
    assert ms.results[0].objective == pytest.approx(11.0616432750, abs=1e-8)  # start 0
    assert ms.results[1].objective <= 0.948  # the witnesses' path, as a start
    assert ms.best_count >= 8


def test_ur5_default_reaches_the_best_known_path_where_twenty_starts_do_not():
    """UR5, 4 position targets: the automatic starts find E = 14.7795; 20 mixed starts do not."""
    problem = _ur5_problem(4)
    ms = run_multistart(problem, method="ipopt")
    assert ms.best.success
    assert ms.best.objective == pytest.approx(14.7794546568, rel=1e-8)
    assert ms.best_count >= 3  # reached from several chains: the result says how sure
    mixed = run_multistart(problem, method="ipopt", n_starts=20, starts="mixed")
    assert mixed.best.objective > ms.best.objective + 1.0


def test_branch_starts_are_deterministic_pruned_and_extended_by_random_starts():
    """Same seed, same starts; chains no costlier than PRUNE_RATIO x the cheapest; then random."""
    problem = _ur5_problem(4)
    a = BranchStarts(problem, None, 3)
    b = BranchStarts(problem, None, 3)
    assert len(a) == len(b) <= start_budget(problem)
    assert all(np.array_equal(a[k], b[k]) for k in range(len(a)))
    assert np.max(a.chain_energies) <= 2.0 * np.min(a.chain_energies)
    longer = BranchStarts(problem, len(a) + 3, 3)
    assert np.array_equal(longer[len(a) - 1], a[len(a) - 1])
    assert np.all((longer[len(a) + 2] >= problem.lower) & (longer[len(a) + 2] <= problem.upper))


def test_a_path_shifted_by_two_pi_or_turned_about_a_free_joint_is_the_same_minimum():
    """ur5 with position targets: the wrist's last joint moves no target; 2 pi shifts are free."""
    problem = _ur5_problem(4)
    free = free_joints(problem)
    assert free.tolist() == [False] * 5 + [True]
    q = np.zeros((4, 6))
    q[:, 0] = [0.1, 0.4, -0.2, 0.3]
    shifted = q.copy()
    shifted[:, 0] += 2 * np.pi
    shifted[:, 5] += 0.7  # any common turn of the free joint
    distance = minimum_distance(problem, planar=False)
    a, b = types.SimpleNamespace(configurations=q), types.SimpleNamespace(configurations=shifted)
    assert distance(a, b) == pytest.approx(0.0, abs=1e-12)  # type: ignore[arg-type]
    shifted[1, 2] += 0.1
    assert distance(a, b) == pytest.approx(0.1, abs=1e-12)  # type: ignore[arg-type]


def test_cli_planar_default_prints_the_best_path_and_its_certainty(capsys, tmp_path):
    """The documented example by default: E = 0.5677879142 and a certainty line."""
    argv = ["ikpath", *PLANAR_ARGS, "--no-progress", "--no-replay", "--out", str(tmp_path / "r")]
    assert main(argv) == 0
    out = capsys.readouterr().out
    # the printed figures, not their last digit: E is converged to ~1e-10 rad^2, and the
    # 10th decimal may round either way with the BLAS kernel (OPENBLAS_CORETYPE)
    best = re.search(r"best: E = (\S+) rad\^2 \(solved\)", out)
    assert best is not None, out
    assert float(best.group(1)) == pytest.approx(PLANAR_BEST, abs=1e-8)
    line = next(ln for ln in out.splitlines() if ln.startswith("certainty: "))
    assert " of 16 starts reached the best E (16 met the targets), 2 distinct minima" in line
    second = re.search(r"the next best E = (\S+) rad\^2", line)
    assert second is not None, line
    assert float(second.group(1)) == pytest.approx(11.06164328, abs=1e-7)


def test_cli_failed_path_prints_its_reason(capsys, tmp_path):
    """A failed IK path says why on the terminal (not only in summary.json)."""
    argv = ["ikpath", "--example", "B", "--max-wall-time", "1e-9", "--no-progress", "--no-replay"]
    assert main([*argv, "--out", str(tmp_path / "r")]) == 1
    out = capsys.readouterr().out
    assert "failed (max_time): " in out and "wall-time limit" in out
    assert "certainty: none of " in out and " starts met the targets" in out


def test_sqp_step_refuses_dependent_constraint_rows():
    """Dependent rows make the KKT matrix singular: no step (its multipliers would be noise)."""
    jac = np.array([[1.0, 0.0, 0.0], [1.0, 1e-13, 0.0]])
    hess = np.eye(3)
    free = np.ones(3, dtype=bool)
    assert _sqp_step(jac, hess, np.ones(3), np.array([1e-3, 2e-3]), free) is None
    step = _sqp_step(
        np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]), hess, np.ones(3), np.zeros(2), free
    )
    assert step is not None and np.all(np.isfinite(step[2]))


@pytest.mark.slow
def test_al_final_phase_emits_no_overflow_warning():
    """ur5, 12 targets, the start whose final phase overflowed ``J^T lam``: no RuntimeWarning."""
    robot = load_model("ur5")  # benchmarks/bench_ikpath.py's spatial_problem("ur5", 12)
    base = CyclicIKProblem(robot=robot.model, frame=robot.tip_frame, targets=((0, 0, 0), (0, 0, 0)))
    rng = np.random.default_rng(2026)
    lo, hi = np.maximum(base.q_lower, -np.pi), np.minimum(base.q_upper, np.pi)
    targets = []
    for k in range(12):
        placement = base.placement(rng.uniform(lo, hi))
        rot = placement.rotation if k % 2 == 0 else None
        targets.append(Target(position=placement.translation, rotation=rot))
    problem = base.with_targets(targets)
    x0 = make_starts_3d(problem, 6, 0, kind="mixed")[5]
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        result = solve(problem, x0=x0)
    assert np.all(np.isfinite(result.configurations))


def test_cli_spatial_default_is_ipopt_on_automatic_starts_and_says_how_sure(capsys, tmp_path):
    """ur5 without --starts/--method: IPOPT on the branch starts; summary.json holds certainty."""
    problem = _ur5_problem(4)
    argv = ["ikpath", "--robot", "ur5", "--no-progress", "--no-replay", "--json"]
    for point in problem.target_points:
        argv += ["--target", *(f"{v:.6f}" for v in point)]
    assert main([*argv, "--out", str(tmp_path / "r")]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["method"] == "ipopt" and doc["start_kind"] == BRANCH_KIND
    assert doc["E"] == pytest.approx(14.7794546568, rel=1e-8)
    cert = doc["certainty"]
    assert cert["starts"] == doc["starts"] and cert["best_count"] == doc["minima"][0]["count"]
    assert cert["distinct_minima"] == len(doc["minima"]) and cert["next_E"] > doc["E"]
