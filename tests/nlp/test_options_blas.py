"""The IPOPT builders keep CasADi's bundled OpenBLAS single-threaded unless the user chose."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

_PROBE = """
import os
from youbot_opt import TrajOptSolver, study1_problem
TrajOptSolver(study1_problem(5), "trapezoidal")
print(os.environ.get("OPENBLAS_NUM_THREADS"))
"""


@pytest.mark.parametrize(("preset", "expected"), [(None, "1"), ("", "1"), ("2", "2")])
def test_first_solver_sets_openblas_threads_only_when_unset(preset, expected) -> None:
    """Building a solver sets OPENBLAS_NUM_THREADS=1 if unset and never overrides a user's value."""
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    if preset is not None:
        env["OPENBLAS_NUM_THREADS"] = preset
    out = subprocess.run(
        [sys.executable, "-c", _PROBE], env=env, capture_output=True, text=True, check=True
    )
    assert out.stdout.strip().splitlines()[-1] == expected
