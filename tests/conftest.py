"""Shared pytest fixtures.

Module-specific fixtures live in the test modules; only fixtures used by several
test modules belong here.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pytest

if TYPE_CHECKING:
    from youbot_opt.robot.model import RobotModel
    from youbot_opt.trajopt.solver import TrajOptSolver

os.environ.setdefault("MPLBACKEND", "Agg")

STUDY1_SOLVER_KNOTS = 20
"""Knots of the shared :func:`study1_solver` (small: the machinery is under test there)."""


@pytest.fixture(scope="session")
def fit_cache(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A temporary folder for sphere fits (never the user's cache), shared by the session.

    Every test that builds a collision model points ``YOUBOT_OPT_CACHE`` here, so each
    robot's fit is computed once per session; with pytest-xdist the workers of one run
    share it (the fit cache writes each file atomically).
    """
    base = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        base = base.parent  # <basetemp root>/popen-gwN: the run's root is shared
    return base / "fits"


@pytest.fixture(scope="session")
def youbot() -> RobotModel:
    """The committed youBot model, loaded once per session; tests must not modify it."""
    from youbot_opt.robot.load import load_model

    return load_model("youbot")


@pytest.fixture(scope="session")
def study1_solver(youbot: RobotModel) -> TrajOptSolver:
    """One trapezoidal study-1 solver at 20 knots, built once and shared by test modules.

    Sweeps reuse one solver in the same way; every ``solve`` call starts from
    its own guess, so the tests sharing it do not depend on each other.
    """
    from youbot_opt.reproduction.study1 import study1_problem
    from youbot_opt.trajopt.solver import TrajOptSolver

    return TrajOptSolver(study1_problem(STUDY1_SOLVER_KNOTS, robot=youbot))


@pytest.fixture()
def rng() -> np.random.Generator:
    """A freshly seeded generator, so each test's random draws are reproducible."""
    return np.random.default_rng(0)


@pytest.fixture()
def faults(monkeypatch: pytest.MonkeyPatch):  # type: ignore[no-untyped-def]
    """``faults(crash=keys, hang=keys, once_dir=None)``: sweep tasks that fail in pool workers.

    See ``tests/_faults.py``; calling it again replaces the earlier faults.
    """
    from _faults import inject

    def set_faults(**kwargs):  # type: ignore[no-untyped-def]
        inject(monkeypatch, **kwargs)

    return set_faults
