"""A trajectory result file written by youbot_opt at commit 74bfa23 loads with today's code."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np

from youbot_opt import study1_problem
from youbot_opt.nlp.status import SolveStatus
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.trajopt.io import load_result
from youbot_opt.trajopt.multistart import run_multistart
from youbot_opt.trajopt.solver import TrajOptSolver

OLD = Path(__file__).resolve().parents[1] / "fixtures" / "files_74bfa23"


def test_old_study1_result_loads_solved_and_checks_clean():
    """Study 1 at 12 knots saved by 74bfa23: SOLVED, its E and problem, the pin.aba check passes."""
    result = load_result(OLD / "traj_study1_n12.npz")
    assert result.status is SolveStatus.SOLVED
    assert result.objective == 9.439772676374494  # as the old solver reported it
    want = study1_problem(n_knots=12)
    assert result.problem.n_knots == 12
    np.testing.assert_array_equal(result.problem.start.q, want.start.q)
    np.testing.assert_array_equal(result.problem.goal.q, want.goal.q)
    verdict = result.check()
    assert verdict.passed, verdict.message


def test_old_multistart_store_resumes_without_solving(tmp_path, youbot):
    """A trajectory multistart store of 74bfa23 resumes: both starts loaded, none solved again.

    The store names the URDF of the checkout that wrote it; it is rewritten to
    this checkout's (a store resumes only with the same robot file).
    """
    out = tmp_path / "traj_multistart"
    shutil.copytree(OLD / "traj_multistart", out)
    manifest = out / "manifest.json"
    text, written_by = manifest.read_text(), "/tmp/old74/urdf/youbot_arm_planar.urdf"
    assert written_by in text
    manifest.write_text(text.replace(written_by, str(youbot.urdf_path)))
    solver = TrajOptSolver(study1_problem(12, robot=youbot))
    sweep = SweepOptions(executor="serial", out=out)
    result = run_multistart(solver, n_starts=2, beta=0.5, seed=3, sweep=sweep)
    assert result.resumed == 2
    assert result.best.objective == 8.144733342334671  # as 74bfa23 stored it
