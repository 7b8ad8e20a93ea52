"""Trajectory files written by youbot_opt at commit 74bfa23 (0.1.0): refused, migrated, loaded.

The package reads the current format only; ``scripts/migrate_0_1_0.py`` carries
the fixtures (copied into ``tmp_path``) forward, and the migrated files load
and resume with the numbers the old files held.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from _migrate import REFUSAL, migrate
from youbot_opt import study1_problem
from youbot_opt.exceptions import ResultFileError
from youbot_opt.nlp.status import SolveStatus
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.trajopt.io import load_result
from youbot_opt.trajopt.multistart import run_multistart
from youbot_opt.trajopt.solver import TrajOptSolver

OLD = Path(__file__).resolve().parents[1] / "fixtures" / "files_74bfa23"


def test_old_study1_result_is_refused_with_the_migration_to_run():
    """Loading the 0.1.0 file names the script that carries it forward."""
    with pytest.raises(ResultFileError, match=REFUSAL):
        load_result(OLD / "traj_study1_n12.npz")


def test_migrated_study1_result_loads_solved_and_checks_clean(tmp_path):
    """Study 1 at 12 knots saved by 74bfa23, migrated: SOLVED, its E and problem, checks clean."""
    old = Path(shutil.copy(OLD / "traj_study1_n12.npz", tmp_path / "old.npz"))
    done = migrate(old, "--out", tmp_path / "new.npz")
    assert done.returncode == 0, done.stderr
    assert "carried forward" in done.stdout
    assert old.read_bytes() == (OLD / "traj_study1_n12.npz").read_bytes()  # --out: untouched
    result = load_result(tmp_path / "new.npz")
    assert result.status is SolveStatus.SOLVED
    assert result.objective == 9.439772676374494  # as the old solver reported it
    assert result.beta == 0.5
    want = study1_problem(n_knots=12)
    assert result.problem.n_knots == 12
    np.testing.assert_array_equal(result.problem.start.q, want.start.q)
    np.testing.assert_array_equal(result.problem.goal.q, want.goal.q)
    verdict = result.check()
    assert verdict.passed, verdict.message


def _resume(out: Path, youbot):
    solver = TrajOptSolver(study1_problem(12, robot=youbot))
    sweep = SweepOptions(executor="serial", out=out)
    return run_multistart(solver, n_starts=2, beta=0.5, seed=3, sweep=sweep)


def test_old_multistart_store_is_refused_with_the_migration_to_run(tmp_path, youbot):
    """Resuming the 0.1.0 store names the script; nothing is solved or written."""
    out = tmp_path / "traj_multistart"
    shutil.copytree(OLD / "traj_multistart", out)
    with pytest.raises(ResultFileError, match=REFUSAL):
        _resume(out, youbot)
    assert sorted(p.name for p in (out / "items").iterdir()) == sorted(
        p.name for p in (OLD / "traj_multistart" / "items").iterdir()
    )


def test_migrated_multistart_store_resumes_without_solving(tmp_path, youbot):
    """A trajectory multistart store of 74bfa23, migrated in place: both starts loaded, none solved.

    The store names the URDF of the checkout that wrote it (gone): the migration
    is told this checkout's (``--urdf``), whose content then identifies the robot.
    """
    out = tmp_path / "traj_multistart"
    shutil.copytree(OLD / "traj_multistart", out)
    gone = migrate(out)
    assert gone.returncode == 1 and "pass --urdf" in gone.stderr
    assert not (tmp_path / "traj_multistart.0.1.0.bak").exists()  # nothing moved
    done = migrate("--urdf", youbot.urdf_path, out)
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "traj_multistart.0.1.0.bak" / "manifest.json").is_file()  # the backup
    result = _resume(out, youbot)
    assert result.resumed == 2
    assert result.best.objective == 8.144733342334671  # as 74bfa23 stored it
