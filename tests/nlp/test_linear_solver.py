"""IpoptOptions.linear_solver: the solvers CasADi's IPOPT accepts, and clear errors.

HSL's solvers (and Pardiso) are loaded by IPOPT from a shared library when a
solver is created; without it IPOPT only reports ``Invalid_Option`` once the
solve has run. The checks here are made against libraries built by the test
(a stand-in that exports the routine IPOPT looks up, and one that does not),
so they run on any machine with a C compiler; no HSL library is needed.
"""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest

from youbot_opt.cli import main
from youbot_opt.exceptions import ParameterError
from youbot_opt.nlp.codegen import find_compiler
from youbot_opt.nlp.ipopt import LINEAR_SOLVERS, IpoptOptions, check_linear_solver

needs_compiler = pytest.mark.skipif(find_compiler() is None, reason="no C compiler")


def _library(folder: Path, name: str, routine: str | None) -> Path:
    """Compile a shared library exporting ``routine`` (a no-op), or nothing useful."""
    source = folder / f"{name}.c"
    body = f"void {routine}(void) {{}}\n" if routine else "void unrelated(void) {}\n"
    source.write_text(body)
    out = folder / f"{name}.so"
    cc = find_compiler()
    assert cc is not None
    subprocess.run([cc, "-shared", "-fPIC", "-o", str(out), str(source)], check=True)
    return out


def test_unknown_solver_and_misplaced_library_are_refused() -> None:
    with pytest.raises(ParameterError, match=r"linear_solver must be one of .*'mumps'.*got 'ma99'"):
        IpoptOptions(linear_solver="ma99")
    with pytest.raises(ParameterError, match="only used by the solvers IPOPT loads at run time"):
        IpoptOptions(linear_solver_library="/opt/hsl/libhsl.so")
    with pytest.raises(ParameterError, match="non-empty path"):
        IpoptOptions(linear_solver="ma57", linear_solver_library="")
    assert IpoptOptions(linear_solver="spral").to_casadi(True)["ipopt"]["linear_solver"] == "spral"
    assert check_linear_solver(IpoptOptions()) is None  # MUMPS is built in
    assert set(LINEAR_SOLVERS) >= {"mumps", "spral", "ma27", "ma57", "ma97"}


def test_missing_hsl_library_is_named_before_the_solve(tmp_path: Path) -> None:
    """The error names the library and the fix, at solver creation (not a failed solve)."""
    from youbot_opt.reproduction.study1 import study1_problem
    from youbot_opt.trajopt.solver import TrajOptSolver

    missing = str(tmp_path / "libhsl.so")
    options = IpoptOptions(linear_solver="ma57", linear_solver_library=missing)
    with pytest.raises(ParameterError, match=r"loaded by IPOPT at run time from the HSL library"):
        options.to_casadi(True)
    with pytest.raises(ParameterError, match=r"libhsl\.so.*cannot be loaded.*'mumps'"):
        TrajOptSolver(study1_problem(5), "trapezoidal", options)
    # the library named in ``extra`` (IPOPT's own option) is the one checked
    extra = IpoptOptions(linear_solver="ma27", extra={"hsllib": missing})
    with pytest.raises(ParameterError, match=r"from the HSL library '.*libhsl\.so'"):
        extra.to_casadi(True)


@needs_compiler
def test_library_must_export_the_solver(tmp_path: Path) -> None:
    """A library with IPOPT's MA57 routine passes and reaches IPOPT as ``hsllib``."""
    good = _library(tmp_path, "libhsl", "ma57ad_")
    wrong = _library(tmp_path, "libother", None)
    options = IpoptOptions(linear_solver="ma57", linear_solver_library=str(good))
    ipopt = options.to_casadi(True)["ipopt"]
    assert ipopt["hsllib"] == str(good) and ipopt["linear_solver"] == "ma57"
    assert not any(k.startswith("mumps_") for k in ipopt)  # MUMPS settings left out
    assert "fast_step_computation" in ipopt
    with pytest.raises(ParameterError, match=r"has no MA57 \(routine 'ma57ad' not found\)"):
        IpoptOptions(linear_solver="ma57", linear_solver_library=str(wrong)).to_casadi(True)
    with pytest.raises(ParameterError, match=r"has no MA27"):  # MA57's library is not MA27's
        IpoptOptions(linear_solver="ma27", linear_solver_library=str(good)).to_casadi(True)
    # recorded (result files, sweep manifests) only when set, and read back
    assert options.to_dict()["linear_solver_library"] == str(good)
    assert "linear_solver_library" not in IpoptOptions().to_dict()
    assert IpoptOptions(**options.to_dict()) == options


def test_spral_reaches_the_mumps_optimum() -> None:
    """Another factorization of the same KKT systems: the same local optimum.

    Study-1 problem at 20 knots; both stop at IPOPT's tol = 1e-8 on the same
    KKT point, so the objectives agree far below the 1e-3 that separates this
    problem's distinct optima (the bounds are those of the fast-KKT test).
    """
    from youbot_opt.reproduction.study1 import study1_problem
    from youbot_opt.trajopt.solver import TrajOptSolver

    problem = study1_problem(20)
    mumps = TrajOptSolver(problem, "trapezoidal").solve(beta=0.5)
    spral = TrajOptSolver(problem, "trapezoidal", IpoptOptions(linear_solver="spral")).solve(
        beta=0.5
    )
    assert mumps.success and spral.success, (mumps.message, spral.message)
    assert spral.objective == pytest.approx(mumps.objective, rel=1e-8)
    np.testing.assert_allclose(spral.variables["q"], mumps.variables["q"], atol=1e-5)
    assert spral.options.linear_solver == "spral"


def test_command_line_flags(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``--linear-solver ma57`` without its library: one error line, exit 2, nothing built."""
    argv = ["solve", "--knots", "5", "--no-refine", "--out", str(tmp_path / "run")]
    missing = str(tmp_path / "libhsl.so")
    assert main([*argv, "--linear-solver", "ma57", "--linear-solver-library", missing]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("youbot-opt: error: linear_solver='ma57'")
    assert missing in err[0]
    assert not (tmp_path / "run").exists()
